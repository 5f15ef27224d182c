//! State mode ([`Mode::State`](super::Mode::State)): the error recursions with real Gaussian
//! noise, run on the same lock-step protocol ([`Proto`]) as the covariance kernels.

use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::DMatrix;

use super::kernel::{
    group_rows, lane_sum, Isa, KernelTables, Params, Proto, Tile, TileOut, SUB_STEPS,
};
use super::{CHUNK_STEPS, LANES};
use crate::error::{Error, Result};
use crate::montecarlo::rng::{NormalSampler, Xoshiro256pp};
use crate::system::LinearSystem;

/// Row-major dense matrices of the error recursions, with noise factors Lq (n × rq, Q = Lq Lq'),
/// Lr (m × m) and Lp (n × rp, P̄ = Lp Lp').
pub(super) struct StateModel {
    /// States.
    n: usize,
    /// Outputs.
    m: usize,
    /// Columns of Lq (the rank of Q).
    rq: usize,
    /// Columns of Lp (the rank of P̄).
    rp: usize,
    /// A.
    a: Vec<f64>,
    /// (I - KC) A.
    f: Vec<f64>,
    /// (I - KC) Lq.
    g: Vec<f64>,
    /// K Lr.
    h: Vec<f64>,
    /// Lq.
    lq: Vec<f64>,
    /// Lp.
    lp: Vec<f64>,
}

/// A factor L (n × rank) with L L' = X for a symmetric PSD X, from its eigen-decomposition
/// (negative round-off eigenvalues are dropped), so singular X is fine.
fn psd_factor(arg: &str, x: &DMatrix<f64>) -> Result<(Vec<f64>, usize)> {
    let n = x.nrows();
    let sym = (x + x.transpose()) * 0.5;
    let eig = nalgebra::linalg::SymmetricEigen::try_new(sym, f64::EPSILON, 10_000).ok_or(
        Error::NotConverged {
            what: "symmetric eigen-decomposition of a noise covariance",
            iterations: 10_000,
            residual: f64::NAN,
        },
    )?;
    let top = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    if !top.is_finite() {
        return Err(Error::invalid(arg, "has a non-finite eigenvalue"));
    }
    let keep: Vec<usize> = (0..n)
        .filter(|&j| eig.eigenvalues[j] > top * 1e-14 && eig.eigenvalues[j] > 0.0)
        .collect();
    let rank = keep.len();
    let mut l = vec![0.0; n * rank];
    for (c, &j) in keep.iter().enumerate() {
        let s = eig.eigenvalues[j].sqrt();
        for i in 0..n {
            l[i * rank + c] = eig.eigenvectors[(i, j)] * s;
        }
    }
    Ok((l, rank))
}

/// The entries of `x`, row by row.
fn row_major(x: &DMatrix<f64>) -> Vec<f64> {
    let mut out = Vec::with_capacity(x.nrows() * x.ncols());
    for i in 0..x.nrows() {
        for j in 0..x.ncols() {
            out.push(x[(i, j)]);
        }
    }
    out
}

/// A rows × cols matrix from its entries row by row.
fn from_row_major(rows: usize, cols: usize, v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(rows, cols, v)
}

impl StateModel {
    /// The recursions of `sys`'s steady-state Kalman filter.
    pub(super) fn new(sys: &LinearSystem) -> Result<Self> {
        let (a, c, q, r, pbar) = (sys.a(), sys.c(), sys.q(), sys.r(), sys.pbar());
        let n = sys.n();
        let m = c.nrows();
        let prior = a * pbar * a.transpose() + q;
        let s = c * &prior * c.transpose() + r;
        let chol = s
            .cholesky()
            .ok_or_else(|| Error::invalid("R", "C P⁻ C' + R is not positive definite"))?;
        // K = P⁻ C' S^{-1} = (S^{-1} C P⁻)'.
        let k = chol.solve(&(c * &prior)).transpose();
        let mkc = DMatrix::<f64>::identity(n, n) - &k * c;
        let (lq, rq) = psd_factor("Q", q)?;
        let (lr, rr) = psd_factor("R", r)?;
        if rr != m {
            return Err(Error::invalid("R", "must be positive definite"));
        }
        let (lp, rp) = psd_factor("P̄", pbar)?;
        let lq_m = from_row_major(n, rq, &lq);
        let lr_m = from_row_major(m, m, &lr);
        let model = StateModel {
            n,
            m,
            rq,
            rp,
            a: row_major(a),
            f: row_major(&(&mkc * a)),
            g: row_major(&(&mkc * &lq_m)),
            h: row_major(&(&k * &lr_m)),
            lq,
            lp,
        };
        if [&model.f, &model.g, &model.h]
            .iter()
            .any(|v| v.iter().any(|x| !x.is_finite()))
        {
            return Err(Error::invalid("sys", "the Kalman gain is not finite"));
        }
        Ok(model)
    }

    /// The number of states n.
    pub(super) fn states(&self) -> usize {
        self.n
    }
}

/// The dot product of `a` and `b`.
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The state-mode coefficients of a scalar system (n = m = 1).
struct Scalar {
    /// A.
    a: f64,
    /// (1 - KC) A.
    f: f64,
    /// (1 - KC) Lq.
    g: f64,
    /// K Lr.
    h: f64,
    /// Lq.
    lq: f64,
}

/// The error recursions of a tile's lanes: the sensor's errors e^s and the remote errors e,
/// lane-major, with scratch space for one lane's step (also the automaton kernel's state mode).
pub(super) struct TileErrors<'m> {
    /// The recursions' matrices.
    model: &'m StateModel,
    /// The same recursions on plain numbers when n = m = 1.
    scalar: Option<Scalar>,
    /// The normal sampler.
    gauss: NormalSampler,
    /// The sensor's errors e^s, lane l at `l * n..(l + 1) * n`.
    es: Vec<f64>,
    /// The remote errors e, laid out as `es`.
    e: Vec<f64>,
    /// One lane's next e^s.
    es_new: Vec<f64>,
    /// One lane's next e.
    e_new: Vec<f64>,
    /// The process noise draw w = Lq zw.
    zw: Vec<f64>,
    /// The measurement noise draw v = Lr zv.
    zv: Vec<f64>,
}

impl<'m> TileErrors<'m> {
    /// The errors at k = 0 of one lane per stream of `noise`: e^s_0 ~ N(0, P̄) (drawn from the
    /// lane's stream), e_0 = 0.
    pub(super) fn start(model: &'m StateModel, noise: &mut [Xoshiro256pp]) -> Self {
        let (n, m, rq, rp) = (model.n, model.m, model.rq, model.rp);
        let lanes = noise.len();
        let gauss = NormalSampler::new();
        let mut es = vec![0.0; lanes * n];
        let mut zp = vec![0.0; rp];
        for l in 0..lanes {
            for z in zp.iter_mut() {
                *z = gauss.draw(&mut noise[l]);
            }
            for (i, out) in es[l * n..(l + 1) * n].iter_mut().enumerate() {
                *out = dot(&model.lp[i * rp..(i + 1) * rp], &zp);
            }
        }
        let scalar = (n == 1 && m == 1).then(|| Scalar {
            a: model.a[0],
            f: model.f[0],
            g: model.g.first().copied().unwrap_or(0.0),
            h: model.h[0],
            lq: model.lq.first().copied().unwrap_or(0.0),
        });
        TileErrors {
            model,
            scalar,
            gauss,
            e: vec![0.0; es.len()],
            es,
            es_new: vec![0.0; n],
            e_new: vec![0.0; n],
            zw: vec![0.0; rq],
            zv: vec![0.0; m],
        }
    }

    /// Sets every lane's remote error to its sensor's, e_0 = e^s_0: the remote estimate starts
    /// at the sensor's (τ_0 = 0), which matters where the first packet may be lost.
    pub(super) fn remote_from_sensor(&mut self) {
        self.e.copy_from_slice(&self.es);
    }

    /// Advances lane l's errors by one step (the packet arrived iff `arrive`), drawing its noise
    /// from `noise`, and returns ||e_k||².
    #[inline(always)]
    pub(super) fn step(&mut self, l: usize, arrive: bool, noise: &mut Xoshiro256pp) -> f64 {
        let Some(sc) = &self.scalar else {
            return self.step_vector(l, arrive, noise);
        };
        let zw = if self.model.rq == 1 {
            self.gauss.draw(noise)
        } else {
            0.0
        };
        let zv = self.gauss.draw(noise);
        let esn = sc.f * self.es[l] + sc.g * zw - sc.h * zv;
        self.es[l] = esn;
        self.e[l] = if arrive {
            esn
        } else {
            sc.a * self.e[l] + sc.lq * zw
        };
        self.e[l] * self.e[l]
    }

    /// [`TileErrors::step`] for a vector system.
    #[inline(always)]
    fn step_vector(&mut self, l: usize, arrive: bool, noise: &mut Xoshiro256pp) -> f64 {
        let model = self.model;
        let (n, m, rq) = (model.n, model.m, model.rq);
        for z in self.zw.iter_mut() {
            *z = self.gauss.draw(noise);
        }
        for z in self.zv.iter_mut() {
            *z = self.gauss.draw(noise);
        }
        let es_l = &mut self.es[l * n..(l + 1) * n];
        let e_l = &mut self.e[l * n..(l + 1) * n];
        // e^s_k = (I-KC) A e^s_{k-1} + (I-KC) w_{k-1} - K v_k.
        for (i, out) in self.es_new.iter_mut().enumerate() {
            *out = dot(&model.f[i * n..(i + 1) * n], es_l)
                + dot(&model.g[i * rq..(i + 1) * rq], &self.zw)
                - dot(&model.h[i * m..(i + 1) * m], &self.zv);
        }
        es_l.copy_from_slice(&self.es_new);
        if arrive {
            e_l.copy_from_slice(&self.es_new);
        } else {
            // e_k = A e_{k-1} + w_{k-1}.
            for (i, out) in self.e_new.iter_mut().enumerate() {
                *out = dot(&model.a[i * n..(i + 1) * n], e_l)
                    + dot(&model.lq[i * rq..(i + 1) * rq], &self.zw);
            }
            e_l.copy_from_slice(&self.e_new);
        }
        e_l.iter().map(|y| y * y).sum()
    }
}

/// Runs one state-mode tile: the protocol on the grouped kernels, a sub-chunk ahead, and each
/// lane's errors along the arrivals it read off their rows; lane l's per-step value is ||e_k||².
pub(super) fn state_tile<
    const ONLINE: bool,
    const MU_DRAW: bool,
    const ATTACK: bool,
    const PROTO_A: bool,
    const RANDOM_BLOCK: bool,
    const FORGE: bool,
>(
    isa: Isa,
    p: &Params,
    model: &StateModel,
    tile: &mut Tile,
    cancel: &AtomicBool,
) -> Result<TileOut> {
    let mut proto = Proto::new(&tile.seeds);
    let side = &mut tile.side;
    let noise = &mut tile.noise;
    let mut errors = TileErrors::start(model, noise);
    let mut sum = [0.0f64; LANES];
    // The protocol runs ahead on the grouped covariance kernels, SUB_STEPS steps at a time; the
    // marker table [1, 0, 0, ...] turns their rows into arrival indicators.
    let marker: Vec<f64> = (0..=p.max_tau)
        .map(|t| f64::from(u8::from(t == 0)))
        .collect();
    let tables = KernelTables::new(p, &marker)?;
    let everyone = [u64::MAX; LANES];
    let mut rows = [[0.0f64; LANES]; SUB_STEPS];
    let mut ignored = [0.0f64; LANES];
    let n = model.n;
    let chunk_steps = (CHUNK_STEPS / (n * n).max(1)).max(1);
    for chunk in tile
        .acc
        .chunks_mut(chunk_steps.div_ceil(SUB_STEPS) * SUB_STEPS)
    {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for sub in chunk.chunks_mut(SUB_STEPS) {
            let rows = &mut rows[..sub.len()];
            group_rows::<ONLINE, MU_DRAW, ATTACK, PROTO_A, RANDOM_BLOCK, FORGE>(
                isa,
                &tables,
                &mut proto,
                &mut ignored,
                side,
                &everyone,
                rows,
            );
            for (acc, row) in sub.iter_mut().zip(rows.iter()) {
                let mut v = [0.0f64; LANES];
                for l in 0..LANES {
                    let x = errors.step(l, row[l] != 0.0, &mut noise[l]);
                    // Only an overflowed error gives NaN (inf - inf); report it as +inf.
                    let x = if x.is_nan() { f64::INFINITY } else { x };
                    sum[l] += x;
                    v[l] = f64::from_bits(x.to_bits() & tile.active[l]);
                }
                *acc += lane_sum(&v);
            }
        }
    }
    Ok(proto.finish(sum))
}
