//! The sensor's steady-state Kalman filter: P̄, the Lyapunov operator h and its traces.
//!
//! P̄ is the positive semi-definite solution of g̃(h(X)) = X (paper, Sec. II-A), with
//! h(X) = A X A' + Q and g̃(X) = X - X C' (C X C' + R)^{-1} C X. We compute the prior
//! (one-step prediction) covariance P⁻ = h(P̄) as the stabilising solution of the filtering
//! DARE by the structure-preserving doubling algorithm (quadratically convergent), then
//! P̄ = g̃(P⁻), and report the residual of g̃(h(P̄)) = P̄.

use nalgebra::{Complex, DMatrix};

use crate::error::{Error, Result};

/// Most traces a single call will compute (8 bytes each).
pub const MAX_TRACES: u128 = 200_000_000;

/// Default relative tolerance of the doubling iteration.
pub const DEFAULT_TOL: f64 = 1e-14;
/// Default cap on doubling steps (each squares the closed-loop contraction).
pub const DEFAULT_MAX_ITER: usize = 200;

/// A validated LTI system x_{k+1} = A x_k + w_k, y_k = C x_k + v_k with its steady state P̄.
#[derive(Debug, Clone)]
pub struct LinearSystem {
    a: DMatrix<f64>,
    c: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    pbar: DMatrix<f64>,
    residual: f64,
    iterations: usize,
    rho: f64,
}

fn frob(m: &DMatrix<f64>) -> f64 {
    m.norm()
}

fn symmetrize(m: &mut DMatrix<f64>) {
    let n = m.nrows();
    for i in 0..n {
        for j in (i + 1)..n {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

fn check_matrix(arg: &str, m: &DMatrix<f64>, rows: usize, cols: usize) -> Result<()> {
    if m.nrows() != rows || m.ncols() != cols {
        return Err(Error::invalid(
            arg,
            format!(
                "incompatible dimensions; expected ({rows}, {cols}) but found ({}, {})",
                m.nrows(),
                m.ncols()
            ),
        ));
    }
    if let Some(x) = m.iter().find(|x| !x.is_finite()) {
        return Err(Error::invalid(
            arg,
            format!("contains a non-finite entry ({x})"),
        ));
    }
    Ok(())
}

fn check_symmetric(arg: &str, m: &DMatrix<f64>) -> Result<()> {
    let scale = m.amax().max(f64::MIN_POSITIVE);
    let asym = (m - m.transpose()).amax();
    if asym > 1e-10 * scale {
        return Err(Error::invalid(
            arg,
            format!("must be symmetric (largest |X - X'| entry is {asym:.3e})"),
        ));
    }
    Ok(())
}

/// Eigenvalues of a general square matrix, without panicking.
pub fn eigenvalues(m: &DMatrix<f64>) -> Result<Vec<Complex<f64>>> {
    let schur = nalgebra::linalg::Schur::try_new(m.clone(), f64::EPSILON, 10_000).ok_or(
        Error::NotConverged {
            what: "Schur decomposition",
            iterations: 10_000,
            residual: f64::NAN,
        },
    )?;
    Ok(schur.complex_eigenvalues().iter().copied().collect())
}

/// Spectral radius ρ(M) = max |eigenvalue|.
pub fn spectral_radius(m: &DMatrix<f64>) -> Result<f64> {
    Ok(eigenvalues(m)?.iter().map(|z| z.norm()).fold(0.0, f64::max))
}

/// PBH test: the eigenvalues of A with |λ| >= 1 that C does not see.
fn undetectable_modes(a: &DMatrix<f64>, c: &DMatrix<f64>) -> Result<Vec<Complex<f64>>> {
    let n = a.nrows();
    let m = c.nrows();
    let scale = a.amax().max(c.amax()).max(1.0);
    let mut bad = Vec::new();
    for ev in eigenvalues(a)? {
        if ev.norm() < 1.0 - 1e-10 {
            continue;
        }
        let mut pbh = DMatrix::<Complex<f64>>::zeros(n + m, n);
        for i in 0..n {
            for j in 0..n {
                pbh[(i, j)] =
                    Complex::new(a[(i, j)], 0.0) - if i == j { ev } else { Complex::new(0.0, 0.0) };
            }
        }
        for i in 0..m {
            for j in 0..n {
                pbh[(n + i, j)] = Complex::new(c[(i, j)], 0.0);
            }
        }
        let svd = pbh
            .try_svd(false, false, f64::EPSILON, 10_000)
            .ok_or(Error::NotConverged {
                what: "SVD in the detectability test",
                iterations: 10_000,
                residual: f64::NAN,
            })?;
        let smin = svd
            .singular_values
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        if smin <= 1e-9 * scale {
            bad.push(ev);
        }
    }
    Ok(bad)
}

/// Structure-preserving doubling for the filtering DARE P = A P A' - A P C'(C P C' + R)^{-1} C P A' + Q.
/// Returns (P⁻, iterations).
fn sda_prior(
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
    // Dual of the control-form SDA: A0 = A', G0 = C' R^{-1} C, H0 = Q.
    let mut ak = a.transpose();
    let mut gk = c.transpose() * r_chol.solve(c);
    symmetrize(&mut gk);
    let mut hk = q.clone();
    let mut change = f64::INFINITY;
    for it in 1..=max_iter {
        let w = &eye + &gk * &hk;
        let lu = w.lu();
        let x1 = lu.solve(&ak).ok_or(Error::NotConverged {
            what: "Riccati doubling (singular I + G H)",
            iterations: it,
            residual: change,
        })?;
        let x2 = lu.solve(&gk).ok_or(Error::NotConverged {
            what: "Riccati doubling (singular I + G H)",
            iterations: it,
            residual: change,
        })?;
        let h_next = &hk + ak.transpose() * &hk * &x1;
        let mut g_next = &gk + &ak * x2 * ak.transpose();
        let a_next = &ak * x1;
        let mut h_next = h_next;
        symmetrize(&mut h_next);
        symmetrize(&mut g_next);
        if !h_next.iter().all(|x| x.is_finite()) {
            return Err(Error::NotConverged {
                what: "Riccati doubling (diverged)",
                iterations: it,
                residual: f64::INFINITY,
            });
        }
        change = frob(&(&h_next - &hk)) / frob(&h_next).max(f64::MIN_POSITIVE);
        hk = h_next;
        gk = g_next;
        ak = a_next;
        if change <= tol || frob(&ak) == 0.0 {
            return Ok((hk, it));
        }
    }
    Err(Error::NotConverged {
        what: "Riccati doubling",
        iterations: max_iter,
        residual: change,
    })
}

impl LinearSystem {
    /// Validates (A, C, Q, R) and solves for P̄ with the default tolerance.
    pub fn new(a: DMatrix<f64>, c: DMatrix<f64>, q: DMatrix<f64>, r: DMatrix<f64>) -> Result<Self> {
        Self::with_tolerance(a, c, q, r, DEFAULT_TOL, DEFAULT_MAX_ITER)
    }

    /// As [`LinearSystem::new`] with an explicit tolerance and iteration cap.
    pub fn with_tolerance(
        a: DMatrix<f64>,
        c: DMatrix<f64>,
        q: DMatrix<f64>,
        r: DMatrix<f64>,
        tol: f64,
        max_iter: usize,
    ) -> Result<Self> {
        let n = a.nrows();
        if n == 0 {
            return Err(Error::invalid("A", "must be a non-empty square matrix"));
        }
        check_matrix("A", &a, n, n)?;
        let m = c.nrows();
        if m == 0 {
            return Err(Error::invalid("C", "must have at least one row"));
        }
        check_matrix("C", &c, m, n)?;
        check_matrix("Q", &q, n, n)?;
        check_matrix("R", &r, m, m)?;
        if !(tol.is_finite() && tol > 0.0) {
            return Err(Error::invalid(
                "tol",
                format!("must be positive, got {tol}"),
            ));
        }
        if max_iter == 0 {
            return Err(Error::invalid("max_iter", "must be at least 1"));
        }
        check_symmetric("Q", &q)?;
        check_symmetric("R", &r)?;
        let mut q = q;
        let mut r = r;
        symmetrize(&mut q);
        symmetrize(&mut r);
        let qmin = q.clone().symmetric_eigenvalues().min();
        if qmin < -1e-10 * q.amax().max(f64::MIN_POSITIVE) {
            return Err(Error::invalid(
                "Q",
                format!("must be positive semi-definite (smallest eigenvalue {qmin:.3e})"),
            ));
        }
        let rmin = r.clone().symmetric_eigenvalues().min();
        if rmin <= 0.0 || r.clone().cholesky().is_none() {
            return Err(Error::invalid(
                "R",
                format!("must be positive definite (smallest eigenvalue {rmin:.3e})"),
            ));
        }
        let rho = spectral_radius(&a)?;
        let diagnose = |err: Error| -> Error {
            match undetectable_modes(&a, &c) {
                Ok(bad) if !bad.is_empty() => Error::invalid(
                    "(A, C)",
                    format!(
                        "not detectable: eigenvalue(s) {} of A with |λ| >= 1 are unobservable from C",
                        bad.iter()
                            .map(|z| format!("{:.6}{:+.6}i", z.re, z.im))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ),
                _ => err,
            }
        };
        let (prior, iterations) = sda_prior(&a, &c, &q, &r, tol, max_iter).map_err(diagnose)?;
        // P̄ = g̃(P⁻).
        let s = &c * &prior * c.transpose() + &r;
        let k = s
            .clone()
            .cholesky()
            .ok_or_else(|| Error::invalid("R", "C P C' + R is not positive definite"))?;
        let pc = &prior * c.transpose();
        let mut pbar = &prior - &pc * k.solve(&pc.transpose());
        symmetrize(&mut pbar);
        // The stabilising solution makes the closed loop A (I - K C) stable; anything else means
        // (A, C) is not detectable (or the iteration found a spurious fixed point).
        let gain = k.solve(&pc.transpose()); // (C P C' + R)^{-1} C P⁻
        let acl = &a * (DMatrix::<f64>::identity(n, n) - gain.transpose() * &c);
        let rho_cl = spectral_radius(&acl)?;
        if rho_cl >= 1.0 {
            return Err(diagnose(Error::NotConverged {
                what: "Riccati doubling (no stabilising solution)",
                iterations,
                residual: rho_cl,
            }));
        }
        let mut sys = LinearSystem {
            a,
            c,
            q,
            r,
            pbar,
            residual: 0.0,
            iterations,
            rho,
        };
        sys.residual = sys.fixed_point_residual(&sys.pbar);
        Ok(sys)
    }

    /// Relative residual ||g̃(h(X)) - X||_F / ||X||_F (absolute when X = 0).
    pub fn fixed_point_residual(&self, x: &DMatrix<f64>) -> f64 {
        let hx = self.h(x);
        let s = &self.c * &hx * self.c.transpose() + &self.r;
        let hc = &hx * self.c.transpose();
        let g = match s.cholesky() {
            Some(ch) => &hx - &hc * ch.solve(&hc.transpose()),
            None => return f64::INFINITY,
        };
        let (d, nx) = (frob(&(g - x)), frob(x));
        if nx > 0.0 {
            d / nx
        } else {
            d
        }
    }

    /// The Lyapunov operator h(X) = A X A' + Q.
    pub fn h(&self, x: &DMatrix<f64>) -> DMatrix<f64> {
        &self.a * x * self.a.transpose() + &self.q
    }

    pub fn n(&self) -> usize {
        self.a.nrows()
    }
    pub fn a(&self) -> &DMatrix<f64> {
        &self.a
    }
    pub fn c(&self) -> &DMatrix<f64> {
        &self.c
    }
    pub fn q(&self) -> &DMatrix<f64> {
        &self.q
    }
    pub fn r(&self) -> &DMatrix<f64> {
        &self.r
    }
    /// Steady-state error covariance P̄.
    pub fn pbar(&self) -> &DMatrix<f64> {
        &self.pbar
    }
    /// Relative residual of g̃(h(P̄)) = P̄.
    pub fn residual(&self) -> f64 {
        self.residual
    }
    /// Doubling steps used.
    pub fn iterations(&self) -> usize {
        self.iterations
    }
    /// Spectral radius ρ(A).
    pub fn rho(&self) -> f64 {
        self.rho
    }

    /// `[Tr h^0(P̄), ..., Tr h^n(P̄)]`. Entries that overflow are `+inf` (never NaN).
    pub fn h_traces(&self, n: usize) -> Vec<f64> {
        self.weighted_traces(1.0, n)
    }

    /// `w_i = a^i Tr h^i(P̄)` for i = 0..=n, computed as the trace of Y_i = a^i h^i(P̄) with
    /// Y_{i+1} = a A Y_i A' + a^{i+1} Q, so the weight is carried inside and the sequence stays
    /// finite whenever a ρ(A)² < 1 even where Tr h^i(P̄) alone would overflow.
    pub fn weighted_traces(&self, weight: f64, n: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(n + 1);
        if self.n() == 1 {
            let (a2, q, mut y) = (self.a[(0, 0)].powi(2), self.q[(0, 0)], self.pbar[(0, 0)]);
            let mut wpow = 1.0;
            out.push(y);
            for _ in 0..n {
                wpow *= weight;
                y = weight * a2 * y + wpow * q;
                out.push(if y.is_finite() { y } else { f64::INFINITY });
            }
            return out;
        }
        let dim = self.n();
        let at = self.a.transpose();
        let mut y = self.pbar.clone();
        let mut tmp = DMatrix::<f64>::zeros(dim, dim);
        let mut wpow = 1.0;
        out.push(y.trace());
        for _ in 0..n {
            wpow *= weight;
            tmp.gemm(1.0, &self.a, &y, 0.0);
            y.gemm(weight, &tmp, &at, 0.0);
            y += &self.q * wpow;
            let tr = y.trace();
            if !tr.is_finite() {
                // Later entries would mix inf and -inf into NaN: they are all +inf.
                out.resize(n + 1, f64::INFINITY);
                return out;
            }
            out.push(tr);
        }
        out
    }

    /// [`LinearSystem::weighted_traces`] for `n` given as a wide count: refuses `n` above
    /// [`MAX_TRACES`] before allocating.
    pub fn checked_weighted_traces(&self, weight: f64, n: u128, arg: &str) -> Result<Vec<f64>> {
        if n >= MAX_TRACES {
            return Err(Error::TooLarge {
                arg: arg.into(),
                requested: n + 1,
                limit: MAX_TRACES,
            });
        }
        if !(weight.is_finite() && weight >= 0.0) {
            return Err(Error::invalid(
                "weight",
                format!("must be finite and >= 0, got {weight}"),
            ));
        }
        Ok(self.weighted_traces(weight, n as usize))
    }

    /// Solves the Stein equation X = s A X A' + C0 by Smith's doubling; `None` if s ρ(A)² >= 1.
    pub fn stein(&self, s: f64, c0: &DMatrix<f64>) -> Result<Option<DMatrix<f64>>> {
        if s * self.rho * self.rho >= 1.0 {
            return Ok(None);
        }
        let mut b = &self.a * s.sqrt();
        let mut x = c0.clone();
        for _ in 0..200 {
            let inc = &b * &x * b.transpose();
            x += &inc;
            b = &b * &b;
            let rel = frob(&inc) / frob(&x).max(f64::MIN_POSITIVE);
            if !rel.is_finite() {
                return Ok(None);
            }
            if rel <= 1e-16 || frob(&b) == 0.0 {
                return Ok(Some(x));
            }
        }
        Err(Error::NotConverged {
            what: "Stein equation (Smith doubling)",
            iterations: 200,
            residual: f64::NAN,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar(a: f64, c: f64, q: f64, r: f64) -> LinearSystem {
        LinearSystem::new(
            DMatrix::from_element(1, 1, a),
            DMatrix::from_element(1, 1, c),
            DMatrix::from_element(1, 1, q),
            DMatrix::from_element(1, 1, r),
        )
        .unwrap()
    }

    /// Scalar closed form: the prior p solves p = a²p r/(c²p + r) + q, a quadratic.
    #[test]
    fn scalar_pbar_matches_quadratic() {
        let (a, c, q, r) = (1.2_f64, 0.7_f64, 0.8_f64, 0.8_f64);
        // c² p² + (r - a² r - q c²) p - q r = 0
        let (qa, qb, qc) = (c * c, r - a * a * r - q * c * c, -q * r);
        let prior = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
        let pbar = prior - prior * prior * c * c / (c * c * prior + r);
        let s = scalar(a, c, q, r);
        assert!(
            (s.pbar()[(0, 0)] - pbar).abs() < 1e-13 * pbar,
            "{} vs {pbar}",
            s.pbar()[(0, 0)]
        );
        assert!(s.residual() < 1e-13);
        let tr = s.h_traces(3);
        assert!((tr[1] - (a * a * pbar + q)).abs() < 1e-13);
        assert!((tr[2] - (a * a * tr[1] + q)).abs() < 1e-12);
    }

    #[test]
    fn weighted_traces_match_plain_ones() {
        let mut a = DMatrix::<f64>::zeros(2, 2);
        a[(0, 0)] = 1.1;
        a[(0, 1)] = 0.3;
        a[(1, 1)] = 0.7;
        let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.5]);
        let q = DMatrix::<f64>::identity(2, 2) * 0.5;
        let r = DMatrix::from_element(1, 1, 0.3);
        let s = LinearSystem::new(a, c, q, r).unwrap();
        let tr = s.h_traces(20);
        let w = s.weighted_traces(0.4, 20);
        for i in 0..=20 {
            assert!((w[i] - 0.4f64.powi(i as i32) * tr[i]).abs() <= 1e-12 * tr[i]);
            if i > 0 {
                assert!(tr[i] > tr[i - 1], "Lemma 2.1: traces increase");
            }
        }
        assert!(s.residual() < 1e-12);
    }

    #[test]
    fn undetectable_is_named() {
        let a = DMatrix::from_row_slice(2, 2, &[2.0, 0.0, 0.0, 0.5]);
        let c = DMatrix::from_row_slice(1, 2, &[0.0, 1.0]);
        let q = DMatrix::<f64>::identity(2, 2);
        let r = DMatrix::from_element(1, 1, 1.0);
        let e = LinearSystem::new(a, c, q, r).unwrap_err();
        assert!(e.to_string().contains("not detectable"), "{e}");
    }

    #[test]
    fn bad_shapes_and_definiteness() {
        let one = DMatrix::from_element(1, 1, 1.0);
        let e = LinearSystem::new(one.clone(), one.clone(), one.clone(), -one.clone()).unwrap_err();
        assert!(e.to_string().starts_with("R:"), "{e}");
        let e = LinearSystem::new(one.clone(), one.clone(), -one.clone(), one.clone()).unwrap_err();
        assert!(e.to_string().starts_with("Q:"), "{e}");
        let e = LinearSystem::new(
            DMatrix::<f64>::identity(2, 2),
            one.clone(),
            one.clone(),
            one.clone(),
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("C:"), "{e}");
        let e = LinearSystem::new(
            DMatrix::from_element(1, 1, f64::NAN),
            one.clone(),
            one.clone(),
            one,
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("A:"), "{e}");
    }

    #[test]
    fn stein_matches_series() {
        let s = scalar(1.2, 0.7, 0.8, 0.8);
        let c0 = DMatrix::from_element(1, 1, 1.0);
        let x = s.stein(0.5, &c0).unwrap().unwrap()[(0, 0)];
        assert!((x - 1.0 / (1.0 - 0.5 * 1.44)).abs() < 1e-13);
        assert!(s.stein(0.8, &c0).unwrap().is_none());
    }
}
