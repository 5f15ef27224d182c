//! Sparse LU solves for the engine: faer's sparse LU (COLAMD ordering, partial pivoting; the
//! symbolic analysis of a pattern is kept and reused for every shift s of I - s K0), and a dense
//! LU (nalgebra) below [`DENSE_MAX`] unknowns, where the sparse analysis costs more than it saves.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::MatMut;
use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};

/// Largest system solved densely.
pub const DENSE_MAX: usize = 64;

/// The scalars the engine solves with: f64 and complex f64.
pub trait Scalar:
    nalgebra::ComplexField<RealField = f64> + faer::traits::ComplexField + Copy + Default
{
    /// `x` as this scalar.
    fn of_real(x: f64) -> Self;
}

impl Scalar for f64 {
    fn of_real(x: f64) -> Self {
        x
    }
}

impl Scalar for faer::c64 {
    fn of_real(x: f64) -> Self {
        faer::c64::new(x, 0.0)
    }
}

/// A sparse pattern in CSC form (row indices sorted within each column).
#[derive(Debug, Clone)]
pub struct Pattern {
    /// Order.
    pub n: usize,
    /// Column pointers.
    pub col_ptr: Vec<usize>,
    /// Row of each entry.
    pub row_idx: Vec<usize>,
}

impl Pattern {
    fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx)
    }

    /// The symbolic LU analysis, for the sparse path (None below [`DENSE_MAX`]).
    pub fn analyse(&self) -> Result<Option<SymbolicLu<usize>>> {
        if self.n <= DENSE_MAX {
            return Ok(None);
        }
        SymbolicLu::try_new(self.symbolic())
            .map(Some)
            .map_err(|e| Error::invalid("max_states", format!("sparse LU analysis failed: {e:?}")))
    }
}

enum Inner<T: Scalar> {
    Dense(nalgebra::LU<T, nalgebra::Dyn, nalgebra::Dyn>),
    Sparse(Box<Lu<usize, T>>),
}

/// The LU factors of a matrix M given on a [`Pattern`], ready to solve M x = b or, when built
/// `transposed`, M^T x = b.
pub struct Factor<T: Scalar> {
    inner: Inner<T>,
    transposed: bool,
    n: usize,
}

impl<T: Scalar> Factor<T> {
    /// Factors the matrix with entries `vals` on `pattern`, reusing the analysis `symbolic`
    /// (from [`Pattern::analyse`]).
    pub fn new(
        pattern: &Pattern,
        symbolic: Option<&SymbolicLu<usize>>,
        vals: &[T],
        transposed: bool,
    ) -> Result<Self> {
        let n = pattern.n;
        let inner = match symbolic {
            None => {
                let mut d = DMatrix::<T>::zeros(n, n);
                for j in 0..n {
                    let r = pattern.col_ptr[j]..pattern.col_ptr[j + 1];
                    for (&i, &v) in pattern.row_idx[r.clone()].iter().zip(&vals[r]) {
                        if transposed {
                            d[(j, i)] = v;
                        } else {
                            d[(i, j)] = v;
                        }
                    }
                }
                Inner::Dense(d.lu())
            }
            Some(sym) => {
                let m = SparseColMatRef::new(pattern.symbolic(), vals);
                let lu = Lu::try_new_with_symbolic(sym.clone(), m).map_err(|e| {
                    Error::invalid("max_states", format!("sparse LU failed: {e:?}"))
                })?;
                Inner::Sparse(Box::new(lu))
            }
        };
        Ok(Factor {
            inner,
            transposed,
            n,
        })
    }

    /// Solves in place; false when the matrix is singular or the solution is not finite.
    pub fn solve(&self, b: &mut [T]) -> bool {
        debug_assert_eq!(b.len(), self.n);
        match &self.inner {
            Inner::Dense(lu) => {
                let mut v = DVector::from_column_slice(b);
                if !lu.solve_mut(&mut v) {
                    return false;
                }
                b.copy_from_slice(v.as_slice());
            }
            Inner::Sparse(lu) => {
                let m = MatMut::from_column_major_slice_mut(b, self.n, 1);
                if self.transposed {
                    lu.solve_transpose_in_place(m);
                } else {
                    lu.solve_in_place(m);
                }
            }
        }
        b.iter().all(|x| nalgebra::ComplexField::is_finite(x))
    }
}
