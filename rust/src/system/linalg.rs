//! Small dense-matrix helpers shared by the system, Riccati and Stein modules.

use nalgebra::DMatrix;

/// Frobenius norm ||M||_F = sqrt(Σ m_ij²) (nalgebra's `norm` of a matrix).
pub(crate) fn frobenius_norm(m: &DMatrix<f64>) -> f64 {
    m.norm()
}

/// Replaces a square matrix by its symmetric part (M + M')/2, in place, so that round-off in a
/// covariance computation does not accumulate an antisymmetric part.
pub(crate) fn symmetrize(m: &mut DMatrix<f64>) {
    let n = m.nrows();
    for i in 0..n {
        for j in (i + 1)..n {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetrize_averages_off_diagonal_pairs() {
        let mut m = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 4.0, 5.0]);
        symmetrize(&mut m);
        assert_eq!(m, DMatrix::from_row_slice(2, 2, &[1.0, 3.0, 3.0, 5.0]));
        assert_eq!(frobenius_norm(&m), 44.0f64.sqrt());
    }
}
