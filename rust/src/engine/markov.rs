//! The engine's fast path for periodic and mask blocking under a Markov channel: renewal over the
//! flag-ACK counter with the channel state as a phase (a Markov renewal process).
//!
//! A *fresh start* is an arrival: the holding time τ is 0, the detector's memory restarts and
//! the next step uses low power (no flag-ACK is sent on an arrival). Its phase c is the channel
//! state of the next step. From a fresh start every step is a low-power step until a packet
//! arrives, so the excursion's losses move the phase by M = diag(1 - low) P and an arrival by
//! diag(low) P. Flag-ACKs come after z0 losses (with probability μ, else z0 + 1) since the last
//! reset, by coins independent of the channel: the j-th of an excursion is sent at the loss step
//! T_j = j z0 + Binomial(j, 1 - μ). A blocked flag-ACK leaves the sensor at low power; a
//! delivered one makes the next step high power, which always arrives (high = 1 in every state,
//! the fast path's condition; the engine covers the rest), so it ends the excursion too.
//!
//! Per excursion from phase c, with F(n) = max{j : T_j <= n} (the flags within n losses):
//!
//! * A_k = Σ_n P(F(n) = k) M^n diag(low) P: it ends by an arrival after exactly k flags;
//! * E_m = Σ_n P(T_{m+1} = n) M^n P: its (m+1)-th flag comes first and is delivered;
//! * Z_m = Σ_s Tr h^s(P̄) (M^s 1) P(T_{m+1} >= s) and L_m = Σ_s (M^s 1) P(T_{m+1} >= s): its
//!   expected cost and length when it may pass at most m flags (the next one ends it).
//!
//! A *run* of b blocked flag-ACKs then a delivered one, entered at a fresh start of phase x,
//! visits fresh starts with j flags of the run behind them x U_j times, U_0 = (I - A_0)^-1,
//! U_j = (Σ_{i<j} U_i A_{j-i}) U_0; it leaves (at the fresh start after the delivered flag) with
//! the phase x B_b, B_b = Σ_{i<=b} U_i E_{b-i}, costing x R_b = x Σ U_i Z_{b-i} over x Λ_b =
//! x Σ U_i L_{b-i} steps. A mask is a cycle of runs b_1..b_d (rotated to end on a delivered
//! flag), so its phase at the start of a cycle has the stationary law x of
//! Π = B_{b_1} ⋯ B_{b_d} and J = x R / x Λ with R = R_{b_1} + B_{b_1}(R_{b_2} + B_{b_2}(…)).
//! "Block the first r of every t" is the runs r, 0, …, 0: Π = B_r B_0^{t-1-r}, so a sweep over
//! every r/t needs the B_b and the powers and partial sums of B_0 once, then O(K³) per fraction.

use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::engine::channel::{closed_class, dense_gth, Channel};
use crate::error::{Error, Result};
use crate::renewal::sweep::{farey, Sweep};
use crate::schedule::OnlineDesign;
use crate::system::LinearSystem;

/// Largest period a sweep or a mask may have under a Markov channel (the set-up is
/// O(t_max² K³)).
pub const MAX_PERIOD: u64 = 20_000;

/// The per-run quantities of a design under a channel, for runs of up to `bmax` blocked flags.
#[derive(Debug, Clone)]
pub struct Runs {
    k: usize,
    /// B_b: phase at the end of a run of b blocked flag-ACKs then a delivered one.
    b: Vec<DMatrix<f64>>,
    /// R_b: expected cost of that run, per entry phase.
    r: Vec<DVector<f64>>,
    /// Λ_b: its expected length in steps.
    l: Vec<DVector<f64>>,
}

/// P(T_j = j z0 + i), i = 0..=j, for j = 0..=jmax (T_j: the loss step of an excursion's j-th
/// flag-ACK).
fn flag_times(mu: f64, jmax: usize) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(jmax + 1);
    let mut row = vec![1.0];
    out.push(row.clone());
    for _ in 0..jmax {
        // One more window: its flag comes after z0 losses (μ) or z0 + 1 (1 - μ).
        let mut next = vec![0.0; row.len() + 1];
        for (i, &p) in row.iter().enumerate() {
            next[i] += p * mu;
            next[i + 1] += p * (1.0 - mu);
        }
        out.push(next.clone());
        row = next;
    }
    out
}

/// Whether every high-power packet arrives, the condition of this fast path.
pub fn applies(channel: &Channel) -> bool {
    channel.high().iter().all(|&h| h == 1.0)
}

impl Runs {
    /// The runs of `design` under `channel` for b = 0..=bmax on `sys`. Refused (naming
    /// `channel`) unless every high-power packet arrives.
    pub fn new(
        sys: &LinearSystem,
        channel: &Channel,
        design: OnlineDesign,
        bmax: usize,
        cancel: Option<&AtomicBool>,
    ) -> Result<Self> {
        design.validate()?;
        if !applies(channel) {
            return Err(Error::invalid(
                "channel",
                "the renewal form needs high-power packets that always arrive; use the engine",
            ));
        }
        if bmax as u64 >= MAX_PERIOD {
            return Err(Error::TooLarge {
                arg: "t_max".into(),
                requested: bmax as u128 + 1,
                limit: MAX_PERIOD as u128,
            });
        }
        let k = channel.n_states();
        let z0 = design.z0 as usize;
        let mu = design.mu;
        let p = DMatrix::from_fn(k, k, |i, j| channel.p(i, j));
        let m_loss = DMatrix::from_fn(k, k, |i, j| (1.0 - channel.low()[i]) * channel.p(i, j));
        let arrive = DMatrix::from_fn(k, k, |i, j| channel.low()[i] * channel.p(i, j));
        // T_{bmax+1} <= (bmax + 1)(z0 + 1): no excursion of these runs has more losses.
        let nmax = (bmax + 1) * (z0 + 1);
        let times = flag_times(mu, bmax + 1);
        let cum: Vec<Vec<f64>> = times
            .iter()
            .map(|w| {
                w.iter()
                    .scan(0.0, |acc, &x| {
                        *acc += x;
                        Some(*acc)
                    })
                    .collect()
            })
            .collect();
        // P(T_j <= n): 0 below T_j's window [j z0, j (z0 + 1)], 1 above it.
        let cdf = |j: usize, n: usize| -> f64 {
            let lo = j * z0;
            if n < lo {
                0.0
            } else if n - lo >= cum[j].len() - 1 {
                1.0
            } else {
                cum[j][n - lo]
            }
        };
        // Cost weights kept finite where they can be: θ^s Tr h^s(P̄) against (M/θ)^s 1, θ the
        // largest loss probability (so (M/θ)^s 1 <= 1).
        let theta = (0..k)
            .map(|i| 1.0 - channel.low()[i])
            .fold(0.0f64, f64::max);
        let theta = if theta > 0.0 { theta } else { 1.0 };
        let wtr = sys.checked_weighted_traces(theta, nmax as u128, "t_max")?;
        let mut a = vec![DMatrix::<f64>::zeros(k, k); bmax + 1];
        let mut e = vec![DMatrix::<f64>::zeros(k, k); bmax + 1];
        // g[s] = Tr h^s(P̄) M^s 1 and h[s] = M^s 1, per phase.
        let mut g: Vec<DVector<f64>> = Vec::with_capacity(nmax + 1);
        let mut h: Vec<DVector<f64>> = Vec::with_capacity(nmax + 1);
        let mut mpow = DMatrix::<f64>::identity(k, k);
        let mut v = DVector::<f64>::from_element(k, 1.0);
        let mut vhat = v.clone();
        let mhat = &m_loss / theta;
        for n in 0..=nmax {
            // Within n losses the flags number between n/(z0+1) - 1 and n/z0.
            let kmin = (n / (z0 + 1)).saturating_sub(1);
            let kmax = (n / z0).min(bmax);
            for kk in kmin..=kmax {
                let w = cdf(kk, n) - cdf(kk + 1, n);
                if w > 0.0 {
                    a[kk] += &mpow * w;
                }
                // E_kk: the (kk+1)-th flag-ACK at loss step n.
                let j = kk + 1;
                if n >= j * z0 && n - j * z0 < times[j].len() {
                    let w = times[j][n - j * z0];
                    if w > 0.0 {
                        e[kk] += &mpow * w;
                    }
                }
            }
            g.push(DVector::from_fn(k, |c, _| {
                if vhat[c] > 0.0 {
                    wtr[n] * vhat[c]
                } else {
                    0.0
                }
            }));
            h.push(v.clone());
            mpow = &mpow * &m_loss;
            v = &m_loss * &v;
            vhat = &mhat * &vhat;
        }
        // Z_m = Σ_s g[s] P(T_{m+1} >= s): every step up to (m+1) z0 is alive, then T_{m+1}'s
        // window.
        let prefix = |x: &[DVector<f64>]| -> Vec<DVector<f64>> {
            let mut out = Vec::with_capacity(x.len());
            let mut acc = DVector::<f64>::zeros(k);
            for y in x {
                acc += y;
                out.push(acc.clone());
            }
            out
        };
        let (gsum, hsum) = (prefix(&g), prefix(&h));
        let mut z = Vec::with_capacity(bmax + 1);
        let mut l = Vec::with_capacity(bmax + 1);
        for m in 0..=bmax {
            let j = m + 1;
            let mut zm = gsum[j * z0].clone();
            let mut lm = hsum[j * z0].clone();
            for s in j * z0 + 1..=(j * (z0 + 1)).min(nmax) {
                let alive = 1.0 - cdf(j, s - 1);
                if alive > 0.0 {
                    zm += &g[s] * alive;
                    lm += &h[s] * alive;
                }
            }
            z.push(zm);
            l.push(lm);
        }
        for x in a.iter_mut() {
            *x = &*x * &arrive;
        }
        for x in e.iter_mut() {
            *x = &*x * &p;
        }
        let u0 = (DMatrix::<f64>::identity(k, k) - &a[0])
            .try_inverse()
            .ok_or_else(|| {
                Error::invalid("channel", "no flag-ACK is ever sent: I - A_0 is singular")
            })?;
        let mut u = Vec::with_capacity(bmax + 1);
        u.push(u0.clone());
        for j in 1..=bmax {
            check(cancel)?;
            let mut acc = DMatrix::<f64>::zeros(k, k);
            for i in 0..j {
                acc += &u[i] * &a[j - i];
            }
            u.push(acc * &u0);
        }
        let mut b = Vec::with_capacity(bmax + 1);
        let mut r = Vec::with_capacity(bmax + 1);
        let mut lam = Vec::with_capacity(bmax + 1);
        for bb in 0..=bmax {
            check(cancel)?;
            let mut bm = DMatrix::<f64>::zeros(k, k);
            let mut rv = DVector::<f64>::zeros(k);
            let mut lv = DVector::<f64>::zeros(k);
            for i in 0..=bb {
                bm += &u[i] * &e[bb - i];
                rv += safe_mul(&u[i], &z[bb - i]);
                lv += &u[i] * &l[bb - i];
            }
            b.push(bm);
            r.push(rv);
            lam.push(lv);
        }
        Ok(Runs { k, b, r, l: lam })
    }

    /// The cost of a cycle of runs (blocked flag-ACKs before each delivered one).
    pub fn cycle_j(&self, runs: &[usize]) -> Result<f64> {
        let k = self.k;
        let mut pi = DMatrix::<f64>::identity(k, k);
        for &b in runs {
            pi = &pi * self.run(b)?.0;
        }
        let (mut r, mut l) = (DVector::<f64>::zeros(k), DVector::<f64>::zeros(k));
        for &b in runs.iter().rev() {
            let (bm, rb, lb) = self.run(b)?;
            r = rb + safe_mul(bm, &r);
            l = lb + bm * &l;
        }
        Ok(ratio(&stationary(&pi)?, &r, &l))
    }

    fn run(&self, b: usize) -> Result<(&DMatrix<f64>, &DVector<f64>, &DVector<f64>)> {
        if b >= self.b.len() {
            return Err(Error::invalid(
                "mask",
                format!("a run of {b} blocked flag-ACKs is longer than prepared"),
            ));
        }
        Ok((&self.b[b], &self.r[b], &self.l[b]))
    }

    /// The cost of a blocking mask (true = blocked) over one period of flag-ACKs; at least one
    /// must be delivered.
    pub fn mask_j(&self, mask: &[bool]) -> Result<f64> {
        self.cycle_j(&runs_of(mask)?)
    }
}

/// [`Error::Interrupted`] once `cancel` is set.
fn check(cancel: Option<&AtomicBool>) -> Result<()> {
    match cancel {
        Some(c) if c.load(Ordering::Relaxed) => Err(Error::Interrupted),
        _ => Ok(()),
    }
}

/// The runs of a mask, rotated to end on a delivered flag-ACK.
pub fn runs_of(mask: &[bool]) -> Result<Vec<usize>> {
    let last = mask
        .iter()
        .rposition(|&x| !x)
        .ok_or_else(|| Error::invalid("mask", "blocks every flag-ACK: its cost is j_max"))?;
    let mut runs = Vec::new();
    let mut b = 0;
    for i in 1..=mask.len() {
        if mask[(last + i) % mask.len()] {
            b += 1;
        } else {
            runs.push(b);
            b = 0;
        }
    }
    Ok(runs)
}

/// `m v` where an infinite entry of v times a zero weight counts 0 (a cost beyond the double
/// range reached with probability 0), never NaN.
fn safe_mul(m: &DMatrix<f64>, v: &DVector<f64>) -> DVector<f64> {
    DVector::from_fn(m.nrows(), |i, _| {
        (0..m.ncols())
            .filter(|&j| m[(i, j)] != 0.0)
            .map(|j| m[(i, j)] * v[j])
            .sum()
    })
}

/// x R / x Λ with zero weights skipping infinite costs; inf (never NaN) past the double range.
fn ratio(x: &[f64], r: &DVector<f64>, l: &DVector<f64>) -> f64 {
    let num: f64 = x
        .iter()
        .zip(r.iter())
        .filter(|(w, _)| **w > 0.0)
        .map(|(w, v)| w * v)
        .sum();
    let den: f64 = x.iter().zip(l.iter()).map(|(w, v)| w * v).sum();
    let j = num / den;
    if j.is_nan() {
        f64::INFINITY
    } else {
        j
    }
}

/// The stationary law of a small stochastic matrix on its one closed class (GTH).
fn stationary(pi: &DMatrix<f64>) -> Result<Vec<f64>> {
    let k = pi.nrows();
    let flat: Vec<f64> = (0..k * k).map(|x| pi[(x / k, x % k)]).collect();
    let closed = closed_class(&flat, k).map_err(|_| {
        Error::invalid(
            "channel",
            "the phase chain of one period has several closed classes",
        )
    })?;
    Ok(dense_gth(&flat, k, &closed))
}

/// J(r, t) of "block the first r of every t" for every reduced r/t with t <= t_max, stopping
/// with [`Error::Interrupted`] once `cancel` is set.
pub fn beta_sweep(
    sys: &LinearSystem,
    channel: &Channel,
    design: OnlineDesign,
    t_max: u64,
    cancel: Option<&AtomicBool>,
) -> Result<Sweep> {
    if t_max < 2 {
        return Err(Error::invalid(
            "t_max",
            format!("must be at least 2, got {t_max}"),
        ));
    }
    if t_max > MAX_PERIOD {
        return Err(Error::TooLarge {
            arg: "t_max".into(),
            requested: t_max as u128,
            limit: MAX_PERIOD as u128,
        });
    }
    let runs = Runs::new(sys, channel, design, t_max as usize - 1, cancel)?;
    let tails = Tails::new(&runs, t_max as usize - 1);
    let fr = farey(t_max);
    let j: Result<Vec<f64>> = fr
        .par_iter()
        .with_min_len(1 << 12)
        .map(|&(r, t)| {
            if r == 1 {
                check(cancel)?;
            }
            tails.first_r(&runs, r as usize, t as usize)
        })
        .collect();
    let beta = fr.iter().map(|&(r, t)| r as f64 / t as f64).collect();
    let (r, t) = fr.into_iter().unzip();
    Ok(Sweep { r, t, beta, j: j? })
}

/// Powers and partial sums of the delivered run B_0, for "first r of t" at O(K³).
struct Tails {
    /// B_0^n.
    pow: Vec<DMatrix<f64>>,
    /// Σ_{j<n} B_0^j R_0 and Σ_{j<n} B_0^j Λ_0.
    r: Vec<DVector<f64>>,
    l: Vec<DVector<f64>>,
}

impl Tails {
    fn new(runs: &Runs, nmax: usize) -> Self {
        let k = runs.k;
        let (b0, r0, l0) = (&runs.b[0], &runs.r[0], &runs.l[0]);
        let mut pow = vec![DMatrix::<f64>::identity(k, k)];
        let mut r = vec![DVector::<f64>::zeros(k)];
        let mut l = vec![DVector::<f64>::zeros(k)];
        for n in 0..nmax {
            r.push(&r[n] + safe_mul(&pow[n], r0));
            l.push(&l[n] + &pow[n] * l0);
            pow.push(&pow[n] * b0);
        }
        Tails { pow, r, l }
    }

    fn first_r(&self, runs: &Runs, r: usize, t: usize) -> Result<f64> {
        let n = t - 1 - r;
        let (br, rr, lr) = runs.run(r)?;
        let pi = br * &self.pow[n];
        let rv = rr + safe_mul(br, &self.r[n]);
        let lv = lr + br * &self.l[n];
        Ok(ratio(&stationary(&pi)?, &rv, &lv))
    }
}

/// J of "block the first r of every t" (0 <= r < t).
pub fn periodic_j(
    sys: &LinearSystem,
    channel: &Channel,
    design: OnlineDesign,
    r: u64,
    t: u64,
) -> Result<f64> {
    if r >= t {
        return Err(Error::invalid(
            "r",
            format!("must be below t = {t}, got {r}"),
        ));
    }
    let mut mask = vec![false; t as usize];
    mask[..r as usize].iter_mut().for_each(|x| *x = true);
    mask_j(sys, channel, design, &mask)
}

/// J of a blocking mask under a Markov channel.
pub fn mask_j(
    sys: &LinearSystem,
    channel: &Channel,
    design: OnlineDesign,
    mask: &[bool],
) -> Result<f64> {
    if mask.len() as u64 > MAX_PERIOD {
        return Err(Error::TooLarge {
            arg: "mask".into(),
            requested: mask.len() as u128,
            limit: MAX_PERIOD as u128,
        });
    }
    let runs = runs_of(mask)?;
    let bmax = runs.iter().copied().max().unwrap_or(0);
    Runs::new(sys, channel, design, bmax, None)?.cycle_j(&runs)
}

/// The most damaging mask with `blocked` of `t` flag-ACKs blocked (t <= 24), exhaustively: every
/// mask is a rotation of one whose last flag-ACK is delivered, and rotations share J, so the
/// C(t-1, blocked) masks ending on a delivered flag-ACK are searched. Returns (mask, J,
/// J of the consecutive mask); a mask beats the consecutive one only by more than 1e-12
/// relative, and among masks within that of each other the first in increasing bit order wins.
pub fn worst_mask(
    sys: &LinearSystem,
    channel: &Channel,
    design: OnlineDesign,
    t: usize,
    blocked: usize,
    cancel: Option<&AtomicBool>,
) -> Result<(Vec<bool>, f64, f64)> {
    if !(1..=24).contains(&t) {
        return Err(Error::invalid(
            "t",
            format!("must lie in 1..=24 for an exhaustive search, got {t}"),
        ));
    }
    if blocked >= t {
        return Err(Error::invalid(
            "blocked",
            format!("must be smaller than t = {t}, got {blocked}"),
        ));
    }
    let runs = Runs::new(sys, channel, design, blocked, cancel)?;
    let to_mask = |bits: u32| (0..t).map(|i| bits >> i & 1 == 1).collect::<Vec<bool>>();
    let consecutive = (1u32 << blocked) - 1;
    let j_consecutive = runs.mask_j(&to_mask(consecutive))?;
    let mut words = Vec::new();
    if blocked > 0 {
        // Gosper's hack: every (t-1)-bit word with `blocked` ones, in increasing order.
        let mut bits = consecutive;
        while bits < (1u32 << (t - 1)) {
            words.push(bits);
            let c = bits & bits.wrapping_neg();
            let r = bits + c;
            bits = (((r ^ bits) >> 2) / c) | r;
        }
    }
    let js: Result<Vec<f64>> = words
        .par_iter()
        .with_min_len(1 << 10)
        .map(|&b| {
            if b & 0x3ff == 0 {
                check(cancel)?;
            }
            runs.mask_j(&to_mask(b))
        })
        .collect();
    let (mut best_bits, mut best_j) = (consecutive, j_consecutive);
    for (&bits, j) in words.iter().zip(js?) {
        if j > best_j * (1.0 + 1e-12) {
            (best_bits, best_j) = (bits, j);
        }
    }
    Ok((to_mask(best_bits), best_j, j_consecutive))
}

#[cfg(test)]
mod tests;
