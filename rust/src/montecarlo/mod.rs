//! Monte Carlo of the real protocol (not of the Markov chain of Sec. IV-B).
//!
//! Each run plays steps k = 1..=horizon of the sensor, the lossy channel, the remote estimator,
//! the event detector and the attacker:
//!
//! * the sensor uses high power Δ (the packet always arrives) or low power δ (it arrives with
//!   probability λ). Offline: `pattern[(k-1) % len]`. Online: Δ at step k iff a flag-ACK was
//!   delivered to the sensor at step k-1;
//! * the remote covariance is P̄ on arrival and h(P_{k-1}) otherwise, so Tr P_k = `tr[τ_k]` with τ_k
//!   the holding time since the last arrival;
//! * the event detector (online) counts the consecutive zero ACKs since the last reset or arrival.
//!   Each step it uses a z0-bit memory with probability μ, else z0+1 bits; when the last L bits are
//!   all zero it sends a flag-ACK and resets the memory to all ones;
//! * the attacker keeps a counter over flag-ACKs and blocks a flag iff `mask[counter]`, then
//!   advances the counter modulo the mask length. A blocked flag still resets the detector's
//!   memory, but the sensor does not learn of it and stays on δ.
//!
//! Initial condition (the paper's): at k = 1 the sensor uses Δ (the packet arrives, τ = 0), the
//! memory is all ones and the attacker's counter is 0.
//!
//! Two channel protocols carry the flag-ACK, as two separate code paths with identical
//! statistics: in [`Protocol::B`] a flag packet exists only when a flag is due and the attacker
//! drops it (DoS); in [`Protocol::A`] the detector sends one bit every step (1 = flag) and the
//! attacker flips 1-bits to 0 (integrity attack).
//!
//! Two fidelities: [`Mode::Covariance`] tracks τ and accumulates `tr[τ]`; [`Mode::State`] simulates
//! the estimation errors with Gaussian noise (see [`Mode::State`]).
//!
//! # Engineering
//!
//! Runs are split into fixed blocks of [`BLOCK_RUNS`]; block b draws all its randomness from
//! SplitMix64 sub-stream (seed, b) and blocks are combined in block order, so results depend only
//! on the seed, never on the number of threads or on the CPU's vector instructions. Blocks run in
//! parallel (rayon) in waves whose per-step sums are folded into the totals as each wave ends, so
//! memory does not grow with `runs` (except for the optional per-run record
//! [`McResult::delivered_per_run`], 8 bytes per run).
//!
//! Two kernel families simulate a block. In covariance mode, plans with a holding-time bound
//! ≤ 32, a memory ≤ 32 under attack and a mask with at most four runs of ones go to the
//! bit-sliced kernel (`bitslice`): the block's 256 runs are the bit lanes of four words, about
//! ten times faster. Every other plan, and state mode, uses the lane kernels below. Each family
//! is deterministic in the seed and independent of threads and CPU features; the two consume
//! randomness differently, so one seed gives different, equally distributed samples on each
//! (tests check both against the exact values).
//!
//! In the lane kernels, tiles of [`LANES`] runs advance in lock-step (structure of arrays). In
//! covariance mode the tile is processed as four groups of four lanes, each running a sub-chunk
//! of steps with its whole state in registers: one kernel body (`group_body!`) instantiated on
//! plain arrays (any target) and on AVX2 registers (x86-64, picked at run time). Tables of up to
//! 8 traces are read with in-register permutes instead of gathers. Every kernel performs the same
//! integer logic and the same f64 additions in the same order, so all give bit-identical results
//! (the tests compare them with the plain 16-lane reference kernel, `Proto::step`). State mode
//! runs the protocol on the same grouped kernels, a sub-chunk ahead, and reads the arrivals off
//! their rows, so both modes see the same protocol randomness.
//!
//! Bernoulli draws use 16-bit slices of 64-bit xoshiro256++ outputs (four draws per output),
//! compared with the top 16 bits of the exact threshold T = ⌊p 2^64⌋; a tie (probability 2^-16)
//! is resolved with 48 further bits from a per-run side stream, so every draw is exactly
//! Bernoulli(T / 2^64), within 2^-64 of p.
//!
//! The holding time never exceeds the plan's bound (the largest reachable τ, or the horizon):
//! τ resets at every arrival, a delivered flag-ACK forces an arrival at the next step, and at most
//! (longest run of blocked flags) flags in a row are blocked. Table lookups clamp their index to
//! the bound anyway, so the tables are never read out of range.
//!
//! # Layout
//!
//! This file holds the public types, validation, the `Plan` and the block driver; `bitslice`
//! the bit-sliced covariance kernel (its word operations in `bitslice/words.rs`); `kernel` the
//! lock-step protocol and the covariance kernels (with the four-lane operation sets in
//! `kernel/lanes4.rs` and `kernel/lanes4_avx2.rs`); `state` the state-mode model and kernel;
//! `tests` the unit tests (`tests/perf.rs`: the ignored throughput and memory checks).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::online::{check_lam, OnlineDesign};
use crate::rng::{bernoulli_threshold, SplitMix64, Xoshiro256pp};
use crate::system::LinearSystem;

/// Calls `$go!(ONLINE, MU_DRAW, ATTACK, PROTO_A)` with the const-generic kernel flags matching
/// the run-time tuple `$flags` (an offline plan has no detector, an unattacked one no channel).
macro_rules! by_flags {
    ($flags:expr, $go:ident) => {
        match $flags {
            (false, _, _, _) => $go!(false, false, false, false),
            (true, false, false, _) => $go!(true, false, false, false),
            (true, true, false, _) => $go!(true, true, false, false),
            (true, false, true, false) => $go!(true, false, true, false),
            (true, false, true, true) => $go!(true, false, true, true),
            (true, true, true, false) => $go!(true, true, true, false),
            (true, true, true, true) => $go!(true, true, true, true),
        }
    };
}

mod bitslice;
mod kernel;
mod state;
#[cfg(test)]
mod tests;

use bitslice::{BsBlock, BsPlan};
use kernel::{cov_tile, detect_isa, Isa, Params, Tile, TileOut};
use state::{state_tile_impl, StateModel};

/// Runs simulated in lock-step by one kernel call (the vector width of the kernels).
pub const LANES: usize = 16;
// `lane_sum` is a 16-lane tree and the grouped kernels take four lanes at a time.
const _: () = assert!(LANES == 16);
/// Runs per block; block b is seeded from (seed, b) alone.
pub const BLOCK_RUNS: u64 = 256;
// The bit-sliced kernel simulates exactly one block per call.
const _: () = assert!(BLOCK_RUNS as usize == bitslice::RUNS);
/// Largest horizon: one f64 per step and per in-flight block, at most 1 GiB per buffer.
pub const MAX_HORIZON: usize = 1 << 27;
/// Most runs whose delivered flag-ACKs can be recorded ([`McConfig::record_runs`]): 2 GiB.
const MAX_RECORDED_RUNS: u64 = 1 << 28;
/// Steps of one lock-step tile between two checks of the cancel flag (LANES × this many run-steps).
const CHUNK_STEPS: usize = 1 << 16;
/// Bits of a 64-bit random word used per Bernoulli draw.
const SLICE_BITS: u32 = 16;
const SLICES_PER_WORD: u32 = 64 / SLICE_BITS;
const SLICE_MASK: u64 = (1 << SLICE_BITS) - 1;

/// The sensor's power schedule.
#[derive(Debug, Clone, PartialEq)]
pub enum McSchedule {
    /// A 0/1 pattern (1 = high power Δ) repeated periodically; `pattern[0]` must be 1.
    Offline { pattern: Vec<u8> },
    /// The ACK-based online schedule: z0-bit memory with probability `mu`, else z0+1 bits.
    Online { z0: u64, mu: f64 },
}

/// What each run tracks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// τ_k only; accumulates Tr P_k = `tr[τ_k]` = Tr h^τ_k(P̄).
    Covariance,
    /// The estimation errors themselves, with real Gaussian noise. The sensor's steady-state
    /// Kalman filter (gain K = P⁻C'(CP⁻C'+R)^{-1}, P⁻ = AP̄A'+Q) has error
    /// e^s_k = (I-KC)(A e^s_{k-1} + w_{k-1}) - K v_k, started stationary e^s_0 ~ N(0, P̄); the
    /// remote error is e_k = e^s_k on arrival, else A e_{k-1} + w_{k-1} (the same w draw).
    /// Accumulates ||e_k||², whose mean is `Tr E[P_k]`.
    ///
    /// Simulating the errors rather than the state x_k keeps an unstable A from overflowing: x_k
    /// grows like ρ(A)^k over the whole horizon (1.2^k overflows f64 after ~3900 steps), while
    /// e_k only grows during a run of losses and restarts from e^s_k at every arrival. An error
    /// that does overflow (an astronomically long loss run) is reported as +inf, never NaN.
    State,
}

/// How the flag-ACK travels from the detector to the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// One bit every step (1 = flag); the attacker flips 1-bits to 0 (integrity attack).
    A,
    /// A flag packet only when a flag is due; the attacker drops it (DoS).
    B,
}

/// One Monte Carlo experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct McConfig {
    /// Low-power arrival probability λ, in (0, 1).
    pub lam: f64,
    /// The sensor's power schedule.
    pub schedule: McSchedule,
    /// Periodic blocking mask over the attacker's flag counter (online schedule only); "block the
    /// first r of every t" is `[true; r] ++ [false; t-r]`. `None`: no attacker.
    pub attack: Option<Vec<bool>>,
    /// Covariance (τ only) or state (Gaussian errors) fidelity.
    pub mode: Mode,
    /// How the flag-ACK travels (A and B give identical results for the same seed).
    pub protocol: Protocol,
    /// Steps per run, 1..=[`MAX_HORIZON`].
    pub horizon: usize,
    /// Number of independent runs, >= 1.
    pub runs: u64,
    /// The results depend on this seed only (not on threads or CPU features).
    pub seed: u64,
    /// Record each run's number of delivered flag-ACKs in [`McResult::delivered_per_run`]
    /// (8 bytes per run, at most 2^28 runs). `false`: nothing extra is kept.
    pub record_runs: bool,
}

/// Averages over the runs.
#[derive(Debug, Clone, PartialEq)]
pub struct McResult {
    /// Length `horizon`: average over runs of Tr P_k (covariance) or ||e_k||² (state), k = 1..
    pub mean_trace: Vec<f64>,
    /// J_k = (1/k) Σ_{i<=k} `mean_trace[i]` (a compensated running sum).
    pub j_k: Vec<f64>,
    /// `j_k[horizon-1]`, the mean over runs of each run's time average.
    pub j: f64,
    /// Standard error of `j`: sample standard deviation of the per-run time averages over
    /// sqrt(runs). `+inf` with a single run (no spread can be estimated) or when some run's
    /// average is infinite; never NaN.
    pub stderr: f64,
    /// Fraction of steps at high power Δ.
    pub high_power_rate: f64,
    /// Flag-ACKs sent by the detector, per step.
    pub flags_sent: f64,
    /// Flag-ACKs blocked (protocol B) or flipped (protocol A) by the attacker, per step.
    pub flags_blocked: f64,
    /// Number of runs.
    pub runs: u64,
    /// Steps per run (= horizon).
    pub steps: u64,
    /// Only with [`McConfig::record_runs`] (else empty, never allocated): entry i is the number
    /// of flag-ACKs delivered to the sensor during run i over steps 1..=horizon, that is sent by
    /// the detector and neither blocked (protocol B) nor flipped (protocol A); a flag delivered
    /// at the last step counts, and the initial high-power step at k = 1 is not a flag. Runs are
    /// in run order: run i is position i % [`BLOCK_RUNS`] of block i / [`BLOCK_RUNS`], so the
    /// entries depend on the seed only (not on threads or kernels), and a run's entry does not
    /// depend on how many runs follow it. All zeros for an offline schedule (no flags). Its mean
    /// over runs, divided by the horizon, is `flags_sent - flags_blocked`.
    ///
    /// Memory: the one output that grows with `runs`, 8 bytes per run (2 GiB at the limit of
    /// 2^28 runs; more is refused with [`Error::TooLarge`]).
    pub delivered_per_run: Vec<u64>,
}

// ---------------------------------------------------------------------------------------------
// Validation and planning.

/// Longest run of `true` in the cyclic sequence (`len` if all are true).
fn longest_cyclic_run(v: &[bool]) -> usize {
    if v.iter().all(|&x| x) {
        return v.len();
    }
    // Start right after a false so no run wraps around.
    let start = v.iter().position(|&x| !x).unwrap_or(0) + 1;
    let (mut best, mut cur) = (0, 0);
    for i in 0..v.len() {
        if v[(start + i) % v.len()] {
            cur += 1;
            best = best.max(cur);
        } else {
            cur = 0;
        }
    }
    best
}

/// The largest holding time τ a run can reach (before capping by the horizon); `None` if
/// unbounded (every flag blocked).
fn max_tau(schedule: &McSchedule, attack: Option<&[bool]>) -> Option<u64> {
    match schedule {
        McSchedule::Offline { pattern } => {
            let zeros: Vec<bool> = pattern.iter().map(|&g| g == 0).collect();
            Some(longest_cyclic_run(&zeros) as u64)
        }
        McSchedule::Online { z0, mu } => {
            let memory = if *mu < 1.0 { z0.saturating_add(1) } else { *z0 };
            let blocked_in_a_row = match attack {
                None => 0,
                Some(mask) if mask.iter().all(|&b| b) => return None,
                Some(mask) => longest_cyclic_run(mask) as u64,
            };
            Some(memory.saturating_mul(blocked_in_a_row + 1))
        }
    }
}

/// The validated, precomputed experiment shared by all blocks.
struct Plan {
    horizon: usize,
    runs: u64,
    seed: u64,
    /// Keep each run's delivered flag-ACK count ([`McConfig::record_runs`]).
    record_runs: bool,
    lam_thr: u64,
    online: bool,
    mu_draw: bool,
    mu_thr: u64,
    z0: u64,
    /// Memory length when there is no draw: z0 for μ = 1, z0+1 for μ = 0.
    l_fixed: u64,
    pattern: Vec<u8>,
    /// Ones among the first `horizon` steps of the offline pattern.
    offline_high: u64,
    mask: Option<Vec<u64>>,
    mask_len: u64,
    protocol: Protocol,
    /// Largest reachable τ, capped by the horizon.
    bound: u64,
    /// tr[τ] = Tr h^τ(P̄), τ = 0..=bound (covariance mode; empty in state mode).
    tr: Vec<f64>,
    state: Option<StateModel>,
    /// The bit-sliced covariance kernel's plan, when the plan fits it (shallow τ bound, short
    /// memory, few runs of ones in the mask); else the lane kernels run.
    bitslice: Option<BsPlan>,
}

impl Plan {
    fn new(sys: &LinearSystem, cfg: &McConfig) -> Result<Self> {
        check_lam(cfg.lam)?;
        if cfg.horizon == 0 {
            return Err(Error::invalid("horizon", "must be at least 1"));
        }
        if cfg.horizon > MAX_HORIZON {
            return Err(Error::TooLarge {
                arg: "horizon".into(),
                requested: cfg.horizon as u128,
                limit: MAX_HORIZON as u128,
            });
        }
        if cfg.runs == 0 {
            return Err(Error::invalid("runs", "must be at least 1"));
        }
        if cfg.record_runs && cfg.runs > MAX_RECORDED_RUNS {
            return Err(Error::TooLarge {
                arg: "runs".into(),
                requested: u128::from(cfg.runs),
                limit: u128::from(MAX_RECORDED_RUNS),
            });
        }
        let mut plan = Plan {
            horizon: cfg.horizon,
            runs: cfg.runs,
            seed: cfg.seed,
            record_runs: cfg.record_runs,
            lam_thr: bernoulli_threshold(cfg.lam),
            online: false,
            mu_draw: false,
            mu_thr: 0,
            z0: 0,
            l_fixed: 0,
            pattern: Vec::new(),
            offline_high: 0,
            mask: None,
            mask_len: 1,
            protocol: cfg.protocol,
            bound: 0,
            tr: Vec::new(),
            state: None,
            bitslice: None,
        };
        match &cfg.schedule {
            McSchedule::Offline { pattern } => {
                if pattern.is_empty() {
                    return Err(Error::invalid("pattern", "must not be empty"));
                }
                if let Some(g) = pattern.iter().find(|&&g| g > 1) {
                    return Err(Error::invalid(
                        "pattern",
                        format!("entries must be 0 or 1, found {g}"),
                    ));
                }
                if pattern[0] != 1 {
                    return Err(Error::invalid(
                        "pattern",
                        "must start with 1 (the sensor uses high power at k = 1)",
                    ));
                }
                if cfg.attack.is_some() {
                    return Err(Error::invalid(
                        "attack",
                        "applies to the online schedule only (the offline schedule sends no flag-ACK)",
                    ));
                }
                let len = pattern.len();
                let ones: u64 = pattern.iter().map(|&g| u64::from(g)).sum();
                let (full, rest) = (cfg.horizon / len, cfg.horizon % len);
                let head: u64 = pattern[..rest].iter().map(|&g| u64::from(g)).sum();
                plan.offline_high = full as u64 * ones + head;
                plan.pattern = pattern.clone();
            }
            McSchedule::Online { z0, mu } => {
                OnlineDesign::new(*z0, *mu)?;
                plan.online = true;
                plan.z0 = *z0;
                // μ = 1 and μ = 0 are deterministic memory lengths: no draw.
                plan.mu_draw = *mu > 0.0 && *mu < 1.0;
                plan.mu_thr = bernoulli_threshold(*mu);
                plan.l_fixed = if *mu >= 1.0 {
                    *z0
                } else {
                    z0.saturating_add(1)
                };
                if let Some(mask) = &cfg.attack {
                    if mask.is_empty() {
                        return Err(Error::invalid(
                            "attack",
                            "the blocking mask must not be empty",
                        ));
                    }
                    let mut words = vec![0u64; mask.len().div_ceil(64)];
                    for (i, &b) in mask.iter().enumerate() {
                        words[i / 64] |= u64::from(b) << (i % 64);
                    }
                    plan.mask = Some(words);
                    plan.mask_len = mask.len() as u64;
                }
            }
        }
        let reach = max_tau(&cfg.schedule, cfg.attack.as_deref()).unwrap_or(u64::MAX);
        plan.bound = reach.min(cfg.horizon as u64);
        match cfg.mode {
            Mode::Covariance => {
                plan.tr = sys.h_traces(plan.bound as usize);
                if plan.tr.len() != plan.bound as usize + 1 || plan.tr.iter().any(|t| t.is_nan()) {
                    return Err(Error::invalid("sys", "Tr h^i(P̄) is not a number"));
                }
            }
            Mode::State => plan.state = Some(StateModel::new(sys)?),
        }
        plan.bitslice = plan.bitslice_plan(cfg.attack.as_deref());
        Ok(plan)
    }

    /// The bit-sliced kernel's plan if this experiment fits it.
    fn bitslice_plan(&self, attack: Option<&[bool]>) -> Option<BsPlan> {
        let depth = self.bound as usize;
        let memory = if self.mu_draw {
            self.z0.saturating_add(1)
        } else {
            self.l_fixed
        };
        let mask_runs = attack.map(bitslice::mask_runs).unwrap_or_default();
        let fits = self.state.is_none()
            && depth <= bitslice::MAX_DEPTH
            && (attack.is_none() || memory <= bitslice::MAX_DEPTH as u64)
            && mask_runs.len() <= bitslice::MAX_MASK_RUNS;
        fits.then(|| BsPlan {
            lam_thr: self.lam_thr,
            mu_thr: self.mu_thr,
            // Memory lengths beyond the depth never trigger (τ <= depth); clamp them.
            z0: self.z0.min(depth as u64 + 1) as usize,
            l_fixed: self.l_fixed.min(depth as u64 + 1) as usize,
            pattern: self.pattern.clone(),
            mask_runs,
            mask_len: self.mask_len,
            tr: self.tr.clone(),
        })
    }

    /// The kernels' const-generic flags: (online, μ draw, attack, protocol A).
    fn flags(&self) -> (bool, bool, bool, bool) {
        (
            self.online,
            self.mu_draw,
            self.mask.is_some(),
            self.protocol == Protocol::A,
        )
    }

    fn params(&self) -> Params<'_> {
        let low = 64 - SLICE_BITS;
        let cap = self.horizon as u64 + 1;
        Params {
            lam_hi: self.lam_thr >> low,
            lam_lo: self.lam_thr & ((1u64 << low) - 1),
            mu_hi: self.mu_thr >> low,
            mu_lo: self.mu_thr & ((1u64 << low) - 1),
            // Zero counts never exceed the horizon, so memory lengths beyond it are all alike;
            // the clamp keeps every lane value below 2^63 (signed vector compares are exact).
            z0: self.z0.min(cap),
            z0p1: self.z0.min(cap) + 1,
            l_fixed: self.l_fixed.min(cap),
            mask: self.mask.as_deref().unwrap_or(&[0]),
            mask_len: self.mask_len,
            pattern: if self.pattern.is_empty() {
                &[1]
            } else {
                &self.pattern
            },
            last: self.bound,
        }
    }
}

/// Runs one tile with the kernel matching the plan (const-generic dispatch).
fn run_tile(plan: &Plan, isa: Isa, tile: &mut Tile, cancel: &AtomicBool) -> Result<TileOut> {
    let p = plan.params();
    macro_rules! go {
        ($o:expr, $m:expr, $a:expr, $pa:expr) => {
            match &plan.state {
                None => cov_tile::<$o, $m, $a, $pa>(isa, &p, &plan.tr, tile, cancel),
                Some(model) => state_tile_impl::<$o, $m, $a, $pa>(isa, &p, model, tile, cancel),
            }
        };
    }
    by_flags!(plan.flags(), go)
}

// ---------------------------------------------------------------------------------------------
// Blocks, statistics and the driver.

/// Count, mean and sum of squared deviations (Welford; Chan et al. to merge).
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    n: u64,
    mean: f64,
    m2: f64,
    nonfinite: bool,
}

impl Moments {
    fn push(&mut self, x: f64) {
        if !x.is_finite() {
            self.nonfinite = true;
        }
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }

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

struct BlockOut {
    acc: Vec<f64>,
    moments: Moments,
    sent: u128,
    blocked: u128,
    high: u128,
    runs: u64,
    /// Delivered flag-ACKs of each run of the block, in run order (empty unless recording).
    delivered: Vec<u64>,
}

/// Which kernels may run: the instruction set, and whether the bit-sliced covariance kernel may
/// take the plans that fit it (tests turn it off to exercise the lane kernels on every plan).
#[derive(Debug, Clone, Copy)]
struct Kernels {
    isa: Isa,
    bitslice: bool,
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
    #[cfg(target_arch = "x86_64")]
    let avx2 = isa == Isa::Avx2;
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = false;
    let res = bitslice::run_block(
        bs,
        plan.flags(),
        avx2,
        &mut BsBlock {
            seed: plan.seed,
            block,
            active: runs as usize,
            record: plan.record_runs,
            acc: &mut acc,
        },
        cancel,
    )?;
    let mut moments = Moments::default();
    let horizon = plan.horizon as f64;
    for s in &res.sum[..runs as usize] {
        moments.push(s / horizon);
    }
    let high = if plan.online {
        // Δ at k = 1 and after every delivered flag except one at the last step.
        u128::from(runs + res.sent - res.blocked - res.hi_last)
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
        high,
        runs,
        delivered,
    })
}

fn run_block(plan: &Plan, kernels: Kernels, block: u64, cancel: &AtomicBool) -> Result<BlockOut> {
    let isa = kernels.isa;
    if let (Some(bs), true) = (&plan.bitslice, kernels.bitslice) {
        return run_bitslice_block(plan, bs, isa, block, cancel);
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
            out.high += if plan.online {
                // Δ at k = 1 and after every delivered flag except one at the last step.
                u128::from(1 + res.sent[l] - res.blocked[l] - res.hi_last[l])
            } else {
                u128::from(plan.offline_high)
            };
            if plan.record_runs {
                out.delivered.push(res.sent[l] - res.blocked[l]);
            }
        }
    }
    out.acc = acc;
    Ok(out)
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

fn simulate_with(
    sys: &LinearSystem,
    cfg: &McConfig,
    cancel: &AtomicBool,
    progress: &AtomicU64,
    kernels: Kernels,
) -> Result<McResult> {
    let plan = Plan::new(sys, cfg)?;
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

    let mut total = vec![0.0f64; plan.horizon];
    let mut moments = Moments::default();
    let (mut sent, mut blocked, mut high) = (0u128, 0u128, 0u128);
    // Blocks are folded in block order, so entry i is run i (at most 2^28 runs, checked).
    let mut delivered = if plan.record_runs {
        Vec::with_capacity(plan.runs as usize)
    } else {
        Vec::new()
    };
    let mut start = 0u64;
    while start < blocks {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        let end = blocks.min(start + wave);
        let outs: Vec<Result<BlockOut>> = (start..end)
            .into_par_iter()
            .map(|b| {
                let out = run_block(&plan, kernels, b, cancel)?;
                progress.fetch_add(out.runs, Ordering::Relaxed);
                Ok(out)
            })
            .collect();
        for out in outs {
            let out = out?;
            for (t, a) in total.iter_mut().zip(&out.acc) {
                *t += a;
            }
            moments.merge(&out.moments);
            sent += out.sent;
            blocked += out.blocked;
            high += out.high;
            delivered.extend_from_slice(&out.delivered);
        }
        start = end;
    }

    let runs = plan.runs as f64;
    let mean_trace: Vec<f64> = total.iter().map(|t| t / runs).collect();
    let j_k = running_means(&mean_trace);
    let j = j_k.last().copied().unwrap_or(f64::NAN);
    let stderr = if moments.n < 2 || moments.nonfinite || !j.is_finite() {
        f64::INFINITY
    } else {
        let var = (moments.m2 / (moments.n - 1) as f64).max(0.0);
        (var / runs).sqrt()
    };
    let steps = runs * plan.horizon as f64;
    Ok(McResult {
        mean_trace,
        j_k,
        j,
        stderr,
        high_power_rate: high as f64 / steps,
        flags_sent: sent as f64 / steps,
        flags_blocked: blocked as f64 / steps,
        runs: plan.runs,
        steps: plan.horizon as u64,
        delivered_per_run: delivered,
    })
}
