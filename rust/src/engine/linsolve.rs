//! Sparse LU solves for the engine: faer's simplicial sparse LU (a COLAMD column ordering,
//! partial pivoting, fill found from the values' pattern at each factorization), and a dense LU
//! (nalgebra) below [`DENSE_MAX`] unknowns, where the sparse analysis costs more than it saves.
//!
//! The ordering is the expensive part (about a third of a 10^4-state solve), so one ordering is
//! computed per product, on the pattern of I - K, and reused for the stationary law and every
//! shift s of I - s K0: a simplicial factorization needs only a column order (it finds the fill
//! from the matrix it is given), and an order made for one pattern is good for a pattern close
//! to it.

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{
    factorize_symbolic_lu, LuRef, LuSymbolicParams, NumericLu, SymbolicLu,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};
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

    /// The column ordering for the sparse path (None below [`DENSE_MAX`]), made for this
    /// pattern and valid for any matrix of its order.
    pub fn analyse(&self) -> Result<Option<Ordering>> {
        if self.n <= DENSE_MAX {
            return Ok(None);
        }
        let params = LuSymbolicParams {
            // Simplicial: the symbolic part is then the ordering alone (the chains' factors are
            // too sparse for supernodes to pay, and the ordering can be shared).
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        };
        factorize_symbolic_lu(self.symbolic(), params)
            .map(|s| Ordering(Arc::new(s)))
            .map(Some)
            .map_err(|e| Error::invalid("max_states", format!("sparse LU analysis failed: {e:?}")))
    }
}

/// A simplicial LU analysis of some pattern: a COLAMD column order, shared by the
/// factorizations of matrices of the same order (good for patterns close to the analysed one).
#[derive(Debug, Clone)]
pub struct Ordering(Arc<SymbolicLu<usize>>);

enum Inner<T: Scalar> {
    Dense(nalgebra::LU<T, nalgebra::Dyn, nalgebra::Dyn>),
    Sparse(Box<(Ordering, NumericLu<usize, T>)>),
}

/// The LU factors of a matrix M given on a [`Pattern`], ready to solve M x = b or, when built
/// `transposed`, M^T x = b.
pub struct Factor<T: Scalar> {
    inner: Inner<T>,
    transposed: bool,
    n: usize,
}

impl<T: Scalar> Factor<T> {
    /// Factors the matrix with entries `vals` on `pattern`, in the column order `symbolic`
    /// (from [`Pattern::analyse`] of this pattern or one close to it, of the same order).
    pub fn new(
        pattern: &Pattern,
        symbolic: Option<&Ordering>,
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
                let fail =
                    |e: String| Error::invalid("max_states", format!("sparse LU failed: {e}"));
                let mut mem = MemBuffer::try_new(
                    sym.0
                        .factorize_numeric_lu_scratch::<T>(Par::Seq, Default::default()),
                )
                .map_err(|e| fail(format!("{e:?}")))?;
                let mut numeric = NumericLu::new();
                sym.0
                    .factorize_numeric_lu(
                        &mut numeric,
                        m,
                        Par::Seq,
                        MemStack::new(&mut mem),
                        Default::default(),
                    )
                    .map_err(|e| fail(format!("{e:?}")))?;
                Inner::Sparse(Box::new((sym.clone(), numeric)))
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
            Inner::Sparse(f) => {
                let (sym, numeric) = &**f;
                // Sound: `numeric` came from `sym`'s factorize_numeric_lu (simplicial both).
                let lu = LuRef::new_unchecked(&sym.0, numeric);
                let Ok(mut mem) =
                    MemBuffer::try_new(sym.0.solve_in_place_scratch::<T>(1, Par::Seq))
                else {
                    return false;
                };
                let m = MatMut::from_column_major_slice_mut(b, self.n, 1);
                let stack = MemStack::new(&mut mem);
                if self.transposed {
                    lu.solve_transpose_in_place_with_conj(Conj::No, m, Par::Seq, stack);
                } else {
                    lu.solve_in_place_with_conj(Conj::No, m, Par::Seq, stack);
                }
            }
        }
        b.iter().all(|x| nalgebra::ComplexField::is_finite(x))
    }
}
