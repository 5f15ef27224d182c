//! The block driver: runs the plan's blocks in parallel waves, each on the kernel that fits it,
//! and folds their sums into the result ([`simulate`]).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use rayon::prelude::*;

use super::bitslice::{self, BsBlock, BsPlan};
use super::config::{McConfig, McResult};
use super::kernel::{cov_tile, detect_isa, Isa, Tile, TileOut};
use super::plan::Plan;
use super::state::state_tile;
use super::{BLOCK_RUNS, LANES};
use crate::error::{Error, Result};
use crate::montecarlo::rng::{SplitMix64, Xoshiro256pp};
use crate::system::LinearSystem;

/// Runs one tile with the kernel matching the plan (const-generic dispatch).
fn run_tile(plan: &Plan, isa: Isa, tile: &mut Tile, cancel: &AtomicBool) -> Result<TileOut> {
    let p = plan.params();
    macro_rules! go {
        ($o:expr, $m:expr, $a:expr, $pa:expr, $rb:expr, $fg:expr) => {
            match &plan.state {
                None => cov_tile::<$o, $m, $a, $pa, $rb, $fg>(isa, &p, &plan.tr, tile, cancel),
                Some(model) => {
                    state_tile::<$o, $m, $a, $pa, $rb, $fg>(isa, &p, model, tile, cancel)
                }
            }
        };
    }
    by_flags!(plan.flags(), go)
}

/// Count, mean and sum of squared deviations (Welford; Chan et al. to merge).
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    /// Count.
    n: u64,
    /// Mean.
    mean: f64,
    /// Sum of squared deviations from the mean.
    m2: f64,
    /// Whether a non-finite value was pushed (the standard error is then infinite).
    nonfinite: bool,
}

impl Moments {
    /// Adds one value.
    fn push(&mut self, x: f64) {
        if !x.is_finite() {
            self.nonfinite = true;
        }
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }

    /// Adds another set of values' moments.
    fn merge(&mut self, o: &Moments) {
        self.nonfinite |= o.nonfinite;
        if o.n == 0 {
            return;
        }
        if self.n == 0 {
            *self = *o;
            return;
        }
        let (n1, n2) = (self.n as f64, o.n as f64);
        let n = n1 + n2;
        let d = o.mean - self.mean;
        self.mean += d * (n2 / n);
        self.m2 += o.m2 + d * d * (n1 * n2 / n);
        self.n += o.n;
    }
}

/// What one block of runs reports.
struct BlockOut {
    /// Per-step sums over the block's runs.
    acc: Vec<f64>,
    /// The moments of the runs' time averages.
    moments: Moments,
    /// Flag-ACKs sent.
    sent: u128,
    /// Flag-ACKs blocked or flipped.
    blocked: u128,
    /// Flag-ACKs forged.
    forged: u128,
    /// High-power steps.
    high: u128,
    /// Runs in the block.
    runs: u64,
    /// Delivered flag-ACKs of each run of the block, in run order (empty unless recording).
    delivered: Vec<u64>,
}

/// Which kernels may run: the instruction set, and whether the bit-sliced covariance kernel may
/// take the plans that fit it (tests turn it off to exercise the lane kernels on every plan).
#[derive(Debug, Clone, Copy)]
pub(super) struct Kernels {
    /// The lane kernel, and the bit-sliced kernel's build (AVX2 if this holds its token).
    pub(super) isa: Isa,
    /// Whether the bit-sliced kernel takes the plans that fit it.
    pub(super) bitslice: bool,
}

/// One block on the bit-sliced kernel.
fn run_bitslice_block(
    plan: &Plan,
    bs: &BsPlan,
    isa: Isa,
    block: u64,
    cancel: &AtomicBool,
) -> Result<BlockOut> {
    let first = block * BLOCK_RUNS;
    let runs = BLOCK_RUNS.min(plan.runs - first);
    let mut acc = vec![0.0; plan.horizon];
    let res = bitslice::run_block(
        bs,
        plan.flags(),
        isa.avx2(),
        &mut BsBlock {
            seed: plan.seed,
            block,
            active: runs as usize,
            record: plan.record_runs,
            acc: &mut acc,
            deep_tr: &plan.tr,
        },
        cancel,
    )?;
    let mut moments = Moments::default();
    let horizon = plan.horizon as f64;
    for s in &res.sum[..runs as usize] {
        moments.push(s / horizon);
    }
    let high = if plan.online {
        // Δ at k = 1 and after every flag reaching the sensor (delivered or forged) except one
        // at the last step.
        u128::from(runs + res.sent - res.blocked + res.forged - res.hi_last)
    } else {
        u128::from(runs) * u128::from(plan.offline_high)
    };
    let mut delivered = res.delivered;
    delivered.truncate(runs as usize);
    Ok(BlockOut {
        acc,
        moments,
        sent: u128::from(res.sent),
        blocked: u128::from(res.blocked),
        forged: u128::from(res.forged),
        high,
        runs,
        delivered,
    })
}

/// One block on the kernel that fits the plan.
fn run_block(plan: &Plan, kernels: Kernels, block: u64, cancel: &AtomicBool) -> Result<BlockOut> {
    let isa = kernels.isa;
    if let (Some(bs), true) = (&plan.bitslice, kernels.bitslice) {
        return run_bitslice_block(plan, bs, isa, block, cancel);
    }
    if plan.markov {
        return Err(markov_unsupported());
    }
    let first = block * BLOCK_RUNS;
    let runs = BLOCK_RUNS.min(plan.runs - first);
    let mut acc = vec![0.0; plan.horizon];
    let mut stream = SplitMix64::stream(plan.seed, block);
    let mut out = BlockOut {
        acc: Vec::new(),
        moments: Moments::default(),
        sent: 0,
        blocked: 0,
        forged: 0,
        high: 0,
        runs,
        delivered: if plan.record_runs {
            Vec::with_capacity(runs as usize)
        } else {
            Vec::new()
        },
    };
    let horizon = plan.horizon as f64;
    let tiles = runs.div_ceil(LANES as u64);
    for t in 0..tiles {
        let active_lanes = (runs - t * LANES as u64).min(LANES as u64) as usize;
        let mut seeds = [[0u64; 4]; LANES];
        let mut side = [Xoshiro256pp::seed_from_u64(0); LANES];
        let mut noise = [Xoshiro256pp::seed_from_u64(0); LANES];
        for l in 0..LANES {
            // Every run owns a SplitMix64 seeded from the block stream: protocol, tie and noise
            // streams, in that order (so both modes see the same protocol randomness).
            let mut run = SplitMix64::new(stream.next_u64());
            seeds[l] = Xoshiro256pp::from_splitmix(&mut run).state();
            side[l] = Xoshiro256pp::from_splitmix(&mut run);
            noise[l] = Xoshiro256pp::from_splitmix(&mut run);
        }
        let mut active = [0u64; LANES];
        for a in active.iter_mut().take(active_lanes) {
            *a = u64::MAX;
        }
        let mut tile = Tile {
            seeds,
            side,
            noise,
            active,
            acc: &mut acc,
        };
        let res = run_tile(plan, isa, &mut tile, cancel)?;
        for l in 0..active_lanes {
            out.moments.push(res.sum[l] / horizon);
            out.sent += u128::from(res.sent[l]);
            out.blocked += u128::from(res.blocked[l]);
            out.forged += u128::from(res.forged[l]);
            // Flags reaching the sensor: delivered genuine ones and forged ones.
            let reached = res.sent[l] - res.blocked[l] + res.forged[l];
            out.high += if plan.online {
                // Δ at k = 1 and after every flag reaching the sensor except one at the last
                // step.
                u128::from(1 + reached - res.hi_last[l])
            } else {
                u128::from(plan.offline_high)
            };
            if plan.record_runs {
                out.delivered.push(reached);
            }
        }
    }
    out.acc = acc;
    Ok(out)
}

/// The error for a Markov channel on a plan the bit-sliced kernel does not take.
fn markov_unsupported() -> Error {
    Error::invalid(
        "channel",
        "a Markov channel is simulated by the bit-sliced kernel only, and this plan is outside \
         its limits (holding-time bound or memory over 32, or over four runs of ones in the mask)",
    )
}

/// [`simulate`], or `Ok(None)` (nothing run) when `cfg` has a Markov channel
/// ([`McConfig::channel`]) and a plan outside the limits of the bit-sliced kernel, the only one
/// that simulates such a channel: a holding-time bound or a memory over 32 (except under
/// independent blocking or forging, whose rare deep runs are tracked one by one), or a mask
/// with over four runs of ones. Errors as [`simulate`] otherwise.
pub fn simulate_if_supported(
    sys: &LinearSystem,
    cfg: &McConfig,
    cancel: &AtomicBool,
    progress: &AtomicU64,
) -> Result<Option<McResult>> {
    let plan = Plan::new(sys, cfg)?;
    if plan.markov && plan.bitslice.is_none() {
        return Ok(None);
    }
    let kernels = Kernels {
        isa: detect_isa(),
        bitslice: true,
    };
    run_plan(&plan, cancel, progress, kernels).map(Some)
}

/// Neumaier-compensated running means J_k.
fn running_means(x: &[f64]) -> Vec<f64> {
    let (mut s, mut c) = (0.0f64, 0.0f64);
    x.iter()
        .enumerate()
        .map(|(k, &v)| {
            let t = s + v;
            if s.abs() >= v.abs() {
                c += (s - t) + v;
            } else {
                c += (v - t) + s;
            }
            s = t;
            let total = s + c;
            (if total.is_nan() { s } else { total }) / (k + 1) as f64
        })
        .collect()
}

/// Runs the Monte Carlo. Deterministic in `cfg.seed` (independent of the thread count); checks
/// `cancel` between blocks and every 2^16 steps of a tile (10^6 run-steps), returning
/// [`Error::Interrupted`] once it is set; adds completed runs to `progress` as blocks finish.
pub fn simulate(
    sys: &LinearSystem,
    cfg: &McConfig,
    cancel: &AtomicBool,
    progress: &AtomicU64,
) -> Result<McResult> {
    let kernels = Kernels {
        isa: detect_isa(),
        bitslice: true,
    };
    simulate_with(sys, cfg, cancel, progress, kernels)
}

/// The sums over the blocks folded so far; blocks are folded in block order, so the results
/// do not depend on which thread ran which block.
struct Totals {
    /// Per-step sums over the runs.
    trace: Vec<f64>,
    /// The moments of the runs' time averages.
    moments: Moments,
    /// Flag-ACKs sent.
    sent: u128,
    /// Flag-ACKs blocked or flipped.
    blocked: u128,
    /// Flag-ACKs forged.
    forged: u128,
    /// High-power steps.
    high: u128,
    /// Delivered flag-ACKs per run, in run order (recording only; at most 2^28 runs, checked).
    delivered: Vec<u64>,
}

impl Totals {
    /// Nothing folded yet.
    fn new(plan: &Plan) -> Self {
        Totals {
            trace: vec![0.0f64; plan.horizon],
            moments: Moments::default(),
            sent: 0,
            blocked: 0,
            forged: 0,
            high: 0,
            delivered: if plan.record_runs {
                Vec::with_capacity(plan.runs as usize)
            } else {
                Vec::new()
            },
        }
    }

    /// Folds in the next block.
    fn add(&mut self, out: &BlockOut) {
        for (t, a) in self.trace.iter_mut().zip(&out.acc) {
            *t += a;
        }
        self.moments.merge(&out.moments);
        self.sent += out.sent;
        self.blocked += out.blocked;
        self.forged += out.forged;
        self.high += out.high;
        self.delivered.extend_from_slice(&out.delivered);
    }

    /// The averages over all of `plan`'s runs.
    fn result(self, plan: &Plan) -> McResult {
        let runs = plan.runs as f64;
        let mean_trace: Vec<f64> = self.trace.iter().map(|t| t / runs).collect();
        let j_k = running_means(&mean_trace);
        let j = j_k.last().copied().unwrap_or(f64::NAN);
        let m = &self.moments;
        let stderr = if m.n < 2 || m.nonfinite || !j.is_finite() {
            f64::INFINITY
        } else {
            let var = (m.m2 / (m.n - 1) as f64).max(0.0);
            (var / runs).sqrt()
        };
        let steps = runs * plan.horizon as f64;
        McResult {
            mean_trace,
            j_k,
            j,
            stderr,
            high_power_rate: self.high as f64 / steps,
            flags_sent: self.sent as f64 / steps,
            flags_blocked: self.blocked as f64 / steps,
            flags_forged: self.forged as f64 / steps,
            runs: plan.runs,
            steps: plan.horizon as u64,
            delivered_per_run: self.delivered,
        }
    }
}

/// [`simulate`] on the given kernels (tests pick them).
pub(super) fn simulate_with(
    sys: &LinearSystem,
    cfg: &McConfig,
    cancel: &AtomicBool,
    progress: &AtomicU64,
    kernels: Kernels,
) -> Result<McResult> {
    let plan = Plan::new(sys, cfg)?;
    if plan.markov && !(kernels.bitslice && plan.bitslice.is_some()) {
        return Err(markov_unsupported());
    }
    run_plan(&plan, cancel, progress, kernels)
}

/// Runs the blocks of a validated plan on `kernels`.
fn run_plan(
    plan: &Plan,
    cancel: &AtomicBool,
    progress: &AtomicU64,
    kernels: Kernels,
) -> Result<McResult> {
    if cancel.load(Ordering::Relaxed) {
        return Err(Error::Interrupted);
    }
    let blocks = plan.runs.div_ceil(BLOCK_RUNS);
    let threads = rayon::current_num_threads().max(1) as u64;
    // Blocks in flight per wave: as many as their per-step buffers allow in 64 MiB (fewer
    // waits at the end of a wave for short horizons), at most 64 per thread and never fewer
    // than one per thread (each buffer at most 1 GiB).
    let buffer_bytes = plan.horizon as u64 * 8;
    let wave = ((64u64 << 20) / buffer_bytes.max(1)).clamp(threads, 64 * threads);
    let mut totals = Totals::new(plan);
    let mut start = 0u64;
    while start < blocks {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        let end = blocks.min(start + wave);
        let outs: Vec<Result<BlockOut>> = (start..end)
            .into_par_iter()
            .map(|b| {
                let out = run_block(plan, kernels, b, cancel)?;
                progress.fetch_add(out.runs, Ordering::Relaxed);
                Ok(out)
            })
            .collect();
        for out in outs {
            totals.add(&out?);
        }
        start = end;
    }
    Ok(totals.result(plan))
}

#[cfg(test)]
mod tests {
    use super::{running_means, Moments};

    fn pushed(xs: &[f64]) -> Moments {
        let mut m = Moments::default();
        for &x in xs {
            m.push(x);
        }
        m
    }

    /// Merging the moments of two parts gives those of the whole (Chan et al.'s pairwise
    /// update), checked against the two-pass mean and squared deviations of the whole, for every
    /// split, empty parts included; a non-finite value in either part marks the merge (kills
    /// every wrong operator of `Moments::merge`).
    #[test]
    fn merged_moments_are_those_of_the_whole() {
        let xs: Vec<f64> = (0..23)
            .map(|i| 1.5 + ((i * 37 % 11) as f64).sqrt() * 0.7)
            .collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let m2: f64 = xs.iter().map(|x| (x - mean) * (x - mean)).sum();
        for split in 0..=xs.len() {
            let mut m = pushed(&xs[..split]);
            m.merge(&pushed(&xs[split..]));
            assert_eq!(m.n, xs.len() as u64);
            assert!((m.mean - mean).abs() < 1e-14 * mean, "{split}: {}", m.mean);
            assert!((m.m2 - m2).abs() < 1e-12 * m2, "{split}: {} vs {m2}", m.m2);
            assert!(!m.nonfinite);
        }
        for (a, b) in [
            (vec![1.0, f64::INFINITY], vec![2.0]),
            (vec![2.0], vec![f64::NAN]),
        ] {
            let mut m = pushed(&a);
            m.merge(&pushed(&b));
            assert!(m.nonfinite);
        }
        let mut m = pushed(&[3.0]);
        m.merge(&Moments {
            nonfinite: true,
            ..Moments::default()
        });
        assert!(m.nonfinite && m.n == 1);
    }

    /// The running means are compensated: 1, 1e100, 1, -1e100 sums to 2 exactly (a plain sum
    /// gives 0), whichever term is the larger at each step; an infinite term gives +inf, not
    /// inf - inf = NaN (kills the compensation's `+=` and `+` turned `-=`, `*=`, `-` or `*`).
    #[test]
    fn running_means_are_compensated() {
        let j = running_means(&[1.0, 1e100, 1.0, -1e100, 2.0]);
        assert_eq!(j[0], 1.0);
        assert_eq!(j[1], 1e100 / 2.0);
        assert_eq!(j[3], 0.5);
        assert_eq!(j[4], 4.0 / 5.0);
        let j = running_means(&[1.0, f64::INFINITY, 1.0]);
        assert_eq!(j, [1.0, f64::INFINITY, f64::INFINITY]);
    }
}
