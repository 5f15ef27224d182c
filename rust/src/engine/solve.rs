//! The solvers on a product automaton: the stationary law of K = K0 + K1, nu = pi K1,
//! w = (I - K0)^-1 1, the arrival check, the M-matrix test, ρ(K0), and the coupled Stein
//! equations that give J.

use faer::c64;
use nalgebra::DMatrix;

use crate::engine::graph::{closed_classes, is_acyclic, strongly_connected};
use crate::engine::linsolve::{Factor, Ordering, Pattern, Scalar};
use crate::engine::product::{Product, SparseRows};
use crate::error::{Error, Result};
use crate::system::LinearSystem;

/// A cancellation flag polled between the solves of a long computation (never set when None).
#[derive(Clone, Copy, Default)]
pub(crate) struct Stop<'a>(pub Option<&'a std::sync::atomic::AtomicBool>);

impl Stop<'_> {
    /// [`Error::Interrupted`] once the flag is set.
    pub(crate) fn check(&self) -> Result<()> {
        match self.0 {
            Some(f) if f.load(std::sync::atomic::Ordering::Relaxed) => Err(Error::Interrupted),
            _ => Ok(()),
        }
    }
}

/// The K0 pattern of (I - s K0)^T in CSC form (column e holds row e of K0 and the diagonal),
/// with the index of each entry's K0 value.
pub(crate) struct ShiftedK0 {
    pattern: Pattern,
    /// K0[e, f] of each entry (0 where only the diagonal is).
    k0: Vec<f64>,
    /// Whether each entry is on the diagonal.
    diag: Vec<bool>,
    symbolic: Option<Ordering>,
}

impl ShiftedK0 {
    /// The pattern of (I - s K0)^T; `ordering` is a column order to reuse (that of I - K when
    /// the stationary law was solved on all states), else one is computed.
    pub(crate) fn new(k0: &SparseRows, ordering: Option<Option<Ordering>>) -> Result<Self> {
        let n = k0.n();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(k0.data.len() + n);
        let mut vals = Vec::with_capacity(k0.data.len() + n);
        let mut diag = Vec::with_capacity(k0.data.len() + n);
        col_ptr.push(0);
        for e in 0..n {
            let mut placed = false;
            for (f, v) in k0.row(e) {
                if !placed && f >= e {
                    if f > e {
                        row_idx.push(e);
                        vals.push(0.0);
                        diag.push(true);
                    }
                    placed = true;
                }
                row_idx.push(f);
                vals.push(v);
                diag.push(f == e);
            }
            if !placed {
                row_idx.push(e);
                vals.push(0.0);
                diag.push(true);
            }
            col_ptr.push(row_idx.len());
        }
        let pattern = Pattern {
            n,
            col_ptr,
            row_idx,
        };
        let symbolic = match ordering {
            Some(o) => o,
            None => pattern.analyse()?,
        };
        Ok(ShiftedK0 {
            pattern,
            k0: vals,
            diag,
            symbolic,
        })
    }

    /// Factors (I - s K0)^T, to solve (I - s K0) x = b.
    pub(crate) fn factor<T: Scalar>(&self, s: T) -> Result<Factor<T>> {
        let vals: Vec<T> = self
            .k0
            .iter()
            .zip(&self.diag)
            .map(|(&v, &d)| {
                let off = s * T::of_real(v);
                if d {
                    T::of_real(1.0) - off
                } else {
                    -off
                }
            })
            .collect();
        Factor::new(&self.pattern, self.symbolic.as_ref(), &vals, true)
    }

    /// The M-matrix test of I - s K0 (s >= 0): the solution x of (I - s K0) x = 1 exists and is
    /// positive iff ρ(s K0) < 1. Returns that x.
    pub(crate) fn m_matrix(&self, s: f64) -> Result<Option<Vec<f64>>> {
        let lu = self.factor(s)?;
        let mut x = vec![1.0; self.pattern.n];
        Ok((lu.solve(&mut x) && x.iter().all(|&v| v > 0.0)).then_some(x))
    }
}

/// What the engine needs of a product, independent of the system.
pub(crate) struct Stationary {
    /// Stationary law of K.
    pub pi: Vec<f64>,
    /// ||pi K - pi||_1.
    pub residual: f64,
    /// nu = pi K1.
    pub nu: Vec<f64>,
    /// w = (I - K0)^-1 1.
    pub w: Vec<f64>,
    pub shifted: ShiftedK0,
}

/// The stationary law of K on one closed class (`members`): the balance equations with the
/// first replaced by pi_0 = 1, solved by LU, then normalised. Returned per member, with the
/// column ordering the LU used.
fn class_law(p: &Product, members: &[usize], arg: &str) -> Result<(Vec<f64>, Option<Ordering>)> {
    let n = p.n();
    let m = members.len();
    let mut local = vec![u32::MAX; n];
    for (i, &e) in members.iter().enumerate() {
        local[e] = i as u32;
    }
    // B = (I - K)^T on the class, CSC: column i holds row members[i] of I - K; row 0 of B
    // replaced by e_0^T.
    let mut col_ptr = Vec::with_capacity(m + 1);
    let mut row_idx: Vec<usize> = Vec::new();
    let mut vals: Vec<f64> = Vec::new();
    col_ptr.push(0);
    let mut row: Vec<(usize, f64)> = Vec::new();
    for (i, &e) in members.iter().enumerate() {
        row.clear();
        row.extend(
            p.k0.row(e)
                .chain(p.k1.row(e))
                .map(|(f, v)| (local[f] as usize, -v)),
        );
        row.push((i, 1.0));
        row.sort_unstable_by_key(|x| x.0);
        let mut last = usize::MAX;
        for &(j, v) in &row {
            if j == 0 && i != 0 {
                continue;
            }
            if j == last {
                *vals.last_mut().expect("pushed") += v;
            } else {
                row_idx.push(j);
                vals.push(v);
                last = j;
            }
        }
        if i == 0 {
            // Row 0 of B is e_0^T: column 0 keeps only 1 at row 0.
            if let Some(pos) = row_idx.iter().position(|&r| r == 0) {
                vals[pos] = 1.0;
            }
        }
        col_ptr.push(row_idx.len());
    }
    let pattern = Pattern {
        n: m,
        col_ptr,
        row_idx,
    };
    let sym = pattern.analyse()?;
    let lu = Factor::new(&pattern, sym.as_ref(), &vals, false)?;
    let mut x = vec![0.0; m];
    x[0] = 1.0;
    if !lu.solve(&mut x) {
        return Err(Error::invalid(arg, "the balance equations are singular"));
    }
    let total: f64 = x.iter().sum();
    Ok((x.into_iter().map(|v| (v / total).max(0.0)).collect(), sym))
}

/// The probability that the chain started from `init` ends in each of `classes`: the mass
/// already there plus y K(T -> class), y = init_T (I - K_TT)^-1 over the transient states T.
fn absorption(p: &Product, classes: &[Vec<usize>], arg: &str) -> Result<Vec<f64>> {
    let n = p.n();
    let mut class_of = vec![usize::MAX; n];
    for (c, members) in classes.iter().enumerate() {
        for &e in members {
            class_of[e] = c;
        }
    }
    let transient: Vec<usize> = (0..n).filter(|&e| class_of[e] == usize::MAX).collect();
    let mut mass = vec![0.0; classes.len()];
    for e in 0..n {
        if class_of[e] != usize::MAX {
            mass[class_of[e]] += p.init[e];
        }
    }
    if transient.is_empty() {
        return Ok(mass);
    }
    let mut local = vec![usize::MAX; n];
    for (i, &e) in transient.iter().enumerate() {
        local[e] = i;
    }
    // (I - K_TT)^T y' = init_T': column i of the CSC is row transient[i] of I - K_TT, so the
    // CSC matrix is (I - K_TT)^T itself.
    let m = transient.len();
    let mut col_ptr = vec![0];
    let mut row_idx = Vec::new();
    let mut vals = Vec::new();
    let mut row: Vec<(usize, f64)> = Vec::new();
    for (i, &e) in transient.iter().enumerate() {
        row.clear();
        row.extend(
            p.k0.row(e)
                .chain(p.k1.row(e))
                .filter(|&(f, _)| local[f] != usize::MAX)
                .map(|(f, v)| (local[f], -v)),
        );
        row.push((i, 1.0));
        row.sort_unstable_by_key(|x| x.0);
        let mut last = usize::MAX;
        for &(j, v) in &row {
            if j == last {
                *vals.last_mut().expect("pushed") += v;
            } else {
                row_idx.push(j);
                vals.push(v);
                last = j;
            }
        }
        col_ptr.push(row_idx.len());
    }
    let pattern = Pattern {
        n: m,
        col_ptr,
        row_idx,
    };
    let sym = pattern.analyse()?;
    let lu = Factor::new(&pattern, sym.as_ref(), &vals, false)?;
    let mut y: Vec<f64> = transient.iter().map(|&e| p.init[e]).collect();
    if !lu.solve(&mut y) {
        return Err(Error::invalid(arg, "the transient states are never left"));
    }
    for (i, &e) in transient.iter().enumerate() {
        for (f, v) in p.k0.row(e).chain(p.k1.row(e)) {
            if class_of[f] != usize::MAX {
                mass[class_of[f]] += y[i] * v;
            }
        }
    }
    Ok(mass)
}

impl Stationary {
    /// Solves the long-run law from the paper's initial condition, nu and w. With one closed
    /// class it is the stationary law of K; with several (a periodic channel beside an offline
    /// pattern, an automaton with absorbing parts) it is the Cesàro limit from the initial law:
    /// each class's stationary law weighted by the chance of ending in it. Every state must
    /// reach an arrival ([`crate::engine::graph::check_arrivals`], run when the product is built).
    pub(crate) fn new(p: &Product, arg: &str) -> Result<Self> {
        let n = p.n();
        let classes = if strongly_connected(p) {
            vec![(0..n).collect()]
        } else {
            closed_classes(p)
        };
        let weights = if classes.len() == 1 {
            vec![1.0]
        } else {
            absorption(p, &classes, arg)?
        };
        let mut pi = vec![0.0; n];
        // The law's column order serves I - s K0 too when its class is every state (the usual
        // case: the states are numbered as explored, so then members[i] = i).
        let mut ordering = None;
        for (members, &wt) in classes.iter().zip(&weights) {
            if wt <= 0.0 {
                continue;
            }
            let (law, order) = class_law(p, members, arg)?;
            if members.len() == n {
                ordering = Some(order);
            }
            for (&e, x) in members.iter().zip(law) {
                pi[e] = wt * x;
            }
        }
        let mut nu = vec![0.0; n];
        p.k1.left_mul(&pi, &mut nu);
        let mut back = vec![0.0; n];
        p.k0.left_mul(&pi, &mut back);
        let residual: f64 = back
            .iter()
            .zip(&nu)
            .zip(&pi)
            .map(|((a, b), c)| (a + b - c).abs())
            .sum();
        let shifted = ShiftedK0::new(&p.k0, ordering)?;
        let lu = shifted.factor(1.0)?;
        let mut w = vec![1.0; n];
        if !lu.solve(&mut w) {
            return Err(Error::invalid(arg, "I - K0 is singular: rho(K0) = 1"));
        }
        Ok(Stationary {
            pi,
            residual,
            nu,
            w,
            shifted,
        })
    }

    /// ρ(K0): 0 when K0's graph has no cycle, else by bisection on r with the M-matrix test
    /// (ρ(K0) < r iff (I - K0/r) x = 1 has a positive solution), to ~1e-13 relative. Each test
    /// with a positive x also bounds ρ(K0) <= r (1 - 1/max x) (Collatz-Wielandt), which tightens
    /// the bracket.
    pub(crate) fn rho_k0(&self, k0: &SparseRows, stop: Stop<'_>) -> Result<f64> {
        if is_acyclic(k0) {
            return Ok(0.0);
        }
        let test = |r: f64| -> Result<Option<f64>> {
            stop.check()?;
            Ok(self
                .shifted
                .m_matrix(1.0 / r)?
                .map(|x| r * (1.0 - 1.0 / x.iter().cloned().fold(1.0, f64::max))))
        };
        // rho < 1 (arrivals are reachable); find lo <= rho by halving.
        let mut hi = 1.0f64;
        let mut lo = 0.5f64;
        let mut halvings = 0;
        while let Some(ub) = test(lo)? {
            hi = hi.min(ub.max(0.0)).min(lo);
            lo *= 0.5;
            halvings += 1;
            if halvings > 1100 {
                return Ok(0.0);
            }
        }
        for _ in 0..200 {
            if hi <= lo * (1.0 + 1e-13) {
                break;
            }
            let mid = (lo * hi).sqrt();
            match test(mid)? {
                Some(ub) => hi = mid.min(ub.max(lo)),
                None => lo = mid,
            }
        }
        Ok(0.5 * (lo + hi))
    }
}

/// J = Tr sum_e nu_e Z_e with Z_e = b_e + sum_f K0[e, f] A Z_f A', b_e = P̄ + (w_e - 1) Q;
/// +inf when ρ(K0) ρ(A)² >= 1 (the M-matrix test at s = ρ(A)²).
pub(crate) fn cost(
    st: &Stationary,
    k0: &SparseRows,
    sys: &LinearSystem,
    stop: Stop<'_>,
) -> Result<f64> {
    let n = st.w.len();
    if sys.n() == 1 {
        let (a, pbar, q) = (sys.a()[(0, 0)], sys.pbar()[(0, 0)], sys.q()[(0, 0)]);
        let s = a * a;
        let mut z: Vec<f64> = st.w.iter().map(|&w| pbar + (w - 1.0) * q).collect();
        let positive_b = z.iter().all(|&b| b > 0.0);
        if !positive_b && st.shifted.m_matrix(s)?.is_none() {
            return Ok(f64::INFINITY);
        }
        let lu = st.shifted.factor(s)?;
        // With b > 0, a positive solution proves ρ(s K0) < 1 (Collatz-Wielandt).
        if !lu.solve(&mut z) || (positive_b && z.iter().any(|&v| v <= 0.0)) {
            return Ok(f64::INFINITY);
        }
        let j: f64 = st.nu.iter().zip(&z).map(|(a, b)| a * b).sum();
        return Ok(if j.is_finite() { j } else { f64::INFINITY });
    }
    let rho = sys.spectral_radius();
    if st.shifted.m_matrix(rho * rho)?.is_none() {
        return Ok(f64::INFINITY);
    }
    let nx = sys.n();
    let ac: DMatrix<c64> = sys.a().map(|x| c64::new(x, 0.0));
    let schur = nalgebra::Schur::try_new(ac, 1e-15, 100_000).ok_or(Error::NotConverged {
        what: "complex Schur form of A",
        iterations: 100_000,
        residual: f64::NAN,
    })?;
    let (u, t) = schur.unpack();
    let uh = u.adjoint();
    let pt = &uh * sys.pbar().map(|x| c64::new(x, 0.0)) * &u;
    let qt = &uh * sys.q().map(|x| c64::new(x, 0.0)) * &u;
    // y[e * nx * nx + k * nx + l] = Ztilde_e(k, l), kept Hermitian.
    let nn = nx * nx;
    let mut y = vec![c64::new(0.0, 0.0); n * nn];
    let mut wrow = vec![c64::new(0.0, 0.0); n * nx];
    let mut g = vec![c64::new(0.0, 0.0); n];
    let mut rhs = vec![c64::new(0.0, 0.0); n];
    for i in (0..nx).rev() {
        // W_f(l) = sum_{k > i} T[i, k] Ztilde_f(k, l), l > i: rows and columns past i are done.
        for f in 0..n {
            let yf = &y[f * nn..(f + 1) * nn];
            for l in i + 1..nx {
                let mut acc = c64::new(0.0, 0.0);
                for k in i + 1..nx {
                    acc += t[(i, k)] * yf[k * nx + l];
                }
                wrow[f * nx + l] = acc;
            }
        }
        for j in (i..nx).rev() {
            if j == i {
                // W_f(i) needs Ztilde_f(k, i) = conj(Ztilde_f(i, k)), k > i: done by now.
                for f in 0..n {
                    let yf = &y[f * nn..(f + 1) * nn];
                    let mut acc = c64::new(0.0, 0.0);
                    for k in i + 1..nx {
                        acc += t[(i, k)] * yf[k * nx + i];
                    }
                    wrow[f * nx + i] = acc;
                }
            }
            // g_f = sum_{(k,l) != (i,j), k >= i, l >= j} T[i,k] Ztilde_f(k,l) conj(T[j,l])
            for (f, gf) in g.iter_mut().enumerate() {
                let yf = &y[f * nn..(f + 1) * nn];
                let mut acc = c64::new(0.0, 0.0);
                for l in j..nx {
                    let tjl = t[(j, l)].conj();
                    acc += tjl * wrow[f * nx + l];
                    if l > j {
                        acc += t[(i, i)] * yf[i * nx + l] * tjl;
                    }
                }
                *gf = acc;
            }
            for (e, r) in rhs.iter_mut().enumerate() {
                let mut acc = pt[(i, j)] + qt[(i, j)] * (st.w[e] - 1.0);
                for (f, v) in k0.row(e) {
                    acc += g[f] * v;
                }
                *r = acc;
            }
            stop.check()?;
            let s = t[(i, i)] * t[(j, j)].conj();
            let lu = st.shifted.factor(s)?;
            if !lu.solve(&mut rhs) {
                return Ok(f64::INFINITY);
            }
            for (e, &v) in rhs.iter().enumerate() {
                y[e * nn + i * nx + j] = v;
                y[e * nn + j * nx + i] = v.conj();
            }
        }
    }
    let j: f64 = (0..n)
        .map(|e| st.nu[e] * (0..nx).map(|k| y[e * nn + k * nx + k].re).sum::<f64>())
        .sum();
    Ok(if j.is_finite() && j > 0.0 {
        j
    } else {
        f64::INFINITY
    })
}
