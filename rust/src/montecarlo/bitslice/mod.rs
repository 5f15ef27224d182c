//! The bit-sliced covariance kernel: the 256 runs of a block are the bit lanes of four u64 words.
//!
//! Every per-run quantity is held as bit-planes, so one word operation advances 64 runs:
//!
//! * the holding time τ as a thermometer: bit l of `therm[j]` is set iff run l has τ ≥ j
//!   (j = 1..=depth; τ never exceeds the plan's bound, which is the depth);
//! * the detector's zero count (under attack) as a thermometer with levels 1..=z0+1;
//! * the attacker's flag counter σ in binary planes; "block" is σ in one of the mask's runs of
//!   ones, a few bit-serial comparisons with constants. Independent blocking has no counter:
//!   each lane holds a β decision drawn ahead of its next flag. Forging is a γ draw in the lanes
//!   without a flag.
//!
//! Independent blocking leaves τ unbounded. Such plans (and forging plans whose bound is deep)
//! stop the thermometer at a level L few runs reach: level L - 1 holds "τ ≥ L", and the lanes
//! there keep their exact τ one by one (`deep.rs`), which the histogram's last bin leaves out.
//!
//! A Bernoulli(p) draw compares each lane's uniform U with the exact threshold T = ⌊p 2^64⌋ bit by
//! bit from the most significant, one random word per bit (bit l of the word belongs to lane l),
//! and stops once every lane that needs a draw is decided or T has no further one bits (the
//! undecided lanes then have U ≥ T). Each lane hits iff U < T: exactly Bernoulli(T / 2^64), as in
//! the lane kernels. Only low-power lanes draw the channel, the μ draw is made only where the
//! zero count is exactly z0 (the one place it matters), β ahead of the flags for every lane
//! whose decision was used, once some flag needs one, and γ only where no flag is sent; a draw
//! for all 256 lanes takes about
//! log2(256) + 1.3 words for a generic p, one word for p = 1/2, none when no lane needs it.
//!
//! Tr P_k summed over runs is Σ_j `tr[j]` n_j(k), with the histogram n_j(k) of τ read off the
//! thermometer by popcounts. Each run's own sum Σ_k `tr[τ_k]` (for the standard error) needs each
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

use std::ops::Range;
use std::sync::atomic::AtomicBool;

use super::cpu::Avx2;
use super::KernelFlags;
use crate::error::Result;

pub(super) mod body;
pub(super) mod deep;
pub(super) mod words;

use body::body;
use words::Portable;
pub(super) use words::{Prob, RUNS};

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
    /// The channel's Bernoulli threshold ⌊λ 2^64⌋ on low power.
    pub(super) lam_thr: u64,
    /// The threshold ⌊μ 2^64⌋ of the z0-bit memory.
    pub(super) mu_thr: u64,
    /// The threshold ⌊β 2^64⌋ of independent blocking (0 without it).
    pub(super) beta_thr: u64,
    /// The threshold ⌊γ 2^64⌋ of forging (0 without it).
    pub(super) gamma_thr: u64,
    /// The short memory length z0 (clamped to the depth + 1).
    pub(super) z0: usize,
    /// Memory length when there is no μ draw.
    pub(super) fixed_memory: usize,
    /// Offline pattern (1 = high power); unused online.
    pub(super) pattern: Vec<u8>,
    /// Runs of ones of the blocking mask, as intervals of the counter.
    pub(super) mask_runs: Vec<Range<u64>>,
    /// Flag-ACKs per period of the mask (1 without an attacker).
    pub(super) mask_len: u64,
    /// The top level L of a deep plan (0: none): the depth is L, and the lanes with τ ≥ L are
    /// tracked one by one with the full trace table ([`BsBlock::deep_tr`]). Only the kernels of
    /// independent blocking and forging take deep plans.
    pub(super) deep_level: usize,
    /// `tr[τ]`, τ = 0..=depth.
    pub(super) tr: Vec<f64>,
    /// A two-state Markov channel, held as one more bit-plane (1 = state 1, bad); `None`: the
    /// i.i.d. channel of `lam_thr`.
    pub(super) channel: Option<BsChannel>,
}

/// The draws of a two-state Markov channel (state 0 good, 1 bad).
#[derive(Debug, Clone, Copy)]
pub(super) struct BsChannel {
    /// Low-power arrival in state 0 and in state 1.
    pub(super) low: [Prob; 2],
    /// Leaving state 0 (p) and leaving state 1 (q), after each step.
    pub(super) switch: [Prob; 2],
    /// The first state is 1, p / (p + q) (the stationary law).
    pub(super) start_bad: Prob,
}

impl BsPlan {
    /// The largest τ (the thermometer's top level).
    fn depth(&self) -> usize {
        self.tr.len() - 1
    }

    /// Thermometer levels needed: τ up to the depth, and the zero count (or τ, which stands for
    /// it without blocking) up to the memory.
    fn levels(&self, mu_draw: bool, attack: bool) -> usize {
        let memory = if mu_draw {
            self.z0 + 1
        } else {
            self.fixed_memory
        };
        let counted = attack || self.deep_level > 0;
        self.depth().max(if counted { memory } else { 0 }).max(1)
    }

    /// Bits of the attacker's counter: enough to hold `mask_len` itself (the wrap test).
    fn counter_bits(&self) -> usize {
        (64 - self.mask_len.leading_zeros()) as usize
    }
}

/// Runs of ones of `mask` as index intervals.
pub(super) fn mask_runs(mask: &[bool]) -> Vec<Range<u64>> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, &b) in mask.iter().chain(std::iter::once(&false)).enumerate() {
        match (b, start) {
            (true, None) => start = Some(i as u64),
            (false, Some(s)) => {
                runs.push(s..i as u64);
                start = None;
            }
            _ => {}
        }
    }
    runs
}

/// What one block reports.
pub(super) struct BsOut {
    /// Σ_k `tr[τ_k]` of each lane (all RUNS lanes; the caller keeps the active ones).
    pub(super) sum: Vec<f64>,
    /// Flag-ACKs delivered to each lane's sensor, genuine or forged (only when recording; else
    /// empty).
    pub(super) delivered: Vec<u64>,
    /// Totals over the active lanes.
    pub(super) sent: u64,
    /// Flags blocked or flipped, over the active lanes.
    pub(super) blocked: u64,
    /// Flags forged, over the active lanes.
    pub(super) forged: u64,
    /// Active lanes with a flag (genuine or forged) reaching the sensor at the last step.
    pub(super) hi_last: u64,
}

/// Inputs of one block.
pub(super) struct BsBlock<'a> {
    /// The experiment's seed.
    pub(super) seed: u64,
    /// The block's index: its randomness is SplitMix64 sub-stream (seed, block).
    pub(super) block: u64,
    /// Lanes 0..active are runs; the rest are simulated but not counted.
    pub(super) active: usize,
    /// Whether to report each lane's delivered flag-ACKs.
    pub(super) record: bool,
    /// Per-step sums over the active lanes are added here (length = horizon).
    pub(super) acc: &'a mut [f64],
    /// The full trace table `tr[τ]`, τ = 0..=bound, for a deep plan's lanes beyond its top
    /// level (unused otherwise).
    pub(super) deep_tr: &'a [f64],
}

/// The portable kernel: every plan on the deepest thermometer and 64 counter planes; CH: on a
/// two-state Markov channel.
fn block_portable<
    const O: bool,
    const M: bool,
    const A: bool,
    const P: bool,
    const RB: bool,
    const FG: bool,
    const CH: bool,
>(
    p: &BsPlan,
    b: &mut BsBlock,
    cancel: &AtomicBool,
) -> Result<BsOut> {
    body::<O, M, A, P, RB, FG, CH, MAX_DEPTH, 64, Portable>(p, b, cancel, Portable)
}

/// The kernel on AVX2 registers with D thermometer levels and B counter planes. Compiled for
/// AVX2 and POPCNT, so calling it is `unsafe` except from such code; [`run_block`] calls it
/// with an [`Avx2`] token and after detecting POPCNT.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
fn block_avx2<
    const O: bool,
    const M: bool,
    const A: bool,
    const P: bool,
    const RB: bool,
    const FG: bool,
    const CH: bool,
    const D: usize,
    const B: usize,
>(
    avx2: Avx2,
    p: &BsPlan,
    b: &mut BsBlock,
    cancel: &AtomicBool,
) -> Result<BsOut> {
    body::<O, M, A, P, RB, FG, CH, D, B, Avx2>(p, b, cancel, avx2)
}

/// The AVX2 kernel for flags ($o, $m, $a, $pa, $rb, $fg), channel $ch and counter width $b,
/// specialised on the smallest thermometer size that holds `levels`; `$t` is the [`Avx2`] token.
#[cfg(target_arch = "x86_64")]
macro_rules! avx2_by_depth {
    ($o:expr, $m:expr, $a:expr, $pa:expr, $rb:expr, $fg:expr, $ch:expr, $b:literal, $levels:expr,
     $t:ident, $p:ident, $blk:ident, $c:ident) => {
        // SAFETY: `$t` is a token that only `Avx2::detect` makes, on a CPU with AVX2, and
        // `run_block` detected POPCNT before using it: the two features `block_avx2` is
        // compiled for.
        unsafe {
            match $levels {
                0..=2 => block_avx2::<$o, $m, $a, $pa, $rb, $fg, $ch, 2, $b>($t, $p, $blk, $c),
                3..=4 => block_avx2::<$o, $m, $a, $pa, $rb, $fg, $ch, 4, $b>($t, $p, $blk, $c),
                5..=8 => block_avx2::<$o, $m, $a, $pa, $rb, $fg, $ch, 8, $b>($t, $p, $blk, $c),
                9..=16 => block_avx2::<$o, $m, $a, $pa, $rb, $fg, $ch, 16, $b>($t, $p, $blk, $c),
                _ => block_avx2::<$o, $m, $a, $pa, $rb, $fg, $ch, 32, $b>($t, $p, $blk, $c),
            }
        }
    };
}

/// Runs one block with the kernel for `flags`, on AVX2 if given the token `avx2` and the CPU
/// also has POPCNT, else on the portable kernel (both give the same results).
pub(super) fn run_block(
    p: &BsPlan,
    flags: KernelFlags,
    avx2: Option<Avx2>,
    b: &mut BsBlock,
    cancel: &AtomicBool,
) -> Result<BsOut> {
    #[cfg(target_arch = "x86_64")]
    if let Some(avx2) = avx2.filter(|_| is_x86_feature_detected!("popcnt")) {
        let levels = p.levels(flags.mu_draw, flags.attack);
        // Counter planes: none without mask blocking, 4 for masks up to 15 long, else 64.
        let wide = p.counter_bits() > 4;
        // Only mask-blocking kernels have counter planes: monomorphise B = 4 and 64 for those
        // alone.
        macro_rules! sized {
            ($ch:tt; $o:tt, $m:tt, true, $pa:tt, false, $fg:tt) => {
                if wide {
                    avx2_by_depth!(
                        $o, $m, true, $pa, false, $fg, $ch, 64, levels, avx2, p, b, cancel
                    )
                } else {
                    avx2_by_depth!(
                        $o, $m, true, $pa, false, $fg, $ch, 4, levels, avx2, p, b, cancel
                    )
                }
            };
            ($ch:tt; $o:tt, $m:tt, $a:tt, $pa:tt, $rb:tt, $fg:tt) => {
                avx2_by_depth!($o, $m, $a, $pa, $rb, $fg, $ch, 1, levels, avx2, p, b, cancel)
            };
        }
        // The channel is a compile-time flag too, so the i.i.d. kernels are untouched by it.
        macro_rules! iid {
            ($($f:tt),*) => { sized!(false; $($f),*) };
        }
        macro_rules! markov {
            ($($f:tt),*) => { sized!(true; $($f),*) };
        }
        return if p.channel.is_some() {
            by_flags!(flags, markov)
        } else {
            by_flags!(flags, iid)
        };
    }
    let _ = avx2;
    macro_rules! portable {
        ($o:expr, $m:expr, $a:expr, $pa:expr, $rb:expr, $fg:expr) => {
            if p.channel.is_some() {
                block_portable::<$o, $m, $a, $pa, $rb, $fg, true>(p, b, cancel)
            } else {
                block_portable::<$o, $m, $a, $pa, $rb, $fg, false>(p, b, cancel)
            }
        };
    }
    by_flags!(flags, portable)
}

#[cfg(test)]
mod tests;
