//! The Stein (discrete Lyapunov) equation X = s A X A' + C0, solved by Smith's doubling.
//!
//! It sums the series X = Σ_i s^i A^i C0 (A')^i, which converges iff s ρ(A)² < 1. With
//! s = a = 1 - λ and C0 = λ P̄ + a Q its trace is the all-blocked cost
//! J_max = Σ_i λ a^i Tr h^i(P̄) of Sec. IV-C (the sum before eq. (14)), finite iff a ρ(A)² < 1
//! (Model note 5); see [`crate::LinearSystem::j_max`].

use nalgebra::DMatrix;

use crate::error::{Error, Result};
use crate::system::linalg::frobenius_norm;

/// Most doubling steps; step k adds 2^k terms of the series, so 200 is never reached when the
/// series converges.
const MAX_DOUBLINGS: usize = 200;

/// Stop when a step changes X by at most this much relative to X (Frobenius norms).
const RELATIVE_STEP_TOL: f64 = 1e-16;

/// Solves the Stein equation X = s A X A' + C0 (A and C0 n×n, s >= 0) by Smith's doubling:
/// with B_0 = √s A and X_0 = C0, X_{k+1} = X_k + B_k X_k B_k' and B_{k+1} = B_k², so X_k is the
/// series' first 2^k terms.
///
/// The series converges iff s ρ(A)² < 1, which the caller is expected to have checked (as
/// [`crate::LinearSystem::stein`] does). Returns `Ok(None)` if the iterates overflow (a divergent
/// series) and [`Error::NotConverged`] if 200 steps do not meet the tolerance.
pub fn solve(a: &DMatrix<f64>, s: f64, c0: &DMatrix<f64>) -> Result<Option<DMatrix<f64>>> {
    let mut b = a * s.sqrt();
    let mut x = c0.clone();
    for _ in 0..MAX_DOUBLINGS {
        let increment = &b * &x * b.transpose();
        x += &increment;
        b = &b * &b;
        let relative_step = frobenius_norm(&increment) / frobenius_norm(&x).max(f64::MIN_POSITIVE);
        if !relative_step.is_finite() {
            return Ok(None);
        }
        if relative_step <= RELATIVE_STEP_TOL || frobenius_norm(&b) == 0.0 {
            return Ok(Some(x));
        }
    }
    Err(Error::NotConverged {
        what: "Stein equation (Smith doubling)",
        iterations: MAX_DOUBLINGS,
        residual: f64::NAN,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_matches_geometric_series() {
        let a = DMatrix::from_element(1, 1, 1.2);
        let c0 = DMatrix::from_element(1, 1, 1.0);
        let x = solve(&a, 0.5, &c0).unwrap().unwrap()[(0, 0)];
        assert!((x - 1.0 / (1.0 - 0.5 * 1.44)).abs() < 1e-13);
        // s ρ(A)² = 1.152 > 1: the series diverges and the iterates overflow.
        assert!(solve(&a, 0.8, &c0).unwrap().is_none());
    }

    #[test]
    fn matrix_solution_satisfies_the_equation() {
        let a = DMatrix::from_row_slice(2, 2, &[0.9, 0.4, -0.3, 0.7]);
        let c0 = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]);
        let s = 0.6;
        let x = solve(&a, s, &c0).unwrap().unwrap();
        let residual = &x - (&a * &x * a.transpose() * s + &c0);
        assert!(frobenius_norm(&residual) < 1e-13 * frobenius_norm(&x));
    }

    #[test]
    fn nilpotent_stops_early() {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.0, 0.0]);
        let c0 = DMatrix::<f64>::identity(2, 2);
        let x = solve(&a, 1.0, &c0).unwrap().unwrap();
        assert_eq!(x, DMatrix::from_row_slice(2, 2, &[2.0, 0.0, 0.0, 1.0]));
    }
}
