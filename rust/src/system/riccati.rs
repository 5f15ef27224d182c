//! The sensor's steady-state error covariance P̄ by structured doubling.
//!
//! P̄ is the positive semi-definite solution of g̃(h(X)) = X (paper, Sec. II-A), with the
//! Lyapunov operator h(X) = A X A' + Q and the Riccati operator
//! g̃(X) = X - X C' (C X C' + R)^{-1} C X. We compute the prior (one-step prediction) covariance
//! P⁻ = h(P̄) as the stabilising solution of the filtering DARE
//! P = A P A' - A P C' (C P C' + R)^{-1} C P A' + Q by the structure-preserving doubling algorithm
//! (quadratically convergent; W.-W. Lin and S.-F. Xu, SIAM J. Matrix Anal. Appl. 28(1), 2006),
//! then P̄ = g̃(P⁻), check that the filter's closed loop is stable, and polish P̄ by Newton steps
//! on X = g̃(h(X)) (defect correction) where the doubling left more than rounding-level residual.
//!
//! Inputs are validated by [`crate::LinearSystem::new`], which calls [`steady_state`] and reports
//! the residual of g̃(h(P̄)) = P̄.

use nalgebra::DMatrix;

use crate::error::{Error, Result};
use crate::system::linalg::{frobenius_norm, symmetrize};
use crate::system::spectral::spectral_radius;
use crate::system::stein;

/// Most defect-correction (Newton) steps after the doubling; one is usually all that helps.
const MAX_CORRECTIONS: usize = 3;

/// A relative residual this small (16 ulps) is already at rounding level: no correction is tried,
/// so well-conditioned systems keep the doubling's P̄ unchanged.
const CORRECTION_THRESHOLD: f64 = 16.0 * f64::EPSILON;

/// P̄ with how it was obtained; see [`steady_state`].
#[derive(Debug, Clone)]
pub struct SteadyState {
    /// Steady-state (posterior) error covariance P̄, symmetric.
    pub pbar: DMatrix<f64>,
    /// Doubling steps used for P⁻.
    pub iterations: usize,
    /// Defect-correction (Newton) steps accepted after the doubling (at most 3).
    pub corrections: usize,
    /// [`fixed_point_residual`] of `pbar`.
    pub residual: f64,
}

/// The Riccati operator g̃(X) = X - X C' (C X C' + R)^{-1} C X (the Kalman measurement update,
/// Sec. II-A) together with (C X C' + R)^{-1} C X, the transposed Kalman gain. `None` when
/// C X C' + R is not positive definite.
///
/// Evaluated in Joseph's form (I - K C) X (I - K C)' + K R K', equal to g̃(X) for the optimal
/// gain K. Why: the subtraction X - K C X cancels when the sensor is precise (g̃(X) much
/// smaller than X): with q / r = 10^12 it loses 4 significant digits of P̄ (and the residual,
/// computed the same way, does not see it). Joseph's form adds two positive semidefinite terms,
/// and its first-order insensitivity to the gain's rounding keeps P̄ to a few ulps there.
pub(crate) fn measurement_update(
    x: &DMatrix<f64>,
    c: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Option<(DMatrix<f64>, DMatrix<f64>)> {
    let n = x.nrows();
    let innovation_cov = c * x * c.transpose() + r;
    let innovation_chol = innovation_cov.cholesky()?;
    let gain_t = innovation_chol.solve(&(c * x));
    let gain = gain_t.transpose();
    let closed = DMatrix::<f64>::identity(n, n) - &gain * c;
    let joseph = &closed * x * closed.transpose() + &gain * r * &gain_t;
    Some((joseph, gain_t))
}

/// Solves for P̄ = g̃(P⁻), where P⁻ is the stabilising solution of the filtering DARE, for
/// validated inputs: A n×n, C m×n, Q n×n symmetric PSD, R m×m symmetric PD, `tol > 0`,
/// `max_iter >= 1` (relative change of the doubling iterate at which to stop, and a cap on steps).
///
/// If the [`fixed_point_residual`] of that P̄ exceeds 16 ulps, up to 3 Newton steps on
/// X = g̃(h(X)) follow, each kept only if it more than halves the residual. They matter when C
/// barely sees an unstable direction: there the doubling can lose digits that the equation's
/// conditioning does not explain (residual 2e-7 brought to 3e-12 on one n = 5 system).
///
/// Errors: [`Error::NotConverged`] if the doubling does not converge within `max_iter` steps,
/// breaks down, or converges to a solution whose closed loop A (I - K C) is not stable (all
/// typical of an undetectable (A, C); the caller can diagnose with
/// [`crate::system::spectral::detectability_error`]).
pub fn steady_state(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    tol: f64,
    max_iter: usize,
) -> Result<SteadyState> {
    let n = a.nrows();
    let (prior, iterations) = prior_by_doubling(a, c, q, r, tol, max_iter)?;
    let (mut pbar, gain_t) = measurement_update(&prior, c, r)
        .ok_or_else(|| Error::invalid("R", "C P C' + R is not positive definite"))?;
    symmetrize(&mut pbar);
    // The stabilising solution makes the closed loop A (I - K C) stable, with
    // K = P⁻ C' (C P⁻ C' + R)^{-1}; anything else means (A, C) is not detectable (or the
    // iteration found a spurious fixed point).
    let closed_loop = a * (DMatrix::<f64>::identity(n, n) - gain_t.transpose() * c);
    let closed_loop_radius = spectral_radius(&closed_loop)?;
    if closed_loop_radius >= 1.0 {
        return Err(Error::NotConverged {
            what: "Riccati doubling (no stabilising solution)",
            iterations,
            residual: closed_loop_radius,
        });
    }
    let (pbar, corrections, residual) = refine(a, c, q, r, pbar);
    Ok(SteadyState {
        pbar,
        iterations,
        corrections,
        residual,
    })
}

/// Relative residual ||g̃(h(X)) - X||_F / ||X||_F of the fixed-point equation of P̄ (absolute
/// when X = 0; `+inf` when C h(X) C' + R is not positive definite).
pub fn fixed_point_residual(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> f64 {
    let hx = a * x * a.transpose() + q;
    let g = match measurement_update(&hx, c, r) {
        Some((g, _)) => g,
        None => return f64::INFINITY,
    };
    let (distance, x_norm) = (frobenius_norm(&(g - x)), frobenius_norm(x));
    if x_norm > 0.0 {
        distance / x_norm
    } else {
        distance
    }
}

/// Defect correction of an approximate P̄ (Newton's method on X = g̃(h(X)), as in Mehrmann and
/// Tan, IEEE Trans. Autom. Control 33(7), 1988). Returns (P̄, steps accepted, its residual).
///
/// Why: when C barely sees an unstable direction, P⁻ is large (|P⁻| ~ 1e7 for some n = 6, m = 1
/// systems), I + G H in the doubling is ill-conditioned (κ ~ 1e8) and P̄ = g̃(P⁻) cancels, so the
/// doubling's P̄ can be off by 1e-8 relative although the equation itself is well conditioned
/// (rounding the data moves the exact P̄ by ~1e-12). One Newton step brings the residual down to
/// what evaluating it in double allows.
///
/// The derivative of X -> g̃(h(X)) is Δ -> F Δ F' with F = (I - K C) A and
/// K = h(X) C' (C h(X) C' + R)^{-1}, so a step solves the Stein equation
/// Δ = F Δ F' + (g̃(h(X)) - X), which [`stein::solve`] can as ρ(F) < 1 near the stabilising
/// solution. Steps are tried while the residual exceeds 16 ulps, and one is kept only if it more
/// than halves the residual; rounding noise stops the loop after one or two steps.
fn refine(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    mut pbar: DMatrix<f64>,
) -> (DMatrix<f64>, usize, f64) {
    let mut residual = fixed_point_residual(a, c, q, r, &pbar);
    let mut accepted = 0;
    while accepted < MAX_CORRECTIONS && residual > CORRECTION_THRESHOLD {
        let Some(candidate) = newton_step(a, c, q, r, &pbar) else {
            break;
        };
        let candidate_residual = fixed_point_residual(a, c, q, r, &candidate);
        // A NaN residual is no improvement either.
        let halved = candidate_residual < 0.5 * residual;
        if !halved {
            break;
        }
        pbar = candidate;
        residual = candidate_residual;
        accepted += 1;
    }
    (pbar, accepted, residual)
}

/// One Newton step X + Δ for X = g̃(h(X)), see [`refine`]; `None` if it cannot be taken.
fn newton_step(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    let hx = a * x * a.transpose() + q;
    let (g, gain_t) = measurement_update(&hx, c, r)?;
    let mut defect = g - x;
    symmetrize(&mut defect);
    let closed_loop = (DMatrix::<f64>::identity(n, n) - gain_t.transpose() * c) * a;
    let delta = stein::solve(&closed_loop, 1.0, &defect).ok()??;
    let mut next = x + delta;
    symmetrize(&mut next);
    Some(next)
}

/// Structure-preserving doubling for the filtering DARE
/// P = A P A' - A P C' (C P C' + R)^{-1} C P A' + Q. Returns (P⁻, doubling steps).
///
/// The dual of the control-form SDA: A_0 = A', G_0 = C' R^{-1} C, H_0 = Q and, with
/// W_k = I + G_k H_k,
/// A_{k+1} = A_k W_k^{-1} A_k, G_{k+1} = G_k + A_k W_k^{-1} G_k A_k',
/// H_{k+1} = H_k + A_k' H_k W_k^{-1} A_k; H_k increases to P⁻ and A_k goes to 0 quadratically.
fn prior_by_doubling(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    tol: f64,
    max_iter: usize,
) -> Result<(DMatrix<f64>, usize)> {
    let n = a.nrows();
    let eye = DMatrix::<f64>::identity(n, n);
    let r_chol = r
        .clone()
        .cholesky()
        .ok_or_else(|| Error::invalid("R", "must be positive definite"))?;
    let mut ak = a.transpose();
    let mut gk = c.transpose() * r_chol.solve(c);
    symmetrize(&mut gk);
    let mut hk = q.clone();
    let mut change = f64::INFINITY;
    for it in 1..=max_iter {
        let singular = Error::NotConverged {
            what: "Riccati doubling (singular I + G H)",
            iterations: it,
            residual: change,
        };
        let w_lu = (&eye + &gk * &hk).lu();
        let w_inv_a = w_lu.solve(&ak).ok_or(singular.clone())?;
        let w_inv_g = w_lu.solve(&gk).ok_or(singular)?;
        let mut h_next = &hk + ak.transpose() * &hk * &w_inv_a;
        let mut g_next = &gk + &ak * w_inv_g * ak.transpose();
        let a_next = &ak * w_inv_a;
        symmetrize(&mut h_next);
        symmetrize(&mut g_next);
        if !h_next.iter().all(|x| x.is_finite()) {
            return Err(Error::NotConverged {
                what: "Riccati doubling (diverged)",
                iterations: it,
                residual: f64::INFINITY,
            });
        }
        change = frobenius_norm(&(&h_next - &hk)) / frobenius_norm(&h_next).max(f64::MIN_POSITIVE);
        hk = h_next;
        gk = g_next;
        ak = a_next;
        if change <= tol || frobenius_norm(&ak) == 0.0 {
            return Ok((hk, it));
        }
    }
    Err(Error::NotConverged {
        what: "Riccati doubling",
        iterations: max_iter,
        residual: change,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(x: f64) -> DMatrix<f64> {
        DMatrix::from_element(1, 1, x)
    }

    /// The doubling squares the closed-loop contraction ρ = |A (1 - K C)| each step, so the
    /// relative change after k steps is about ρ^(2^k): it stops at k = ⌈log2(ln tol / ln ρ)⌉
    /// within one (kills a wrong relative change, `-` turned `+` or `/` turned `*` or `%`,
    /// and the stopping rule's `||` turned `&&`, which all change the count; a system scaled by
    /// 10^6 tells a relative change from an absolute one, as `/` turned `%` makes it).
    #[test]
    fn doubling_steps_match_the_contraction() {
        // The last system is the first scaled by 10^6 (same ρ): the change must be relative.
        for (a, c, q, r) in [
            (1.2, 0.7, 0.8, 0.8),
            (1.0, 0.1, 1.0, 1.0),
            (1.0, 0.001, 1.0, 1.0),
            (1.2, 0.7, 0.8e6, 0.8e6),
        ] {
            for tol in [1e-2, 1e-8, 1e-14] {
                let ss = steady_state(&m(a), &m(c), &m(q), &m(r), tol, 200).unwrap();
                let pbar = ss.pbar[(0, 0)];
                let prior = a * pbar * a + q;
                let k = prior * c / (c * prior * c + r);
                let rho = (a * (1.0 - k * c)).abs();
                let predicted = ((tol.ln() / rho.ln()).log2()).ceil() as i64;
                let got = ss.iterations as i64;
                assert!(
                    (got - predicted).abs() <= 1,
                    "{a} {c}: {got} vs {predicted} at {tol}"
                );
            }
        }
    }

    /// The defect correction's rules (kills `x_norm > 0` turned `>=`, which divides by a zero
    /// norm; the loop's `&&` turned `||` and `<` turned `<=`; and the acceptance test's
    /// `0.5 * residual` turned `0.5 + residual` or `0.5 / residual`). On a scalar system, with
    /// P̄ from the quadratic formula: at X = 0 the residual is absolute, |g̃(Q)| = q r / (c² q + r);
    /// a Newton step from 0 does not halve it, so none is kept; from 3 P̄ every step halves it and
    /// the limit of 3 stops the loop; from P̄ (1 + 3e-15), already below 16 ulps, none is tried
    /// although one would halve it.
    #[test]
    fn refine_keeps_only_halving_steps_within_its_limits() {
        let (a, c, q, r) = (1.2, 0.7, 0.8, 0.8);
        let (ma, mc, mq, mr) = (m(a), m(c), m(q), m(r));
        // Prior: c² p² + (r (1 - a²) - c² q) p - q r = 0, positive root; P̄ = p r / (c² p + r).
        let b = r * (1.0 - a * a) - c * c * q;
        let prior = (-b + (b * b + 4.0 * c * c * q * r).sqrt()) / (2.0 * c * c);
        let pbar = prior * r / (c * c * prior + r);
        let residual = |x: f64| fixed_point_residual(&ma, &mc, &mq, &mr, &m(x));
        let newton = |x: f64| newton_step(&ma, &mc, &mq, &mr, &m(x)).unwrap()[(0, 0)];

        let at_zero = residual(0.0);
        assert!(
            (at_zero - q * r / (c * c * q + r)).abs() < 1e-15,
            "{at_zero}"
        );
        assert!(residual(newton(0.0)) > 0.5 * at_zero);
        let (x, kept, res) = refine(&ma, &mc, &mq, &mr, m(0.0));
        assert_eq!((x[(0, 0)], kept, res), (0.0, 0, at_zero));

        let (x, kept, res) = refine(&ma, &mc, &mq, &mr, m(3.0 * pbar));
        assert_eq!(kept, MAX_CORRECTIONS);
        assert!(residual(newton(x[(0, 0)])) < 0.5 * res && res > CORRECTION_THRESHOLD);
        assert!((x[(0, 0)] - pbar).abs() < 1e-5 * pbar);

        let near = pbar * (1.0 + 3e-15);
        let near_residual = residual(near);
        assert!(near_residual > 0.0 && near_residual <= CORRECTION_THRESHOLD);
        assert!(residual(newton(near)) < 0.5 * near_residual);
        let (x, kept, _) = refine(&ma, &mc, &mq, &mr, m(near));
        assert_eq!((x[(0, 0)], kept), (near, 0));
    }

    /// The prior solves the filtering DARE, and P̄ = g̃(P⁻) is a fixed point of g̃ ∘ h.
    #[test]
    fn prior_solves_the_dare() {
        let a = DMatrix::from_row_slice(2, 2, &[1.1, 0.3, 0.0, 0.7]);
        let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.5]);
        let q = DMatrix::<f64>::identity(2, 2) * 0.5;
        let r = m(0.3);
        let (prior, _) = prior_by_doubling(&a, &c, &q, &r, 1e-14, 200).unwrap();
        let (posterior, _) = measurement_update(&prior, &c, &r).unwrap();
        let dare = &a * &posterior * a.transpose() + &q;
        assert!(frobenius_norm(&(dare - &prior)) < 1e-13 * frobenius_norm(&prior));
        let ss = steady_state(&a, &c, &q, &r, 1e-14, 200).unwrap();
        assert!(frobenius_norm(&(ss.pbar - posterior)) < 1e-13 * frobenius_norm(&prior));
    }

    /// Scalar: g̃(x) = x r / (c² x + r), gain (c² x + r)^{-1} c x.
    #[test]
    fn scalar_measurement_update() {
        let (x, c, r) = (2.0, 0.7, 0.8);
        let (post, gain_t) = measurement_update(&m(x), &m(c), &m(r)).unwrap();
        assert!((post[(0, 0)] - x * r / (c * c * x + r)).abs() < 1e-15);
        assert!((gain_t[(0, 0)] - c * x / (c * c * x + r)).abs() < 1e-15);
        assert!(measurement_update(&m(x), &m(c), &m(-1.0)).is_none());
    }

    /// A precise sensor (q / r = 10^12): P̄ is 10^-12 of the prior, so the update must not
    /// subtract two near-equal numbers. Scalar: g̃(x) = x r / (c² x + r) within 4 ulps (the
    /// subtracting form X - K C X is off by ~1e-4); a coupled 2-state prior whose update is an
    /// exact rational matrix, entry by entry (the off-diagonal entry is 1e-6 of the others);
    /// and P̄ from `steady_state` with the prior from the quadratic formula.
    #[test]
    fn precise_sensor_keeps_the_digits_of_pbar() {
        let (x, c, r) = (1e12, 1.0, 1.0);
        let (post, _) = measurement_update(&m(x), &m(c), &m(r)).unwrap();
        let exact = x * r / (c * c * x + r);
        assert!((post[(0, 0)] - exact).abs() < 4.0 * f64::EPSILON * exact);

        // C = R = I: g̃(X) = X (X + I)^{-1}, which for this integer X is exactly
        // [[3e12, 1e6], [1e6, 2e12 + 3]] / (3e12 + 4) (every number here is exact in a double).
        let xm = DMatrix::from_row_slice(2, 2, &[1e12, 1e6, 1e6, 3.0]);
        let eye = DMatrix::<f64>::identity(2, 2);
        let (post, _) = measurement_update(&xm, &eye, &eye).unwrap();
        let det = 3e12 + 4.0;
        let expected = DMatrix::from_row_slice(2, 2, &[3e12, 1e6, 1e6, 2e12 + 3.0]) / det;
        for (p, e) in post.iter().zip(expected.iter()) {
            assert!((p - e).abs() < 1e-14 * e.abs(), "{post}");
        }

        let (a, q) = (0.5, 1e12);
        let b = r - a * a * r - q * c * c;
        let prior = (-b + (b * b + 4.0 * c * c * q * r).sqrt()) / (2.0 * c * c);
        let pbar = prior * r / (c * c * prior + r);
        let ss = steady_state(&m(a), &m(c), &m(q), &m(r), 1e-14, 200).unwrap();
        assert!(
            (ss.pbar[(0, 0)] - pbar).abs() < 1e-14 * pbar,
            "{}",
            ss.pbar[(0, 0)]
        );
        assert!(ss.residual < 1e-14);
    }

    /// An unstable mode C cannot see has no stabilising solution: the solver says it failed.
    #[test]
    fn undetectable_fails_to_converge() {
        let a = DMatrix::from_row_slice(2, 2, &[2.0, 0.0, 0.0, 0.5]);
        let c = DMatrix::from_row_slice(1, 2, &[0.0, 1.0]);
        let q = DMatrix::<f64>::identity(2, 2);
        let e = steady_state(&a, &c, &q, &m(1.0), 1e-14, 200).unwrap_err();
        assert!(matches!(e, Error::NotConverged { .. }), "{e}");
    }

    /// A system C barely sees (n = 4, m = 1; |P⁻| ~ 1e5, |I - K C| ~ 55), drawn by the
    /// `properties::riccati_residual_small` generator. The doubling alone gives P̄ with residual
    /// 2.4e-9 and forward error 4.6e-10; one Newton step brings both to rounding level.
    /// `expected` is P̄ computed in 60-digit arithmetic (mpmath), rounded to double.
    #[test]
    fn defect_correction_recovers_lost_digits() {
        let a = DMatrix::from_row_slice(
            4,
            4,
            &[
                1.1763416343100064,
                -0.852825335762758,
                -0.4379718841235386,
                -0.01894352014146219,
                -0.7153341439332397,
                -1.1966782616748766,
                1.0804206266764345,
                -1.1894030181128035,
                -0.6695429042387882,
                1.2571402148605053,
                0.36458973705198044,
                1.0288767519766593,
                -0.4314522079509742,
                -0.8805668695491901,
                -0.3451892110462164,
                0.9111543329212093,
            ],
        );
        let c = DMatrix::from_row_slice(
            1,
            4,
            &[
                0.7138457517418055,
                0.19233111406075953,
                0.6209299299288193,
                0.08200048468827648,
            ],
        );
        let q = DMatrix::from_row_slice(
            4,
            4,
            &[
                2.31618832317278,
                0.21080384949916248,
                -0.6445833789896775,
                0.7384914459147965,
                0.21080384949916248,
                1.6438367943410541,
                0.3294247532287964,
                1.401656626753239,
                -0.6445833789896775,
                0.3294247532287964,
                0.4629443112904339,
                0.2586906387416351,
                0.7384914459147965,
                1.401656626753239,
                0.2586906387416351,
                1.8429448562319353,
            ],
        );
        let r = m(0.2535539385420759);
        let expected = DMatrix::from_row_slice(
            4,
            4,
            &[
                447.93496471075485,
                2855.9534094850283,
                -1482.9599010154643,
                668.843455318152,
                2855.9534094850283,
                22132.597531736632,
                -10788.332015664419,
                5061.4250336139585,
                -1482.9599010154643,
                -10788.332015664419,
                5363.103035716007,
                -2485.0217708128275,
                668.843455318152,
                5061.4250336139585,
                -2485.0217708128275,
                1163.0056252665295,
            ],
        );
        let ss = steady_state(&a, &c, &q, &r, 1e-14, 200).unwrap();
        assert!(ss.corrections >= 1);
        assert!(ss.residual < 1e-11, "residual {:e}", ss.residual);
        let forward = frobenius_norm(&(&ss.pbar - &expected)) / frobenius_norm(&expected);
        assert!(forward < 1e-10, "forward error {forward:e}");
    }
}
