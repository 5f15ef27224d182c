//! Spectra of the system matrices: eigenvalues, the spectral radius ρ(A) and the PBH test for
//! detectability of (A, C).
//!
//! ρ(A) decides which costs are finite (J_max needs a ρ(A)² < 1, Model note 5), and the paper's
//! P̄ exists only when (A, C) is detectable (the paper assumes it observable, Sec. II-A).
//! [`detectability_error`] turns a failed Riccati solve into a message naming the modes of A
//! that C cannot see.

use nalgebra::{Complex, DMatrix};

use crate::error::{Error, Result};

/// Iteration cap of the Schur and SVD decompositions used here.
const DECOMPOSITION_MAX_ITER: usize = 10_000;

/// Eigenvalues with |λ| at least `1 - UNIT_CIRCLE_MARGIN` count as on or outside the unit circle.
const UNIT_CIRCLE_MARGIN: f64 = 1e-10;

/// A PBH matrix whose smallest singular value is at most this times max(|A|, |C|, 1) (largest
/// entries) is taken as rank-deficient.
const RANK_TOL: f64 = 1e-9;

/// Eigenvalues of a general square matrix (from its real Schur form), without panicking: a Schur
/// iteration that does not converge is an [`Error::NotConverged`].
pub fn eigenvalues(m: &DMatrix<f64>) -> Result<Vec<Complex<f64>>> {
    let schur = nalgebra::linalg::Schur::try_new(m.clone(), f64::EPSILON, DECOMPOSITION_MAX_ITER)
        .ok_or(Error::NotConverged {
        what: "Schur decomposition",
        iterations: DECOMPOSITION_MAX_ITER,
        residual: f64::NAN,
    })?;
    Ok(schur.complex_eigenvalues().iter().copied().collect())
}

/// Spectral radius ρ(M) = max |eigenvalue| of a square matrix (0 for an empty one).
pub fn spectral_radius(m: &DMatrix<f64>) -> Result<f64> {
    Ok(eigenvalues(m)?.iter().map(|z| z.norm()).fold(0.0, f64::max))
}

/// The PBH matrix [A - λI; C] of one eigenvalue λ, in complex arithmetic.
fn pbh_matrix(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    eigenvalue: Complex<f64>,
) -> DMatrix<Complex<f64>> {
    let n = a.nrows();
    let m = c.nrows();
    let mut pbh = DMatrix::<Complex<f64>>::zeros(n + m, n);
    for i in 0..n {
        for j in 0..n {
            let shift = if i == j {
                eigenvalue
            } else {
                Complex::new(0.0, 0.0)
            };
            pbh[(i, j)] = Complex::new(a[(i, j)], 0.0) - shift;
        }
    }
    for i in 0..m {
        for j in 0..n {
            pbh[(n + i, j)] = Complex::new(c[(i, j)], 0.0);
        }
    }
    pbh
}

/// PBH (Popov-Belevitch-Hautus) test: the eigenvalues λ of A with |λ| >= 1 (up to a margin of
/// 1e-10) for which [A - λI; C] loses rank, i.e. the modes C does not see that do not decay.
/// (A, C) is detectable iff the list is empty. `a` is n×n, `c` is m×n.
pub fn undetectable_modes(a: &DMatrix<f64>, c: &DMatrix<f64>) -> Result<Vec<Complex<f64>>> {
    let scale = a.amax().max(c.amax()).max(1.0);
    let mut undetectable = Vec::new();
    for eigenvalue in eigenvalues(a)? {
        if eigenvalue.norm() < 1.0 - UNIT_CIRCLE_MARGIN {
            continue;
        }
        let svd = pbh_matrix(a, c, eigenvalue)
            .try_svd(false, false, f64::EPSILON, DECOMPOSITION_MAX_ITER)
            .ok_or(Error::NotConverged {
                what: "SVD in the detectability test",
                iterations: DECOMPOSITION_MAX_ITER,
                residual: f64::NAN,
            })?;
        let smallest_singular_value = svd
            .singular_values
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        if smallest_singular_value <= RANK_TOL * scale {
            undetectable.push(eigenvalue);
        }
    }
    Ok(undetectable)
}

/// The error to report when (A, C) is not detectable: an [`Error::InvalidArgument`] on "(A, C)"
/// naming the undetectable eigenvalues. `None` when (A, C) passes the PBH test of
/// [`undetectable_modes`], or when that test cannot be run (a decomposition did not converge).
pub fn detectability_error(a: &DMatrix<f64>, c: &DMatrix<f64>) -> Option<Error> {
    match undetectable_modes(a, c) {
        Ok(modes) if !modes.is_empty() => Some(Error::invalid(
            "(A, C)",
            format!(
                "not detectable: eigenvalue(s) {} of A with |λ| >= 1 are unobservable from C",
                modes
                    .iter()
                    .map(|z| format!("{:.6}{:+.6}i", z.re, z.im))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_has_unit_spectral_radius() {
        let (cos, sin) = (0.6, 0.8);
        let rotation = DMatrix::from_row_slice(2, 2, &[cos, -sin, sin, cos]) * 1.5;
        let mut eig = eigenvalues(&rotation).unwrap();
        eig.sort_by(|x, y| x.im.total_cmp(&y.im));
        assert!((eig[0] - Complex::new(0.9, -1.2)).norm() < 1e-14, "{eig:?}");
        assert!((eig[1] - Complex::new(0.9, 1.2)).norm() < 1e-14, "{eig:?}");
        assert!((spectral_radius(&rotation).unwrap() - 1.5).abs() < 1e-14);
    }

    #[test]
    fn pbh_finds_only_unseen_unstable_modes() {
        let a = DMatrix::from_row_slice(3, 3, &[2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5]);
        // C sees the mode at 2 only: 1 (marginal) and 0.5 (stable) are unseen.
        let c = DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]);
        let modes = undetectable_modes(&a, &c).unwrap();
        assert_eq!(modes.len(), 1, "{modes:?}");
        assert!((modes[0] - Complex::new(1.0, 0.0)).norm() < 1e-12);
        let e = detectability_error(&a, &c).unwrap();
        assert!(e.to_string().starts_with("(A, C): not detectable"), "{e}");
        // Seeing the marginal mode too makes (A, C) detectable.
        let c = DMatrix::from_row_slice(1, 3, &[1.0, 1.0, 0.0]);
        assert!(undetectable_modes(&a, &c).unwrap().is_empty());
        assert!(detectability_error(&a, &c).is_none());
    }
}
