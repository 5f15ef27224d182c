//! The process and sensor model of the paper's Sec. II-A, eqs. (1)-(2): x_{k+1} = A x_k + w_k,
//! y_k = C x_k + v_k with w ~ N(0, Q), v ~ N(0, R), validated once, with its steady-state error
//! covariance P̄ (eq. (5)) and the traces Tr h^i(P̄) every cost of the crate is built from.
//!
//! P̄ is the positive semi-definite solution of g̃(h(X)) = X, with h(X) = A X A' + Q and
//! g̃(X) = X - X C' (C X C' + R)^{-1} C X; [`riccati`] computes it.
//!
//! The closed-form solvers the model is built on live here with it, since nothing else needs
//! them: [`riccati`] (P̄ by structured doubling), [`stein`] (the Stein equation behind J_max) and
//! [`spectral`] (ρ(A) and the detectability test).
//!
//! Only the model's own methods of [`LinearSystem`] are here; the quantities of the analysis are
//! its methods in the `analysis` module.

use nalgebra::DMatrix;

use crate::error::{Error, Result};
use linalg::symmetrize;
use spectral::{detectability_error, spectral_radius};

mod linalg;
pub mod riccati;
pub mod spectral;
pub mod stein;

/// Most traces a single call will compute (8 bytes each).
pub const MAX_TRACES: u128 = 200_000_000;

/// Default relative tolerance of the doubling iteration.
pub const DEFAULT_TOL: f64 = 1e-14;
/// Default cap on doubling steps (each squares the closed-loop contraction).
pub const DEFAULT_MAX_ITER: usize = 200;

/// Relative tolerance of the symmetry and semi-definiteness checks of Q and R.
const SYMMETRY_TOL: f64 = 1e-10;

/// A validated LTI system x_{k+1} = A x_k + w_k, y_k = C x_k + v_k (eqs. (1)-(2)) with its
/// steady state P̄.
#[derive(Debug, Clone)]
pub struct LinearSystem {
    a: DMatrix<f64>,
    c: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    pbar: DMatrix<f64>,
    residual: f64,
    iterations: usize,
    spectral_radius: f64,
}

/// Checks that `m` is `rows`×`cols` with finite entries; errors name `arg`.
fn check_shape_and_finite(arg: &str, m: &DMatrix<f64>, rows: usize, cols: usize) -> Result<()> {
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

/// Checks that `m` is symmetric up to a relative 1e-10 of its largest entry.
fn check_symmetric(arg: &str, m: &DMatrix<f64>) -> Result<()> {
    let scale = m.amax().max(f64::MIN_POSITIVE);
    let asymmetry = (m - m.transpose()).amax();
    if asymmetry > SYMMETRY_TOL * scale {
        return Err(Error::invalid(
            arg,
            format!("must be symmetric (largest |X - X'| entry is {asymmetry:.3e})"),
        ));
    }
    Ok(())
}

/// Validates shapes, finiteness, the solver settings, and that Q is symmetric PSD and R symmetric
/// PD. Returns the symmetrised (Q, R).
fn validate(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    tol: f64,
    max_iter: usize,
) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    let n = a.nrows();
    if n == 0 {
        return Err(Error::invalid("A", "must be a non-empty square matrix"));
    }
    check_shape_and_finite("A", a, n, n)?;
    let m = c.nrows();
    if m == 0 {
        return Err(Error::invalid("C", "must have at least one row"));
    }
    check_shape_and_finite("C", c, m, n)?;
    check_shape_and_finite("Q", &q, n, n)?;
    check_shape_and_finite("R", &r, m, m)?;
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
    let q_min_eigenvalue = q.clone().symmetric_eigenvalues().min();
    if q_min_eigenvalue < -SYMMETRY_TOL * q.amax().max(f64::MIN_POSITIVE) {
        return Err(Error::invalid(
            "Q",
            format!("must be positive semi-definite (smallest eigenvalue {q_min_eigenvalue:.3e})"),
        ));
    }
    let r_min_eigenvalue = r.clone().symmetric_eigenvalues().min();
    if r_min_eigenvalue <= 0.0 || r.clone().cholesky().is_none() {
        return Err(Error::invalid(
            "R",
            format!("must be positive definite (smallest eigenvalue {r_min_eigenvalue:.3e})"),
        ));
    }
    Ok((q, r))
}

impl LinearSystem {
    /// Validates (A, C, Q, R) and solves for P̄ with the default tolerance ([`DEFAULT_TOL`],
    /// [`DEFAULT_MAX_ITER`]).
    pub fn new(a: DMatrix<f64>, c: DMatrix<f64>, q: DMatrix<f64>, r: DMatrix<f64>) -> Result<Self> {
        Self::with_tolerance(a, c, q, r, DEFAULT_TOL, DEFAULT_MAX_ITER)
    }

    /// As [`LinearSystem::new`] with an explicit tolerance and iteration cap of the Riccati
    /// doubling ([`riccati::steady_state`]).
    ///
    /// A must be n×n (n >= 1), C m×n (m >= 1), Q n×n symmetric positive semi-definite, R m×m
    /// symmetric positive definite, all finite; each violation is an [`Error::InvalidArgument`]
    /// naming the matrix. When the solver fails because (A, C) is not detectable, the error names
    /// the undetectable eigenvalues of A instead.
    pub fn with_tolerance(
        a: DMatrix<f64>,
        c: DMatrix<f64>,
        q: DMatrix<f64>,
        r: DMatrix<f64>,
        tol: f64,
        max_iter: usize,
    ) -> Result<Self> {
        let (q, r) = validate(&a, &c, q, r, tol, max_iter)?;
        let spectral_radius = spectral_radius(&a)?;
        let steady = riccati::steady_state(&a, &c, &q, &r, tol, max_iter).map_err(|e| match e {
            Error::NotConverged { .. } => detectability_error(&a, &c).unwrap_or(e),
            other => other,
        })?;
        Ok(LinearSystem {
            a,
            c,
            q,
            r,
            pbar: steady.pbar,
            residual: steady.residual,
            iterations: steady.iterations,
            spectral_radius,
        })
    }

    /// A scalar system x' = a x + w, y = c x + v with noise variances q and r (1×1 matrices).
    pub fn scalar(a: f64, c: f64, q: f64, r: f64) -> Result<Self> {
        let m = |x: f64| DMatrix::from_element(1, 1, x);
        LinearSystem::new(m(a), m(c), m(q), m(r))
    }

    /// Relative residual ||g̃(h(X)) - X||_F / ||X||_F of the fixed-point equation of P̄
    /// (absolute when X = 0; `+inf` when C h(X) C' + R is not positive definite).
    pub fn fixed_point_residual(&self, x: &DMatrix<f64>) -> f64 {
        riccati::fixed_point_residual(&self.a, &self.c, &self.q, &self.r, x)
    }

    /// The Lyapunov operator h(X) = A X A' + Q (Sec. II-A): the remote error covariance one step
    /// after a packet is lost, eq. (10).
    pub fn h(&self, x: &DMatrix<f64>) -> DMatrix<f64> {
        &self.a * x * self.a.transpose() + &self.q
    }

    /// State dimension n_x.
    pub fn n(&self) -> usize {
        self.a.nrows()
    }
    /// System matrix A (n×n).
    pub fn a(&self) -> &DMatrix<f64> {
        &self.a
    }
    /// Measurement matrix C (m×n).
    pub fn c(&self) -> &DMatrix<f64> {
        &self.c
    }
    /// Process noise covariance Q (n×n, symmetrised).
    pub fn q(&self) -> &DMatrix<f64> {
        &self.q
    }
    /// Measurement noise covariance R (m×m, symmetrised).
    pub fn r(&self) -> &DMatrix<f64> {
        &self.r
    }
    /// Steady-state error covariance P̄ of the sensor's Kalman filter, eq. (5).
    pub fn pbar(&self) -> &DMatrix<f64> {
        &self.pbar
    }
    /// Relative residual of g̃(h(P̄)) = P̄ ([`LinearSystem::fixed_point_residual`] of P̄).
    pub fn residual(&self) -> f64 {
        self.residual
    }
    /// Doubling steps used.
    pub fn iterations(&self) -> usize {
        self.iterations
    }
    /// Spectral radius ρ(A), the largest |eigenvalue| of A.
    pub fn spectral_radius(&self) -> f64 {
        self.spectral_radius
    }

    /// `[Tr h^0(P̄), ..., Tr h^n(P̄)]`, strictly increasing by Lemma 2.1, eq. (7). Entries that
    /// overflow are `+inf` (never NaN).
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
            let mut weight_pow = 1.0;
            out.push(y);
            for _ in 0..n {
                weight_pow *= weight;
                y = weight * a2 * y + weight_pow * q;
                out.push(if y.is_finite() { y } else { f64::INFINITY });
            }
            return out;
        }
        let dim = self.n();
        let at = self.a.transpose();
        let mut y = self.pbar.clone();
        let mut ay = DMatrix::<f64>::zeros(dim, dim);
        let mut weight_pow = 1.0;
        out.push(y.trace());
        for _ in 0..n {
            weight_pow *= weight;
            ay.gemm(1.0, &self.a, &y, 0.0);
            y.gemm(weight, &ay, &at, 0.0);
            y += &self.q * weight_pow;
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

    /// [`LinearSystem::weighted_traces`] for `n` given as a wide count: refuses `n` at or above
    /// [`MAX_TRACES`] before allocating ([`Error::TooLarge`] naming `arg`), and a weight that is
    /// not finite and >= 0.
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

    /// Solves the Stein equation X = s A X A' + C0 ([`stein::solve`]); `Ok(None)` if
    /// s ρ(A)² >= 1, where the series Σ s^i A^i C0 (A')^i diverges (Model note 5).
    pub fn stein(&self, s: f64, c0: &DMatrix<f64>) -> Result<Option<DMatrix<f64>>> {
        if s * self.spectral_radius * self.spectral_radius >= 1.0 {
            return Ok(None);
        }
        stein::solve(&self.a, s, c0)
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
