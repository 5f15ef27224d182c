//! Attacked cost for any periodic blocking mask and any memory mix μ, by renewal structure.
//!
//! After a *fresh start* (an arrival, τ = 0) the detector's memory fills with zeros; a flag-ACK is
//! due after z0 losses with probability μ, else after z0 + 1. The chance that a flag comes before
//! the next arrival is u = a^z0 (μ + (1-μ) a), the same after every memory reset. A blocked flag
//! resets the memory but not τ, so k blocked flags in a row put the walk in *segment k*, where
//! τ = k z0 + i + z: i of the k intervals were long (binomial, weight C(k,i) μ^(k-i) (1-μ)^i) and z
//! counts zeros since the last reset (z = z0 + 1 carries weight 1 - μ).
//!
//! Balancing the flag rate F across counter levels σ gives the stationary law
//! π(state in level σ, segment k) = (F/u) c̃(σ-k) a^τ (path weight), with c̃(j) = 1 - u when the
//! flag before level j is blocked and 1 otherwise; segment k exists in level σ iff the k flags
//! before it were all blocked. So J = N/D with N = Σ_σ Σ_k c̃(σ-k) W_k and D the same with
//! M_k, where W_k (M_k) sums a^τ Tr h^τ(P̄) (a^τ) over segment k. `stationary::structured` is
//! the μ = 1, first-r-of-t case written out state by state.

use crate::attack::{longest_cyclic_run, Attack};
use crate::error::{Error, Result};
use crate::schedule::{OnlineDesign, Walk};
use crate::system::LinearSystem;

/// Largest segment index for μ < 1, where building the segments costs O(kmax²).
pub const MAX_SEGMENTS_MIXED: u64 = 20_000;

/// Segment sums of one fresh-start walk.
///
/// With forged flag-ACKs (a [`Walk`] with γ > 0) every formula keeps its form: steps without a
/// genuine flag go on with probability c = (1-λ)(1-γ) instead of a, so the sums use c^τ, each
/// blocked flag on the way to segment k weighs ε = 1/(1-γ) more (segment k is scaled by ε^k),
/// and a level entered by a blocked flag restarts at the relative rate 1 - ε u.
#[derive(Debug, Clone)]
pub struct Segments {
    /// u = c^z0 (μ + (1-μ) c): probability of a genuine flag before the next fresh start.
    pub u: f64,
    /// 1 - u, computed without cancellation (tiny λ).
    pub one_minus_u: f64,
    /// 1 - ε u: the c̃ of a counter level entered by a blocked flag (= 1 - u without forging).
    pub restart_after_block: f64,
    /// W_k: segment k's sum of c^τ Tr h^τ(P̄) (times the path weights).
    pub w: Vec<f64>,
    /// M_k: segment k's sum of c^τ (times the path weights): expected steps spent there.
    pub m: Vec<f64>,
}

/// Highest τ that segments 0..=kmax reach: kmax (z0 + 1) + z0 + 1.
pub fn tau_needed(z0: u64, kmax: u64) -> u128 {
    (kmax as u128 + 1) * (z0 as u128 + 1)
}

/// The masses c^τ, τ = 0..n, of a walk's steps without a genuine flag (they depend on λ and γ
/// only, not on the memory).
pub fn masses(walk: &Walk, n: usize) -> Vec<f64> {
    (0..n).map(|tau| walk.c_pow(tau as u64)).collect()
}

fn prefix(v: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(v.len() + 1);
    let mut acc = 0.0;
    out.push(0.0);
    for x in v {
        acc += x;
        out.push(acc);
    }
    out
}

impl Segments {
    /// Segments 0..=kmax from the weighted traces `wtr[τ] = a^τ Tr h^τ(P̄)`,
    /// τ = 0..=[`tau_needed`].
    pub fn new(wtr: &[f64], lam: f64, design: OnlineDesign, kmax: u64) -> Result<Self> {
        Self::of_walk(wtr, &Walk::new(lam, design, 0.0)?, kmax)
    }

    /// Segments 0..=kmax of a walk with forged flags, from `wtr[τ] = c^τ Tr h^τ(P̄)`.
    pub fn of_walk(wtr: &[f64], walk: &Walk, kmax: u64) -> Result<Self> {
        let need = tau_needed(walk.design.z0, kmax) as usize + 1;
        if wtr.len() < need {
            return Err(Error::invalid("w", format!("needs {need} weighted traces")));
        }
        Self::of_walk_with_masses(wtr, &masses(walk, need), walk, kmax)
    }

    /// [`Segments::of_walk`] with the masses `c^τ` already computed by [`masses`] (at least
    /// [`tau_needed`] + 1 of them, for any walk with the same λ and γ): callers that build
    /// segments for many designs at one λ compute them once.
    pub fn of_walk_with_masses(wtr: &[f64], mass: &[f64], walk: &Walk, kmax: u64) -> Result<Self> {
        let OnlineDesign { z0, mu } = walk.design;
        let need = tau_needed(z0, kmax) as usize + 1;
        if wtr.len() < need || mass.len() < need {
            return Err(Error::invalid("w", format!("needs {need} weighted traces")));
        }
        let (mut w, mut m) = segment_sums(&wtr[..need], &mass[..need], z0, mu, kmax);
        scale_by_block_factor(&mut w, walk);
        scale_by_block_factor(&mut m, walk);
        Ok(Segments {
            u: walk.flag_probability(),
            one_minus_u: walk.no_flag_probability(),
            restart_after_block: walk.restart_after_block(),
            w,
            m,
        })
    }

    /// Segments 0..=kmax for a system, computing the weighted traces it needs (refused before
    /// allocating if too many).
    pub fn for_system(
        sys: &LinearSystem,
        lam: f64,
        design: OnlineDesign,
        kmax: u64,
    ) -> Result<Self> {
        Self::for_walk(sys, &Walk::new(lam, design, 0.0)?, kmax)
    }

    /// [`Segments::for_system`] for a walk with forged flags.
    pub fn for_walk(sys: &LinearSystem, walk: &Walk, kmax: u64) -> Result<Self> {
        Self::check_depth(walk.design, kmax)?;
        let c = walk.continuation();
        let w = sys.checked_weighted_traces(c, tau_needed(walk.design.z0, kmax), "r")?;
        Segments::of_walk(&w, walk, kmax)
    }

    /// Segments 0..=kmax of the expected time alone (`w = m`): enough for the flag rates, which
    /// do not depend on the system.
    pub fn masses_only(walk: &Walk, kmax: u64) -> Result<Self> {
        Self::check_depth(walk.design, kmax)?;
        let need = tau_needed(walk.design.z0, kmax);
        if need >= crate::system::MAX_TRACES {
            return Err(Error::TooLarge {
                arg: "r".into(),
                requested: need,
                limit: crate::system::MAX_TRACES,
            });
        }
        let mass: Vec<f64> = (0..=need as u64).map(|tau| walk.c_pow(tau)).collect();
        Segments::of_walk(&mass, walk, kmax)
    }

    fn check_depth(design: OnlineDesign, kmax: u64) -> Result<()> {
        if design.mu < 1.0 && kmax > MAX_SEGMENTS_MIXED {
            return Err(Error::TooLarge {
                arg: "r (with mu < 1)".into(),
                requested: kmax as u128,
                limit: MAX_SEGMENTS_MIXED as u128,
            });
        }
        Ok(())
    }

    /// The deepest segment an attack reaches: its longest cyclic run of blocked flag-ACKs
    /// (below the period, since at least one flag gets through).
    pub fn depth(attack: &Attack) -> u64 {
        attack
            .longest_blocked_run()
            .min(attack.period().saturating_sub(1))
    }

    /// J under an attack: the first-r-of-t closed form when the attack has that shape, else the
    /// mask sum. The attack must let at least one flag-ACK through.
    pub fn j_attack(&self, attack: &Attack) -> Result<f64> {
        attack.validate()?;
        attack.check_lets_flags_through()?;
        match attack.as_first_r() {
            Some((r, t)) => {
                self.check_holds(r)?;
                Ok(self.j_first_r(r as usize, t as usize))
            }
            None => self.j_mask(&attack.blocking_mask()?),
        }
    }

    /// Flag-ACKs per step under an attack (None: no attack).
    pub fn attack_flag_rates(&self, attack: Option<&Attack>) -> Result<(f64, f64)> {
        match attack {
            None => self.flag_rates(&[false]),
            Some(a) => {
                a.validate()?;
                self.flag_rates(&a.blocking_mask()?)
            }
        }
    }

    fn check_holds(&self, k: u64) -> Result<()> {
        if (self.w.len() as u64) <= k {
            return Err(Error::invalid(
                "r",
                format!("needs segments up to {k}, have {}", self.w.len()),
            ));
        }
        Ok(())
    }

    /// J of the walk with a blocking mask over the attacker's counter (true = blocked).
    /// Every mask must leave at least one flag through.
    pub fn j_mask(&self, mask: &[bool]) -> Result<f64> {
        let (num, den) = self.mask_sums(mask)?;
        Ok(num / den)
    }

    /// Long-run flag-ACKs per step under a blocking mask: (sent by the detector, delivered to
    /// the sensor). Each counter level is left at rate F = u / D, so t levels send t F and the
    /// unblocked ones deliver (number of zeros in the mask) F.
    pub fn flag_rates(&self, mask: &[bool]) -> Result<(f64, f64)> {
        let (_, den) = self.mask_sums(mask)?;
        let per_level = self.u / den;
        let open = mask.iter().filter(|&&b| !b).count();
        Ok((mask.len() as f64 * per_level, open as f64 * per_level))
    }

    /// (N, D) = (Σ_σ Σ_k c̃(σ-k) W_k, Σ_σ Σ_k c̃(σ-k) M_k) for a blocking mask.
    fn mask_sums(&self, mask: &[bool]) -> Result<(f64, f64)> {
        let t = mask.len();
        if t == 0 {
            return Err(Error::invalid("mask", "must not be empty"));
        }
        if mask.iter().all(|&b| b) {
            return Err(Error::invalid(
                "mask",
                "blocks every flag-ACK: that is J_max, see schedules::j_max",
            ));
        }
        let run = longest_cyclic_run(mask);
        if self.w.len() <= run {
            return Err(Error::invalid(
                "mask",
                format!("needs segments up to {run}"),
            ));
        }
        let c_tilde = |j: usize| {
            if mask[(j + t - 1) % t] {
                self.restart_after_block
            } else {
                1.0
            }
        };
        let (mut num, mut den) = (0.0, 0.0);
        for sigma in 0..t {
            // Segment k lives in level σ iff the k flags before σ were all blocked.
            // k < t always: the mask has an unblocked position, which ends the walk back.
            let mut k = 0;
            loop {
                let c = c_tilde((sigma + t - k) % t);
                num += c * self.w[k];
                den += c * self.m[k];
                if !mask[(sigma + 2 * t - k - 1) % t] {
                    break;
                }
                k += 1;
            }
        }
        Ok((num, den))
    }

    /// Cumulative quantities for "block the first r of every t": with
    /// `a_r = Σ_{σ=1..r} W_σ + (1-u) Σ_{k<r} (r-k) W_k - r W_0` (and `b_r` the same for M),
    /// J(r, t) = (t W_0 + a_r) / (t M_0 + b_r). Returns (a_r, b_r) for r = 0..=rmax.
    pub fn first_r_offsets(&self, rmax: usize) -> (Vec<f64>, Vec<f64>) {
        let one_minus_u = self.restart_after_block;
        let run = |v: &[f64]| -> Vec<f64> {
            let mut out = Vec::with_capacity(rmax + 1);
            let (mut head, mut tail, mut partial) = (0.0, 0.0, 0.0);
            // head = Σ_{σ=1..r} v_σ; tail = Σ_{k<r} (r-k) v_k; partial = Σ_{k<r} v_k.
            for r in 0..=rmax {
                // r W_0 is 0 for r = 0 even when W_0 is beyond the double range (no 0 * inf).
                let shift = if r == 0 { 0.0 } else { r as f64 * v[0] };
                out.push(head + one_minus_u * tail - shift);
                partial += v[r];
                tail += partial;
                if r < rmax {
                    head += v[r + 1];
                }
            }
            out
        };
        (run(&self.w), run(&self.m))
    }

    /// J(r, t) for "block the first r of every t flag-ACKs".
    pub fn j_first_r(&self, r: usize, t: usize) -> f64 {
        let (a, b) = self.first_r_offsets(r);
        first_r_j(t as f64, self.w[0], a[r], self.m[0], b[r])
    }

    /// The numerator N(r, t) = t W_0 + a_r alone (with masses as `w`, the normaliser D).
    pub fn first_r_numerator(&self, r: usize, t: usize) -> f64 {
        let (a, _) = self.first_r_offsets(r);
        t as f64 * self.w[0] + a[r]
    }
}

/// Multiplies segment k by ε^k (see [`Segments`]); exact when nothing is forged. A segment that
/// c = 0 empties (γ = 1) stays 0.
fn scale_by_block_factor(v: &mut [f64], walk: &Walk) {
    let ln_eps = walk.ln_block_factor();
    if ln_eps == 0.0 {
        return;
    }
    for (k, x) in v.iter_mut().enumerate().skip(1) {
        let f = k as f64 * ln_eps;
        *x = if *x == 0.0 {
            0.0
        } else if f < 700.0 {
            *x * f.exp()
        } else {
            (x.ln() + f).exp() // ε^k alone would overflow; the product does not
        };
    }
}

/// J(r, t) = (t W_0 + a_r) / (t M_0 + b_r). The numerator is a sum of non-negative terms written
/// with a subtraction (a_r holds - r W_0), so a NaN there means inf - inf: W beyond the double
/// range, J = +inf.
#[inline]
pub fn first_r_j(t: f64, w0: f64, a_r: f64, m0: f64, b_r: f64) -> f64 {
    let num = t * w0 + a_r;
    let num = if num.is_nan() { f64::INFINITY } else { num };
    num / (t * m0 + b_r)
}

/// Segment sums Σ_i C(k,i) μ^(k-i) (1-μ)^i Z_k(k z0 + i) of two per-τ weights `v` and `u` (the
/// weighted traces and the masses), where Z_0(s) = Σ_{z=0..z0} v[s+z] + (1-μ) v[s+z0+1] and
/// Z_k(s) = Z_0(s) - v[s] for k ≥ 1. Both share one pass over the binomial weights (O(kmax²)
/// for μ < 1). Each sum adds its terms in the order of i, starting from the value an empty
/// `Iterator::sum` starts from, so the results are those of `.sum()` over each vector alone.
fn segment_sums(v: &[f64], u: &[f64], z0: u64, mu: f64, kmax: u64) -> (Vec<f64>, Vec<f64>) {
    let z = z0 as usize;
    let (pre_v, pre_u) = (prefix(v), prefix(u));
    let n = kmax as usize + 1;
    let (mut out_v, mut out_u) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let one_mu = 1.0 - mu;
    // Z_k(k z0 + i) for i = 0..len: a difference of prefix sums plus the long interval's tail.
    let zsums = |out: &mut Vec<f64>, pre: &[f64], x: &[f64], k: usize, len: usize| {
        let (base, first) = (k * z, usize::from(k > 0));
        let ends = &pre[base + z + 1..base + z + 1 + len];
        let starts = &pre[base + first..base + first + len];
        let tails = &x[base + z + 1..base + z + 1 + len];
        out.clear();
        out.extend(ends.iter().zip(starts).zip(tails).map(|((e, s), t)| {
            let tail = if one_mu > 0.0 { one_mu * t } else { 0.0 };
            let sum = e - s + tail;
            // The terms are non-negative and overflow only from some τ on (the traces
            // grow geometrically), so inf - inf is a segment beyond the double range:
            // +inf, not NaN.
            if sum.is_nan() {
                f64::INFINITY
            } else {
                sum
            }
        }));
    };
    if mu == 1.0 {
        let (mut zv, mut zu) = (Vec::with_capacity(1), Vec::with_capacity(1));
        for k in 0..n {
            zsums(&mut zv, &pre_v, v, k, 1);
            zsums(&mut zu, &pre_u, u, k, 1);
            out_v.push(zv[0]);
            out_u.push(zu[0]);
        }
        return (out_v, out_u);
    }
    let empty_sum: f64 = std::iter::empty::<f64>().sum();
    let mut binom: Vec<f64> = Vec::with_capacity(n + 1);
    let mut next: Vec<f64> = Vec::with_capacity(n + 1);
    let (mut zv, mut zu) = (Vec::with_capacity(n + 1), Vec::with_capacity(n + 1));
    binom.push(1.0);
    for k in 0..n {
        let len = binom.len();
        zsums(&mut zv, &pre_v, v, k, len);
        zsums(&mut zu, &pre_u, u, k, len);
        let (mut tv, mut tu) = (empty_sum, empty_sum);
        for ((&b, &sv), &su) in binom.iter().zip(&zv).zip(&zu) {
            let (x, y) = if b == 0.0 {
                (0.0, 0.0)
            } else {
                (b * sv, b * su)
            };
            tv += x;
            tu += y;
        }
        out_v.push(tv);
        out_u.push(tu);
        // Binomial law of the number of long intervals, one segment on:
        // next[i] = (1-μ) binom[i-1] + μ binom[i] (terms >= 0, so no signed zero to mind).
        next.clear();
        next.push(mu * binom[0]);
        next.extend(binom.windows(2).map(|w| one_mu * w[0] + mu * w[1]));
        next.push(one_mu * binom[len - 1]);
        std::mem::swap(&mut binom, &mut next);
    }
    (out_v, out_u)
}

/// The most damaging mask with `blocked` of `t` flag-ACKs blocked (exhaustive, t <= 24), its J,
/// and the J of the consecutive mask (the paper's "first r of t").
pub fn worst_mask(seg: &Segments, t: usize, blocked: usize) -> Result<(Vec<bool>, f64, f64)> {
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
    let to_mask = |bits: u32| (0..t).map(|i| bits >> i & 1 == 1).collect::<Vec<bool>>();
    let consecutive = (1u32 << blocked) - 1;
    let j_consecutive = seg.j_mask(&to_mask(consecutive))?;
    let (mut best_bits, mut best_j) = (consecutive, j_consecutive);
    if blocked > 0 {
        // Gosper's hack: every t-bit word with `blocked` ones, in increasing order.
        let mut bits = consecutive;
        while bits < (1u32 << t) {
            let j = seg.j_mask(&to_mask(bits))?;
            if j > best_j * (1.0 + 1e-12) {
                (best_bits, best_j) = (bits, j);
            }
            let c = bits & bits.wrapping_neg();
            let r = bits + c;
            bits = (((r ^ bits) >> 2) / c) | r;
        }
    }
    Ok((to_mask(best_bits), best_j, j_consecutive))
}

/// J of the large-period limit r, t → ∞ with r/t → β: the time-weighted mix of the unattacked
/// and the all-blocked regimes,
/// J = [(1-β) W_0 + β (1-u) W_∞] / [(1-β) M_0 + β (1-u) M_∞], with M_∞ = 1/λ and
/// W_∞ = J_max/λ (every flag blocked: the sensor never uses high power).
pub fn j_limit(seg: &Segments, lam: f64, j_max: f64, beta: f64) -> Result<f64> {
    if !(beta.is_finite() && (0.0..=1.0).contains(&beta)) {
        return Err(Error::invalid(
            "beta",
            format!("must lie in [0, 1], got {beta}"),
        ));
    }
    if beta == 0.0 {
        return Ok(seg.w[0] / seg.m[0]);
    }
    if j_max.is_infinite() {
        return Ok(f64::INFINITY);
    }
    let blk = beta * seg.one_minus_u / lam;
    Ok(((1.0 - beta) * seg.w[0] + blk * j_max) / ((1.0 - beta) * seg.m[0] + blk))
}

/// The β at which [`j_limit`] equals `j_ref` (J_offline): β̄ = G / (G + L) with
/// G = (J_ref - J_on) M_0 and L = (1-u)/λ (J_max - J_ref), the time-weighted gain of the
/// unattacked and loss of the all-blocked regime. 0 when the online schedule does not beat
/// `j_ref` even unattacked (or J_max is infinite); 1 when even J_max does not exceed it.
pub fn beta_limit_threshold(seg: &Segments, lam: f64, j_max: f64, j_ref: f64) -> f64 {
    let gain = j_ref * seg.m[0] - seg.w[0];
    if gain <= 0.0 || j_max.is_infinite() {
        return 0.0;
    }
    let loss = seg.one_minus_u / lam * (j_max - j_ref);
    if loss <= 0.0 {
        return 1.0;
    }
    gain / (gain + loss)
}

#[cfg(test)]
mod tests;
