//! The sensor's steady-state error covariance P̄ by structured doubling.
//!
//! P̄ is the positive semi-definite solution of g̃(h(X)) = X (paper, Sec. II-A), with the
//! Lyapunov operator h(X) = A X A' + Q and the Riccati operator
//! g̃(X) = X - X C' (C X C' + R)^{-1} C X. We compute the prior (one-step prediction) covariance
//! P⁻ = h(P̄) as the stabilising solution of the filtering DARE
//! P = A P A' - A P C' (C P C' + R)^{-1} C P A' + Q by the structure-preserving doubling algorithm
//! (quadratically convergent; W.-W. Lin and S.-F. Xu, SIAM J. Matrix Anal. Appl. 28(1), 2006),
//! then P̄ = g̃(P⁻), and check that the filter's closed loop is stable.
//!
//! Inputs are validated by [`crate::LinearSystem::new`], which calls [`steady_state`] and reports
//! the residual of g̃(h(P̄)) = P̄.

use nalgebra::DMatrix;

use crate::error::{Error, Result};
use crate::linalg::{frobenius_norm, symmetrize};
use crate::spectral::spectral_radius;

/// P̄ with the number of doubling steps that produced it; see [`steady_state`].
#[derive(Debug, Clone)]
pub struct SteadyState {
    /// Steady-state (posterior) error covariance P̄ = g̃(P⁻), symmetric.
    pub pbar: DMatrix<f64>,
    /// Doubling steps used for P⁻.
    pub iterations: usize,
}

/// The Riccati operator g̃(X) = X - X C' (C X C' + R)^{-1} C X (the Kalman measurement update,
/// Sec. II-A) together with (C X C' + R)^{-1} C X, the transposed Kalman gain. `None` when
/// C X C' + R is not positive definite.
pub(crate) fn measurement_update(
    x: &DMatrix<f64>,
    c: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Option<(DMatrix<f64>, DMatrix<f64>)> {
    let innovation_cov = c * x * c.transpose() + r;
    let innovation_chol = innovation_cov.cholesky()?;
    let xc = x * c.transpose();
    let gain_t = innovation_chol.solve(&xc.transpose());
    Some((x - &xc * &gain_t, gain_t))
}

/// Solves for P̄ = g̃(P⁻), where P⁻ is the stabilising solution of the filtering DARE, for
/// validated inputs: A n×n, C m×n, Q n×n symmetric PSD, R m×m symmetric PD, `tol > 0`,
/// `max_iter >= 1` (relative change of the doubling iterate at which to stop, and a cap on steps).
///
/// Errors: [`Error::NotConverged`] if the doubling does not converge within `max_iter` steps,
/// breaks down, or converges to a solution whose closed loop A (I - K C) is not stable (all
/// typical of an undetectable (A, C); the caller can diagnose with
/// [`crate::spectral::detectability_error`]).
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
    // The stabilising solution makes the closed loop A (I - K C) stable, K = P⁻ C' (C P⁻ C' + R)^{-1};
    // anything else means (A, C) is not detectable (or the iteration found a spurious fixed point).
    let closed_loop = a * (DMatrix::<f64>::identity(n, n) - gain_t.transpose() * c);
    let closed_loop_radius = spectral_radius(&closed_loop)?;
    if closed_loop_radius >= 1.0 {
        return Err(Error::NotConverged {
            what: "Riccati doubling (no stabilising solution)",
            iterations,
            residual: closed_loop_radius,
        });
    }
    Ok(SteadyState { pbar, iterations })
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

    /// An unstable mode C cannot see has no stabilising solution: the solver says it failed.
    #[test]
    fn undetectable_fails_to_converge() {
        let a = DMatrix::from_row_slice(2, 2, &[2.0, 0.0, 0.0, 0.5]);
        let c = DMatrix::from_row_slice(1, 2, &[0.0, 1.0]);
        let q = DMatrix::<f64>::identity(2, 2);
        let e = steady_state(&a, &c, &q, &m(1.0), 1e-14, 200).unwrap_err();
        assert!(matches!(e, Error::NotConverged { .. }), "{e}");
    }
}
