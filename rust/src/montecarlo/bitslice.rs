//! The bit-sliced covariance kernel: the 256 runs of a block are the bit lanes of four u64 words.
//!
//! Every per-run quantity is held as bit-planes, so one word operation advances 64 runs:
//!
//! * the holding time τ as a thermometer: bit l of `therm[j]` is set iff run l has τ ≥ j
//!   (j = 1..=depth; τ never exceeds the plan's bound, which is the depth);
//! * the detector's zero count (under attack) as a thermometer with levels 1..=z0+1;
//! * the attacker's flag counter σ in binary planes; "block" is σ in one of the mask's runs of
//!   ones, a few bit-serial comparisons with constants.
//!
//! A Bernoulli(p) draw compares each lane's uniform U with the exact threshold T = ⌊p 2^64⌋ bit by
//! bit from the most significant, one random word per bit (bit l of the word belongs to lane l),
//! and stops once every lane that needs a draw is decided or T has no further one bits (the
//! undecided lanes then have U ≥ T). Each lane hits iff U < T: exactly Bernoulli(T / 2^64), as in
//! the lane kernels. Only low-power lanes draw the channel, and the μ draw is made only where the
//! zero count is exactly z0 (the one place it matters); a draw for all 256 lanes takes about
//! log2(256) + 1.3 words for a generic p, one word for p = 1/2, none when no lane needs it.
//!
//! Tr P_k summed over runs is Σ_j tr[j] n_j(k), with the histogram n_j(k) of τ read off the
//! thermometer by popcounts. Each run's own sum Σ_k tr[τ_k] (for the standard error) needs each
//! run's count of steps with τ ≥ j: per-lane counters fed with the thermometer words through
//! carry-save adders (Harley-Seal, 16 steps at a time).
//!
//! The vector build is specialised on the thermometer size D (2, 4, 8, 16 or 32 levels, the
//! smallest that holds the plan) and on the counter width, so the level loops unroll and the
//! state stays in registers; the portable build runs D = 32 for every plan. Levels above the
//! plan's depth stay empty and add exact zeros, so the results do not depend on D.
//!
//! Randomness is consumed per block (four xoshiro256++ streams, one per word) and all lanes are
//! always simulated, padding lanes of a partial block included, so results depend only on the
//! seed; the portable and the AVX2 builds run the same integer code and the same f64 additions
//! in the same order, hence are bit-identical. The random streams differ from the lane kernels',
//! so for one seed the two families give different (equally distributed) samples.

use std::sync::atomic::{AtomicBool, Ordering};

use super::KernelFlags;
use crate::error::{Error, Result};

mod words;

pub(super) use words::RUNS;
use words::{
    and, andnot, equals, increment, less_than, not, or, popcount, splat, xor, LaneCounter, Rng4,
    BATCH, ONES, W, ZERO,
};

/// Deepest thermometer (largest τ bound, and largest memory z0 + 1 under attack) the kernel
/// takes; deeper plans use the lane kernels, whose cost does not grow with the bound.
pub(super) const MAX_DEPTH: usize = 32;
/// Most runs of ones in a blocking mask (each costs up to two comparisons per step).
pub(super) const MAX_MASK_RUNS: usize = 4;
/// Steps between two checks of the cancel flag.
const CANCEL_STEPS: usize = 1 << 14;

/// The plan of a bit-sliced run (built by the driver when the experiment fits).
#[derive(Debug, Clone)]
pub(super) struct BsPlan {
    pub(super) lam_thr: u64,
    pub(super) mu_thr: u64,
    pub(super) z0: usize,
    /// Memory length when there is no μ draw.
    pub(super) fixed_memory: usize,
    /// Offline pattern (1 = high power); unused online.
    pub(super) pattern: Vec<u8>,
    /// Runs of ones of the blocking mask, as half-open intervals of the counter.
    pub(super) mask_runs: Vec<(u64, u64)>,
    pub(super) mask_len: u64,
    /// tr[τ], τ = 0..=depth.
    pub(super) tr: Vec<f64>,
}

impl BsPlan {
    fn depth(&self) -> usize {
        self.tr.len() - 1
    }

    /// Thermometer levels needed: τ up to the depth, and the zero count up to the memory.
    fn levels(&self, mu_draw: bool, attack: bool) -> usize {
        let memory = if mu_draw {
            self.z0 + 1
        } else {
            self.fixed_memory
        };
        self.depth().max(if attack { memory } else { 0 }).max(1)
    }

    /// Bits of the attacker's counter: enough to hold `mask_len` itself (the wrap test).
    fn counter_bits(&self) -> usize {
        (64 - self.mask_len.leading_zeros()) as usize
    }
}

/// Runs of ones of `mask` as half-open index intervals.
pub(super) fn mask_runs(mask: &[bool]) -> Vec<(u64, u64)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, &b) in mask.iter().chain(std::iter::once(&false)).enumerate() {
        match (b, start) {
            (true, None) => start = Some(i as u64),
            (false, Some(s)) => {
                runs.push((s, i as u64));
                start = None;
            }
            _ => {}
        }
    }
    runs
}

/// What one block reports.
pub(super) struct BsOut {
    /// Σ_k tr[τ_k] of each lane (all RUNS lanes; the caller keeps the active ones).
    pub(super) sum: Vec<f64>,
    /// Flag-ACKs delivered to each lane's sensor (only when recording; else empty).
    pub(super) delivered: Vec<u64>,
    /// Totals over the active lanes.
    pub(super) sent: u64,
    pub(super) blocked: u64,
    pub(super) hi_last: u64,
}

/// Inputs of one block.
pub(super) struct BsBlock<'a> {
    pub(super) seed: u64,
    pub(super) block: u64,
    /// Lanes 0..active are runs; the rest are simulated but not counted.
    pub(super) active: usize,
    pub(super) record: bool,
    /// Per-step sums over the active lanes are added here (length = horizon).
    pub(super) acc: &'a mut [f64],
}

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

/// The kernel on thermometers of D levels (levels[j] holds "≥ j + 1") and B counter planes;
/// `AVX` steps the random streams in AVX2 registers.
#[inline(always)]
fn body<
    const ONLINE: bool,
    const MU_DRAW: bool,
    const ATTACK: bool,
    const PROTO_A: bool,
    const D: usize,
    const B: usize,
    const AVX: bool,
>(
    p: &BsPlan,
    b: &mut BsBlock,
    cancel: &AtomicBool,
) -> Result<BsOut> {
    let bits = p.counter_bits();
    if p.levels(MU_DRAW, ATTACK) > D || (ATTACK && bits > B) || b.active > RUNS {
        return Err(Error::invalid(
            "sys",
            "plan too large for the bit-sliced kernel",
        ));
    }
    let active: W = std::array::from_fn(|w| match b.active.saturating_sub(64 * w) {
        0 => 0,
        n if n >= 64 => u64::MAX,
        n => (1u64 << n) - 1,
    });
    // tr padded with zeros to D + 1 levels (the extra levels are never occupied).
    let tr: [f64; MAX_DEPTH + 1] = std::array::from_fn(|j| p.tr.get(j).copied().unwrap_or(0.0));
    // Selectors of the memory lengths: level L - 1 holds "≥ L".
    let sel = |len: usize| -> [bool; D] { std::array::from_fn(|j| j + 1 == len) };
    let (sel_fixed, sel_short, sel_long) = (sel(p.fixed_memory), sel(p.z0), sel(p.z0 + 1));
    let mut rng = Rng4::for_block(b.seed, b.block);
    let mut therm = [ZERO; D];
    let mut zeros = [ZERO; D];
    let mut sigma = [ZERO; B];
    let mut hi = ONES; // k = 1 is a high-power step
    let mut counters = [LaneCounter::NEW; D];
    let (mut sent_c, mut lost_c) = (LaneCounter::NEW, LaneCounter::NEW);
    let mut batch = [[ZERO; BATCH]; D];
    let (mut sent_b, mut lost_b) = ([ZERO; BATCH], [ZERO; BATCH]);
    let mut pat = 0usize;
    let horizon = b.acc.len();
    for (k0, steps) in b.acc.chunks_mut(BATCH).enumerate() {
        if (k0 * BATCH) % CANCEL_STEPS == 0 && cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for (s, acc) in steps.iter_mut().enumerate() {
            let high = if ONLINE {
                hi
            } else {
                let g = p.pattern[pat];
                pat = if pat + 1 == p.pattern.len() {
                    0
                } else {
                    pat + 1
                };
                splat(g == 1)
            };
            // Only low-power packets need the channel's draw.
            let arrive = or(high, rng.bernoulli::<AVX>(p.lam_thr, not(high)));
            // τ' = 0 on arrival, else τ + 1 (never beyond the plan's bound <= D).
            for j in (1..D).rev() {
                therm[j] = andnot(therm[j - 1], arrive);
            }
            therm[0] = not(arrive);
            // Histogram of τ over the active lanes from n[j] = #(τ >= j); empty bins add
            // nothing (a select, not a branch, and no 0 · inf).
            let mut above = b.active as u32;
            let mut v = 0.0;
            for j in 0..D {
                let n = popcount(and(therm[j], active));
                let x = tr[j] * f64::from(above - n);
                v += if above != n { x } else { 0.0 };
                above = n;
                batch[j][s] = therm[j];
            }
            let x = tr[D] * f64::from(above);
            *acc += v + if above != 0 { x } else { 0.0 };
            if !ONLINE {
                continue;
            }
            // The detector flags where the zero count reaches the memory: z0 bits (`short`,
            // drawn only where the count is exactly z0, the one place it matters) or z0 + 1
            // with a μ draw, else the fixed length.
            let mut reached = |t: &[W; D]| -> W {
                if MU_DRAW {
                    let (long, at_z0) = (pick(t, &sel_long), pick(t, &sel_short));
                    let short = rng.bernoulli::<AVX>(p.mu_thr, andnot(at_z0, long));
                    or(long, and(at_z0, short))
                } else {
                    pick(t, &sel_fixed)
                }
            };
            let (flag, lost);
            if ATTACK {
                for j in (1..D).rev() {
                    zeros[j] = andnot(zeros[j - 1], arrive);
                }
                zeros[0] = not(arrive);
                flag = reached(&zeros);
                for z in zeros.iter_mut() {
                    *z = andnot(*z, flag);
                }
                let mut blocking = ZERO;
                for &(lo, end) in &p.mask_runs {
                    let below_end = less_than(&sigma, end);
                    let run = if lo == 0 {
                        below_end
                    } else {
                        andnot(below_end, less_than(&sigma, lo))
                    };
                    blocking = or(blocking, run);
                }
                if PROTO_A {
                    // One bit every step; the attacker flips 1-bits to 0.
                    let bit = flag;
                    lost = and(bit, blocking);
                    hi = xor(bit, lost);
                    increment(&mut sigma, bit);
                } else {
                    // A flag packet only when a flag is due; the attacker drops it.
                    lost = and(flag, blocking);
                    hi = andnot(flag, lost);
                    increment(&mut sigma, flag);
                }
                // All B planes take part (B >= bits; the planes above `bits` stay zero), so
                // these loops unroll.
                let wrap = equals(&sigma, p.mask_len);
                for plane in sigma.iter_mut() {
                    *plane = andnot(*plane, wrap);
                }
            } else {
                // Without an attacker every flag is delivered and followed by an arrival, so
                // the zero count equals τ whenever it matters.
                flag = reached(&therm);
                lost = ZERO;
                hi = flag;
            }
            sent_b[s] = flag;
            lost_b[s] = lost;
        }
        // A partial last batch counts zeros in its unused slots.
        let n = steps.len();
        for (c, d) in counters.iter_mut().zip(batch.iter_mut()) {
            d[n..].fill(ZERO);
            c.add16(d);
        }
        if ONLINE {
            sent_b[n..].fill(ZERO);
            sent_c.add16(&sent_b);
            if ATTACK {
                lost_b[n..].fill(ZERO);
                lost_c.add16(&lost_b);
            }
        }
    }
    // Each lane's Σ_k tr[τ_k] from its histogram, in the order of the per-step sums.
    let mut above = [horizon as u64; RUNS];
    let mut sum = vec![0.0; RUNS];
    for (j, c) in counters.iter().enumerate() {
        for ((s, a), n) in sum.iter_mut().zip(above.iter_mut()).zip(c.counts()) {
            let x = tr[j] * (*a - n) as f64;
            *s += if *a != n { x } else { 0.0 };
            *a = n;
        }
    }
    for (s, a) in sum.iter_mut().zip(above) {
        let x = tr[D] * a as f64;
        *s += if a != 0 { x } else { 0.0 };
    }
    Ok(BsOut {
        sum,
        delivered: if b.record {
            let (sent, lost) = (sent_c.counts(), lost_c.counts());
            (0..RUNS).map(|l| sent[l] - lost[l]).collect()
        } else {
            Vec::new()
        },
        sent: sent_c.total(active),
        blocked: lost_c.total(active),
        hi_last: if ONLINE {
            u64::from(popcount(and(hi, active)))
        } else {
            0
        },
    })
}

fn block_portable<const O: bool, const M: bool, const A: bool, const P: bool>(
    p: &BsPlan,
    b: &mut BsBlock,
    cancel: &AtomicBool,
) -> Result<BsOut> {
    body::<O, M, A, P, MAX_DEPTH, 64, false>(p, b, cancel)
}

/// # Safety
/// The CPU must support AVX2 and POPCNT.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn block_avx2<
    const O: bool,
    const M: bool,
    const A: bool,
    const P: bool,
    const D: usize,
    const B: usize,
>(
    p: &BsPlan,
    b: &mut BsBlock,
    cancel: &AtomicBool,
) -> Result<BsOut> {
    body::<O, M, A, P, D, B, true>(p, b, cancel)
}

/// The AVX2 kernel for flags ($o, $m, $a, $pa) and counter width $b, specialised on the
/// smallest thermometer size that holds `levels`.
#[cfg(target_arch = "x86_64")]
macro_rules! avx2_by_depth {
    ($o:expr, $m:expr, $a:expr, $pa:expr, $b:literal, $levels:expr, $p:ident, $blk:ident, $c:ident) => {
        // SAFETY (all arms): the caller checked AVX2 and POPCNT at run time.
        unsafe {
            match $levels {
                0..=2 => block_avx2::<$o, $m, $a, $pa, 2, $b>($p, $blk, $c),
                3..=4 => block_avx2::<$o, $m, $a, $pa, 4, $b>($p, $blk, $c),
                5..=8 => block_avx2::<$o, $m, $a, $pa, 8, $b>($p, $blk, $c),
                9..=16 => block_avx2::<$o, $m, $a, $pa, 16, $b>($p, $blk, $c),
                _ => block_avx2::<$o, $m, $a, $pa, 32, $b>($p, $blk, $c),
            }
        }
    };
}

/// Runs one block with the kernel for (online, μ draw, attack, protocol A), on AVX2 if `avx2`
/// and the CPU has it.
pub(super) fn run_block(
    p: &BsPlan,
    flags: KernelFlags,
    avx2: bool,
    b: &mut BsBlock,
    cancel: &AtomicBool,
) -> Result<BsOut> {
    #[cfg(target_arch = "x86_64")]
    if avx2 && is_x86_feature_detected!("avx2") && is_x86_feature_detected!("popcnt") {
        let levels = p.levels(flags.mu_draw, flags.attack);
        // Counter planes: none without an attacker, 4 for masks up to 15 long, else 64.
        let wide = p.counter_bits() > 4;
        // Only attacked kernels have counter planes: monomorphise B = 4 and 64 for those alone.
        macro_rules! sized {
            ($o:tt, $m:tt, false, $pa:tt) => {
                avx2_by_depth!($o, $m, false, $pa, 1, levels, p, b, cancel)
            };
            ($o:tt, $m:tt, true, $pa:tt) => {
                if wide {
                    avx2_by_depth!($o, $m, true, $pa, 64, levels, p, b, cancel)
                } else {
                    avx2_by_depth!($o, $m, true, $pa, 4, levels, p, b, cancel)
                }
            };
        }
        return by_flags!(flags, sized);
    }
    let _ = avx2;
    macro_rules! portable {
        ($o:expr, $m:expr, $a:expr, $pa:expr) => {
            block_portable::<$o, $m, $a, $pa>(p, b, cancel)
        };
    }
    by_flags!(flags, portable)
}

#[cfg(test)]
mod tests;
