//! The bit-sliced game kernel: the [`RUNS`] runs of a block are the bit lanes of four u64 words,
//! as in the plain Monte Carlo's bit-sliced kernel, with the sensor's modes and tests in the loop.
//!
//! Per run, as bit-planes:
//!
//! * τ as a thermometer of D levels (`therm[j]`: τ ≥ j + 1), D = 8, 16 or 32 (see
//!   [`Sliced::depth`]); the lanes with τ ≥ D keep their exact τ one by one (`DeepRuns`);
//! * the detector's zero count as a thermometer of D levels (D ≥ z0 + 1, the count's largest
//!   value), and the attacker's flag counter in binary planes (a blocking mask: "block" is the
//!   counter in one of the mask's runs of ones) or its β decisions drawn ahead (`BetaPool`);
//! * the mode: one word of online lanes; the offline lanes in classes by the step at which their
//!   offline stretch began modulo the pattern's period, so one class shares one power per step
//!   (a stretch starts at a window's end, so there are at most period / gcd(period, window));
//!   the lanes that went offline at each of the last `fallback` window ends, to bring them back;
//! * the gap since the last flag-ACK that reached the sensor as a thermometer up to the larger of
//!   the interval test's last edge and the support check's `min_gap` (none without either),
//!   which sorts each counted flag-ACK into its bin and finds the short gaps; for the support
//!   check, the lanes online since their last flag-ACK (whose next gap it checks) and those with
//!   a short gap in the current window.
//!
//! Per-lane counts (steps with τ ≥ j, high-power steps, flag-ACKs delivered, and the window's
//! count and bins) go through carry-save counters ([`LaneCounter`]), whose binary planes the
//! count test compares with its bounds in a few word operations. The interval test reads each
//! lane's bin counts and sums Pearson's X² lane by lane at the window's end.
//!
//! This module holds the plan form the kernel takes ([`Sliced`]) and its entry ([`run_block`]);
//! `body` holds a block's state and its step loop.
//!
//! [`LaneCounter`]: crate::montecarlo::bitslice::words::LaneCounter
//!
//! Draws per step, each only for the lanes that need it: λ (low-power lanes), μ (zero count
//! exactly z0), β (when some flag finds its lane without a decision), γ (lanes without a flag).
//! A draw with probability 1 hits every lane that needs it without drawing.

use std::ops::Range;
use std::sync::atomic::AtomicBool;

use crate::montecarlo::cpu::Avx2;

use super::plan::{Block, Plan};
use super::{Detector, Policy};
use crate::attack::Attack;
use crate::error::Result;
use crate::montecarlo::bitslice::mask_runs;
use crate::montecarlo::bitslice::words::{Portable, Rng4, StreamStepper, RUNS, W};
use crate::montecarlo::rng::bernoulli_threshold;

mod body;

use body::block_body;

/// Largest zero-count memory (z0 + 1) and thermometer the kernel takes.
const MAX_DEPTH: usize = 32;
/// Most bins, and largest last edge, of an interval test the kernel takes; largest `min_gap` of
/// its support check.
const MAX_GAP: usize = 64;
/// Most runs of ones in a blocking mask.
const MAX_MASK_RUNS: usize = 8;
/// The thermometer stops at the smallest depth whose chance of being reached on a step, at most
/// (1 - λ)^D, is below this.
const DEEP_TAIL: f64 = 1.0 / 4096.0;

/// A Bernoulli draw's threshold ⌊p 2^64⌋, or a sure hit.
#[derive(Debug, Clone, Copy)]
struct Draw {
    thr: u64,
    always: bool,
}

impl Draw {
    fn new(p: f64) -> Self {
        Draw {
            thr: bernoulli_threshold(p),
            always: p >= 1.0,
        }
    }

    /// The draw for the lanes of `need` (0 elsewhere).
    #[inline(always)]
    fn hits<S: StreamStepper>(self, rng: &mut Rng4, stepper: S, need: W) -> W {
        if self.always {
            need
        } else {
            rng.bernoulli(stepper, self.thr, need)
        }
    }
}

/// The attacker's rule for genuine flags.
#[derive(Debug, Clone)]
enum Blocking {
    None,
    /// Blocked iff the counter lies in one of `runs`; the counter counts flags modulo `len`.
    Mask {
        runs: Vec<Range<u64>>,
        len: u64,
        bits: usize,
    },
    /// Blocked with probability β, independently.
    Random(Draw),
}

/// A [`Plan`] in the form the bit-sliced kernel runs, when it fits.
pub(super) struct Sliced {
    lam: Draw,
    /// μ's draw (μ = 1, the fixed memory z0, draws nothing).
    mu: Draw,
    /// γ's draw (γ = 0, no forging, draws nothing).
    gamma: Draw,
    blocking: Blocking,
    z0: usize,
    /// The thermometers' size.
    depth: usize,
    /// `tr[τ]` for τ = 0..depth (zeros where the run is too short to get there).
    tr: Vec<f64>,
    /// The interval test's bin edges minus one (thermometer levels); empty without it.
    edges: Vec<usize>,
    /// The support check's shortest allowed gap, > 1; 0 without the check.
    min_gap: usize,
}

impl Sliced {
    /// Levels of the gap thermometer: up to the last bin's edge and to `min_gap`.
    fn gap_levels(&self) -> usize {
        self.edges.last().map_or(0, |&e| e + 1).max(self.min_gap)
    }
}

impl Sliced {
    /// The kernel's form of `plan`, or `None` when the plan does not fit it (a Markov channel, an
    /// attacker automaton, a memory deeper than 32 steps, an interval test with more than 64
    /// bins or a last edge beyond 64 steps, a support check with `min_gap` beyond 64, a blocking
    /// mask with more than 8 runs of ones).
    pub(super) fn of(plan: &Plan<'_>) -> Option<Self> {
        let cfg = plan.cfg;
        // A Markov channel, the CUSUM policy and the likelihood-ratio test run on the lane kernel.
        if cfg.channel.is_some() || matches!(cfg.policy, Policy::Cusum { .. }) || plan.likelihood()
        {
            return None;
        }
        let z0 = usize::try_from(cfg.design.z0).ok()?;
        if z0 + 1 > MAX_DEPTH {
            return None;
        }
        let depth = [8, 16, MAX_DEPTH]
            .into_iter()
            .find(|&d| d > z0 && (1.0 - cfg.lam).powi(d as i32) <= DEEP_TAIL)
            .unwrap_or(MAX_DEPTH);
        let blocking = match &plan.block {
            // An attacker automaton runs on the lane kernel.
            Block::Automaton { .. } => return None,
            Block::None => Blocking::None,
            // The same exact threshold ⌊β 2^64⌋, split in the lane kernel's form.
            Block::Random(b) => Blocking::Random(Draw {
                thr: (b.hi << 48) | b.lo,
                always: b.always,
            }),
            Block::FirstR { r, t } => Blocking::Mask {
                // r = 0 gives the empty run, which blocks nothing.
                runs: std::iter::once(0..*r).collect(),
                len: *t,
                bits: (64 - t.leading_zeros()) as usize,
            },
            Block::Mask(mask) => {
                let runs = mask_runs(mask);
                if runs.len() > MAX_MASK_RUNS {
                    return None;
                }
                let len = mask.len() as u64;
                Blocking::Mask {
                    runs,
                    len,
                    bits: (64 - len.leading_zeros()) as usize,
                }
            }
        };
        let edges = match &cfg.policy {
            Policy::Test {
                detector: Detector::Interval { edges, .. },
                ..
            } => {
                // The edges increase from 1, so this bounds the bins too.
                if *edges.last()? > MAX_GAP as u64 {
                    return None;
                }
                edges.iter().map(|&e| e as usize - 1).collect()
            }
            _ => Vec::new(),
        };
        // The check of an i.i.d. channel's attack-free minimum, z0 + 1 or z0 + 2, always fits.
        let min_gap = usize::try_from(plan.min_gap)
            .ok()
            .filter(|&g| g <= MAX_GAP)?;
        let gamma = cfg.attack.as_ref().map_or(0.0, Attack::forging);
        Some(Sliced {
            lam: Draw::new(cfg.lam),
            mu: Draw::new(cfg.design.mu),
            gamma: Draw::new(gamma),
            blocking,
            z0,
            depth,
            tr: (0..depth)
                .map(|j| plan.traces.get(j).copied().unwrap_or(0.0))
                .collect(),
            edges,
            min_gap,
        })
    }
}

/// One block's per-lane results (all [`RUNS`] lanes; the caller keeps the active ones).
pub(super) struct SlicedOut {
    /// Σ Tr P_k over the measured steps.
    pub(super) cost: Vec<f64>,
    pub(super) high: [u64; RUNS],
    pub(super) online_steps: [u64; RUNS],
    pub(super) delivered: [u64; RUNS],
    pub(super) tested: [u64; RUNS],
    pub(super) alarms: [u64; RUNS],
    pub(super) fallbacks: [u64; RUNS],
}

impl SlicedOut {
    /// No cost, every count zero.
    pub(super) const EMPTY: SlicedOut = SlicedOut {
        cost: Vec::new(),
        high: [0; RUNS],
        online_steps: [0; RUNS],
        delivered: [0; RUNS],
        tested: [0; RUNS],
        alarms: [0; RUNS],
        fallbacks: [0; RUNS],
    };
}

/// Runs block `block` of `plan` on AVX2 if given the token and the CPU has POPCNT, else
/// portably (both give the same results).
pub(super) fn run_block(
    s: &Sliced,
    plan: &Plan<'_>,
    block: u64,
    avx2: Option<Avx2>,
    cancel: &AtomicBool,
) -> Result<SlicedOut> {
    #[cfg(target_arch = "x86_64")]
    if let Some(avx2) = avx2.filter(|_| is_x86_feature_detected!("popcnt")) {
        // SAFETY: `avx2` is a token that only `Avx2::detect` makes, on a CPU with AVX2, and
        // POPCNT was detected above: the two features `block_avx2` is compiled for.
        return unsafe {
            match s.depth {
                8 => block_avx2::<8>(avx2, s, plan, block, cancel),
                16 => block_avx2::<16>(avx2, s, plan, block, cancel),
                _ => block_avx2::<MAX_DEPTH>(avx2, s, plan, block, cancel),
            }
        };
    }
    let _ = avx2;
    match s.depth {
        8 => block_body::<8, _>(s, plan, block, cancel, Portable),
        16 => block_body::<16, _>(s, plan, block, cancel, Portable),
        _ => block_body::<MAX_DEPTH, _>(s, plan, block, cancel, Portable),
    }
}

/// The kernel compiled for AVX2 and POPCNT: calling it is `unsafe` except from such code.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
fn block_avx2<const D: usize>(
    avx2: Avx2,
    s: &Sliced,
    plan: &Plan<'_>,
    block: u64,
    cancel: &AtomicBool,
) -> Result<SlicedOut> {
    block_body::<D, _>(s, plan, block, cancel, avx2)
}

#[cfg(test)]
mod tests;
