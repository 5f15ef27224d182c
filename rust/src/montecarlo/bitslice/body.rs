//! The bit-sliced kernel's body: one block of [`RUNS`] runs, step by step, on bit-planes. Its
//! helpers are `#[inline(always)]` so that, as in one function, the thermometers and the counter
//! planes stay in registers and the level loops unroll.
//!
//! (Over 450 lines: the step's helpers must stay in one module to be inlined into one loop; the
//! independent-blocking and forging paths added the last ~60.)

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};

use super::deep::DeepRuns;
use super::words::{
    and, andnot, any, equals, increment, less_than, not, or, popcount, splat, xor, LaneCounter,
    Rng4, StreamStepper, BATCH, ONES, RUNS, W, ZERO,
};
use super::{BsBlock, BsChannel, BsOut, BsPlan, Prob, CANCEL_STEPS, MAX_DEPTH};
use crate::error::{Error, Result};

/// OR of the levels whose selector is set (a level picked by a run-time index without
/// indexing, so the levels can live in registers).
#[inline(always)]
fn pick<const D: usize>(levels: &[W; D], sel: &[bool; D]) -> W {
    let mut out = ZERO;
    for j in 0..D {
        out = or(out, and(levels[j], splat(sel[j])));
    }
    out
}

/// Advances a thermometer by one step: all levels clear where `reset`, else every lane moves
/// one level up (`levels[j]` holds "≥ j + 1").
#[inline(always)]
pub(in crate::montecarlo) fn step_up<const D: usize>(levels: &mut [W; D], reset: W) {
    for j in (1..D).rev() {
        levels[j] = andnot(levels[j - 1], reset);
    }
    levels[0] = not(reset);
}

/// The selectors of the memory lengths on a zero-count thermometer: level L - 1 holds "≥ L".
struct MemoryLevels<const D: usize> {
    /// The memory length when there is no μ draw.
    fixed: [bool; D],
    /// z0 bits (with probability μ).
    short: [bool; D],
    /// z0 + 1 bits.
    long: [bool; D],
}

impl<const D: usize> MemoryLevels<D> {
    /// The selectors of `p`'s memory lengths.
    fn new(p: &BsPlan) -> Self {
        let sel = |len: usize| -> [bool; D] { std::array::from_fn(|j| j + 1 == len) };
        MemoryLevels {
            fixed: sel(p.fixed_memory),
            short: sel(p.z0),
            long: sel(p.z0 + 1),
        }
    }

    /// Lanes where the zero count `count` reaches the detector's memory: z0 bits (`short`,
    /// drawn only where the count is exactly z0, the one place it matters) or z0 + 1 with a μ
    /// draw, else the fixed length.
    #[inline(always)]
    fn reached<const MU_DRAW: bool, S: StreamStepper>(
        &self,
        count: &[W; D],
        rng: &mut Rng4,
        stepper: S,
        mu_thr: u64,
    ) -> W {
        if MU_DRAW {
            let (long, at_z0) = (pick(count, &self.long), pick(count, &self.short));
            let short = rng.bernoulli(stepper, mu_thr, andnot(at_z0, long));
            or(long, and(at_z0, short))
        } else {
            pick(count, &self.fixed)
        }
    }
}

/// Lanes whose attacker counter σ (binary planes) lies in one of the mask's runs of ones.
#[inline(always)]
fn blocking<const B: usize>(sigma: &[W; B], mask_runs: &[Range<u64>]) -> W {
    let mut blocking = ZERO;
    for run in mask_runs {
        let below_end = less_than(sigma, run.end);
        let inside = if run.start == 0 {
            below_end
        } else {
            andnot(below_end, less_than(sigma, run.start))
        };
        blocking = or(blocking, inside);
    }
    blocking
}

/// What the attacker lets through this step.
struct Delivery {
    /// Lanes whose sensor receives a flag (Δ at the next step).
    high_next: W,
    /// Lanes whose flag the attacker blocked or flipped.
    lost: W,
}

/// The attacker on this step's flags: blocks them where `blocking`, and counts every flag in
/// σ modulo `mask_len`. Protocol A and B give the same result by different operations.
#[inline(always)]
fn attack<const PROTO_A: bool, const B: usize>(
    flag: W,
    blocking: W,
    sigma: &mut [W; B],
    mask_len: u64,
) -> Delivery {
    let delivery = if PROTO_A {
        // One bit every step; the attacker flips 1-bits to 0.
        let bit = flag;
        let lost = and(bit, blocking);
        increment(sigma, bit);
        Delivery {
            high_next: xor(bit, lost),
            lost,
        }
    } else {
        // A flag packet only when a flag is due; the attacker drops it.
        let lost = and(flag, blocking);
        increment(sigma, flag);
        Delivery {
            high_next: andnot(flag, lost),
            lost,
        }
    };
    // All B planes take part (B >= the counter's bits; the planes above stay zero), so these
    // loops unroll.
    let wrap = equals(sigma, mask_len);
    for plane in sigma.iter_mut() {
        *plane = andnot(*plane, wrap);
    }
    delivery
}

/// Independent blocking's β decisions, drawn ahead: each lane holds up to two, for its next
/// two flags.
///
/// A decision is drawn before the flag it decides, from random bits nothing else reads, so it
/// is exactly an independent Bernoulli(β) draw, as one made at the flag's step would be. Drawing
/// ahead lets many lanes share a draw: a bit-serial draw takes about log2(lanes) + 1.3 words
/// (see `Rng4::bernoulli`) whatever the number of lanes, so redrawing every used decision at
/// once, both planes, when some flag finds its lane without one costs far fewer words per step
/// than a draw for each step's flags. Two planes, not one: a lane flags at most every z0 + 1
/// steps, so with one decision a lane ran dry about every third step on the paper's example;
/// with two, refills (two draws each) come less often: 3.7% fewer instructions in all.
pub(in crate::montecarlo) struct BetaPool {
    /// Each lane's decision for its next flag (1 = block it), valid where `fresh`.
    next: W,
    /// Lanes whose `next` is drawn and not yet used.
    fresh: W,
    /// Each lane's decision for the flag after, valid where `spare_fresh`.
    spare: W,
    /// Lanes whose `spare` is drawn and not yet used.
    spare_fresh: W,
}

impl BetaPool {
    /// No decision drawn yet.
    pub(in crate::montecarlo) const EMPTY: BetaPool = BetaPool {
        next: ZERO,
        fresh: ZERO,
        spare: ZERO,
        spare_fresh: ZERO,
    };

    /// The decisions for this step's flags `flag` (1 = blocked), drawn with threshold `thr`.
    #[inline(always)]
    pub(in crate::montecarlo) fn take<S: StreamStepper>(
        &mut self,
        flag: W,
        rng: &mut Rng4,
        stepper: S,
        thr: u64,
    ) -> W {
        if any(andnot(flag, self.fresh)) {
            // A draw is 0 outside the lanes it is made for, so OR-ing keeps the valid ones.
            let drawn = rng.bernoulli(stepper, thr, not(self.fresh));
            self.next = or(and(self.next, self.fresh), drawn);
            self.fresh = ONES;
            let drawn = rng.bernoulli(stepper, thr, not(self.spare_fresh));
            self.spare = or(and(self.spare, self.spare_fresh), drawn);
            self.spare_fresh = ONES;
        }
        let blocked = and(self.next, flag);
        // The flag lanes move their spare decision up.
        self.next = or(andnot(self.next, flag), and(self.spare, flag));
        self.fresh = or(andnot(self.fresh, flag), and(self.spare_fresh, flag));
        self.spare_fresh = andnot(self.spare_fresh, flag);
        blocked
    }
}

/// The independent attacker on this step's flags: blocks them where `blocking` (their β
/// decisions, see [`BetaPool`]), with no counter. Protocol A and B give the same result by
/// different operations.
#[inline(always)]
fn attack_random<const PROTO_A: bool>(flag: W, blocking: W) -> Delivery {
    if PROTO_A {
        let bit = flag;
        let lost = and(bit, blocking);
        Delivery {
            high_next: xor(bit, lost),
            lost,
        }
    } else {
        let lost = and(flag, blocking);
        Delivery {
            high_next: andnot(flag, lost),
            lost,
        }
    }
}

/// What reaches the sensor once the attacker forges: `high_next` (the genuine flags it let
/// through) plus a flag wherever no genuine flag was sent and `forge` (its γ draw, made for
/// those lanes only) is set.
#[inline(always)]
fn forge_flags<const PROTO_A: bool>(flag: W, high_next: W, forge: W) -> W {
    if PROTO_A {
        // The detector's 0-bit of this step flipped to 1.
        xor(high_next, andnot(forge, flag))
    } else {
        // A flag packet where the detector sent none.
        or(high_next, andnot(forge, flag))
    }
}

/// This step's Σ over the active lanes of `tr[τ]`, from the histogram `n[j]` = #(τ ≥ j) read off
/// the thermometer; empty bins add nothing (a select, not a branch, and no 0 · inf). With
/// `deep`, only the bins below `top` (the lanes at or above it are the caller's, see
/// [`DeepRuns`]); else `top` is D and the last bin is τ ≥ D. Also stores the thermometer in
/// slot `s` of the per-lane counters' batch.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn step_sum<const D: usize>(
    therm: &[W; D],
    active: W,
    active_runs: usize,
    tr: &[f64; MAX_DEPTH + 1],
    batch: &mut [[W; BATCH]; D],
    s: usize,
    top: usize,
    deep: bool,
) -> f64 {
    let mut above = active_runs as u32;
    let mut v = 0.0;
    for j in 0..D {
        if j < top {
            let n = popcount(and(therm[j], active));
            let x = tr[j] * f64::from(above - n);
            v += if above != n { x } else { 0.0 };
            above = n;
        }
        batch[j][s] = therm[j];
    }
    if deep {
        return v;
    }
    let x = tr[D] * f64::from(above);
    v + if above != 0 { x } else { 0.0 }
}

/// Per-lane counts, fed a batch of [`BATCH`] steps at a time.
struct Tallies<const D: usize> {
    /// Level j: each lane's count of steps with τ ≥ j + 1.
    levels: [LaneCounter; D],
    /// Each lane's flags sent.
    sent: LaneCounter,
    /// Each lane's flags blocked or flipped.
    lost: LaneCounter,
    /// Each lane's forged flags.
    forged: LaneCounter,
    /// The current batch of thermometer words, level by level.
    level_batch: [[W; BATCH]; D],
    /// The current batch of sent flags.
    sent_batch: [W; BATCH],
    /// The current batch of lost flags.
    lost_batch: [W; BATCH],
    /// The current batch of forged flags.
    forged_batch: [W; BATCH],
}

impl<const D: usize> Tallies<D> {
    /// All counts zero.
    fn new() -> Self {
        Tallies {
            levels: [LaneCounter::NEW; D],
            sent: LaneCounter::NEW,
            lost: LaneCounter::NEW,
            forged: LaneCounter::NEW,
            level_batch: [[ZERO; BATCH]; D],
            sent_batch: [ZERO; BATCH],
            lost_batch: [ZERO; BATCH],
            forged_batch: [ZERO; BATCH],
        }
    }

    /// Adds the batch's first `n` steps to the counters (a partial last batch counts zeros in
    /// its unused slots).
    #[inline(always)]
    fn add_batch<const ONLINE: bool, const ATTACK: bool, const FORGE: bool>(&mut self, n: usize) {
        for (c, d) in self.levels.iter_mut().zip(self.level_batch.iter_mut()) {
            d[n..].fill(ZERO);
            c.add16(d);
        }
        if ONLINE {
            self.sent_batch[n..].fill(ZERO);
            self.sent.add16(&self.sent_batch);
            if ATTACK {
                self.lost_batch[n..].fill(ZERO);
                self.lost.add16(&self.lost_batch);
            }
            if FORGE {
                self.forged_batch[n..].fill(ZERO);
                self.forged.add16(&self.forged_batch);
            }
        }
    }

    /// The block's report after `horizon` steps, with totals over the `active` lanes; each
    /// lane's delivered flag-ACKs (genuine ones let through and forged ones) if `record`. With
    /// `deep`, the histograms stop below `top` and the lanes' sums above it are `deep`'s.
    fn report(
        &self,
        horizon: usize,
        tr: &[f64; MAX_DEPTH + 1],
        (top, deep): (usize, Option<&DeepRuns>),
        active: W,
        record: bool,
        hi_last: u64,
    ) -> BsOut {
        BsOut {
            sum: lane_sums(&self.levels[..top], horizon, tr, deep.map(|d| &*d.sum)),
            delivered: if record {
                let (sent, lost) = (self.sent.counts(), self.lost.counts());
                let forged = self.forged.counts();
                (0..RUNS).map(|l| sent[l] - lost[l] + forged[l]).collect()
            } else {
                Vec::new()
            },
            sent: self.sent.total(active),
            blocked: self.lost.total(active),
            forged: self.forged.total(active),
            hi_last,
        }
    }
}

/// Each lane's Σ_k `tr[τ_k]` over `horizon` steps from its per-level counts (`levels[j]`: steps
/// with τ ≥ j + 1), in the order of the per-step sums: the bins τ = 0..levels.len(), then the
/// last bin τ ≥ levels.len() (`tr[levels.len()]` each) or, with `deep`, the lane's own sum over
/// its steps there.
pub(in crate::montecarlo) fn lane_sums(
    levels: &[LaneCounter],
    horizon: usize,
    tr: &[f64],
    deep: Option<&[f64; RUNS]>,
) -> Vec<f64> {
    let top = levels.len();
    let mut above = [horizon as u64; RUNS];
    let mut sum = vec![0.0; RUNS];
    for (j, c) in levels.iter().enumerate() {
        for ((s, a), n) in sum.iter_mut().zip(above.iter_mut()).zip(c.counts()) {
            let x = tr[j] * (*a - n) as f64;
            *s += if *a != n { x } else { 0.0 };
            *a = n;
        }
    }
    for (l, (s, a)) in sum.iter_mut().zip(above).enumerate() {
        let x = match deep {
            Some(deep) => deep[l],
            None => tr[top] * a as f64,
        };
        *s += if a != 0 { x } else { 0.0 };
    }
    sum
}

/// The lanes of runs `0..active` (the rest of the block is padding).
fn active_lanes(active: usize) -> W {
    std::array::from_fn(|w| match active.saturating_sub(64 * w) {
        0 => 0,
        n if n >= 64 => u64::MAX,
        n => (1u64 << n) - 1,
    })
}

/// The offline pattern's power at this step (all lanes alike), advancing `pos` cyclically.
#[inline(always)]
fn pattern_step(pattern: &[u8], pos: &mut usize) -> W {
    let g = pattern[*pos];
    *pos = if *pos + 1 == pattern.len() {
        0
    } else {
        *pos + 1
    };
    splat(g == 1)
}

/// The kernel on thermometers of D levels (`levels[j]` holds "≥ j + 1") and B counter planes;
/// `stepper` steps the random streams (on AVX2 registers, or portably). RANDOM blocks the
/// genuine flags independently (β decisions drawn ahead, [`BetaPool`]; no counter); FORGE forges
/// a flag with a γ draw for the lanes without one. CHANNEL: a two-state Markov channel, its
/// state one more bit-plane (1 = bad), drawn from the stationary law before step 1; a low-power
/// packet then arrives with its state's probability, and the state moves right after (its draw
/// is independent of the step's others, and the new state is first read at the next step).
/// Draws per step: λ, the channel's move, μ, β (when some flag needs one), γ, in that order.
#[inline(always)]
pub(super) fn body<
    const ONLINE: bool,
    const MU_DRAW: bool,
    const ATTACK: bool,
    const PROTO_A: bool,
    const RANDOM: bool,
    const FORGE: bool,
    const CHANNEL: bool,
    const D: usize,
    const B: usize,
    S: StreamStepper,
>(
    p: &BsPlan,
    b: &mut BsBlock,
    cancel: &AtomicBool,
    stepper: S,
) -> Result<BsOut> {
    // Only the kernels of the attacks that block or forge at random track deep runs.
    let deep_level = if RANDOM || FORGE { p.deep_level } else { 0 };
    if p.levels(MU_DRAW, ATTACK) > D
        || (ATTACK && p.counter_bits() > B)
        || b.active > RUNS
        || deep_level > D
        || (deep_level > 0 && b.deep_tr.len() <= deep_level)
        || CHANNEL != p.channel.is_some()
    {
        return Err(Error::invalid(
            "sys",
            "plan too large for the bit-sliced kernel",
        ));
    }
    let active = active_lanes(b.active);
    // tr padded with zeros to D + 1 levels (the extra levels are never occupied).
    let tr: [f64; MAX_DEPTH + 1] = std::array::from_fn(|j| p.tr.get(j).copied().unwrap_or(0.0));
    let memory = MemoryLevels::<D>::new(p);
    let mut rng = Rng4::for_block(b.seed, b.block);
    let mut therm = [ZERO; D];
    let mut zeros = [ZERO; D];
    let mut sigma = [ZERO; B];
    let mut hi = ONES; // k = 1 is a high-power step
    let mut tallies = Tallies::<D>::new();
    let mut pattern_pos = 0usize;
    let horizon = b.acc.len();
    // The thermometer's top level: τ ≥ deep_level is held by level deep_level - 1 and the
    // lanes there are tracked one by one; else every level counts.
    let (top, deep_sel): (usize, [bool; D]) = if deep_level > 0 {
        (deep_level, std::array::from_fn(|j| j + 1 == deep_level))
    } else {
        (D, [false; D])
    };
    let mut deep = (deep_level > 0).then(|| DeepRuns::new(deep_level));
    let mut beta_pool = BetaPool::EMPTY;
    // The channel's state plane (unused on the i.i.d. channel).
    let never = Prob::new(0.0);
    let channel = p.channel.unwrap_or(BsChannel {
        low: [never; 2],
        switch: [never; 2],
        start_bad: never,
    });
    let mut bad = ZERO;
    if CHANNEL {
        let start = (channel.start_bad, channel.start_bad);
        bad = rng.bernoulli_sel(stepper, start, ZERO, ONES);
    }
    for (batch_index, steps) in b.acc.chunks_mut(BATCH).enumerate() {
        if (batch_index * BATCH) % CANCEL_STEPS == 0 && cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for (s, acc) in steps.iter_mut().enumerate() {
            let high = if ONLINE {
                hi
            } else {
                pattern_step(&p.pattern, &mut pattern_pos)
            };
            // Only low-power packets need the channel's draw.
            let arrive = if CHANNEL {
                let low = (channel.low[0], channel.low[1]);
                let arrive = or(high, rng.bernoulli_sel(stepper, low, bad, not(high)));
                let switch = (channel.switch[0], channel.switch[1]);
                bad = xor(bad, rng.bernoulli_sel(stepper, switch, bad, ONES));
                arrive
            } else {
                or(high, rng.bernoulli(stepper, p.lam_thr, not(high)))
            };
            // τ' = 0 on arrival, else τ + 1 (never beyond the plan's bound <= D, except in
            // the lanes at or above a deep plan's top level).
            step_up(&mut therm, arrive);
            let batch = &mut tallies.level_batch;
            let is_deep = deep.is_some();
            // A deep plan's level is D itself on the specialised builds: a constant there.
            let mut v = if top == D {
                step_sum(&therm, active, b.active, &tr, batch, s, D, is_deep)
            } else {
                step_sum(&therm, active, b.active, &tr, batch, s, top, is_deep)
            };
            if let Some(deep) = deep.as_mut() {
                let now = if top == D {
                    therm[D - 1]
                } else {
                    pick(&therm, &deep_sel)
                };
                if let Some(x) = deep.step(now, active, b.deep_tr) {
                    v += x;
                }
            }
            *acc += v;
            if !ONLINE {
                continue;
            }
            let (flag, lost);
            if ATTACK {
                step_up(&mut zeros, arrive);
                flag = memory.reached::<MU_DRAW, S>(&zeros, &mut rng, stepper, p.mu_thr);
                for z in zeros.iter_mut() {
                    *z = andnot(*z, flag);
                }
                let delivery = if RANDOM {
                    let blocking = beta_pool.take(flag, &mut rng, stepper, p.beta_thr);
                    attack_random::<PROTO_A>(flag, blocking)
                } else {
                    let blocking = blocking(&sigma, &p.mask_runs);
                    attack::<PROTO_A, B>(flag, blocking, &mut sigma, p.mask_len)
                };
                lost = delivery.lost;
                hi = delivery.high_next;
            } else {
                // Without blocking every flag, genuine or forged, reaches the sensor and is
                // followed by an arrival, so the zero count equals τ whenever it matters.
                flag = memory.reached::<MU_DRAW, S>(&therm, &mut rng, stepper, p.mu_thr);
                lost = ZERO;
                hi = flag;
            }
            if FORGE {
                let forge = rng.bernoulli(stepper, p.gamma_thr, not(flag));
                hi = forge_flags::<PROTO_A>(flag, hi, forge);
                tallies.forged_batch[s] = forge;
            }
            tallies.sent_batch[s] = flag;
            tallies.lost_batch[s] = lost;
        }
        tallies.add_batch::<ONLINE, ATTACK, FORGE>(steps.len());
    }
    let hi_last = if ONLINE {
        u64::from(popcount(and(hi, active)))
    } else {
        0
    };
    let sums = (top, deep.as_ref());
    Ok(tallies.report(horizon, &tr, sums, active, b.record, hi_last))
}
