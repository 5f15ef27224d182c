//! A plain per-run Monte Carlo of the protocol under any attacker automaton, on a finite-state
//! Markov channel, with the online design or any offline pattern ([`simulate`]).
//!
//! It simulates the protocol from its components, one run after another, step by step: the
//! channel state, the sensor's power, the holding time τ, the detector's zero count and the
//! attacker's state. It never forms the product automaton of the exact engine, so it checks
//! the engine independently, and it takes every attack the engine takes: a built-in attack,
//! mimicry or an injection with a minimum gap are all written as an [`Attacker`] table by the
//! Python layer (`fakeack.attacks.as_automaton`).
//!
//! One step k, in the order of the lane kernels' reference (`kernel/reference.rs`):
//!
//! 1. the sensor's power: online, high iff a flag-ACK reached it at the end of step k-1 (high at
//!    k = 1); offline, the pattern's symbol for step k (`pattern[(k-1) % len]`);
//! 2. in channel state c_k the packet arrives with probability `high[c_k]` or `low[c_k]`; τ_k = 0
//!    on arrival, else τ_{k-1} + 1, and the step's cost is `tr[τ_k]` = Tr h^τ_k(P̄);
//! 3. online: the detector's zero count z restarts at an arrival and grows by one at a loss;
//!    the memory has z0 bits at this step with probability μ (else z0 + 1), and a flag-ACK is
//!    sent iff z reaches the memory length (surely at z = z0 + 1, with probability μ at z = z0);
//!    the count restarts after every flag-ACK sent;
//! 4. the attacker in state s sees the event "flag" (a genuine flag-ACK was sent) or "quiet" and
//!    takes one of that event's transitions (p, deliver, next): the sensor receives a flag-ACK
//!    (high power at k + 1) iff `deliver`, and the attacker moves to `next`;
//! 5. the channel moves c_k → c_{k+1} by `P[c_k]`.
//!
//! In covariance mode step k costs `tr[τ_k]` = Tr h^τ_k(P̄); in state mode ([`Mode::State`]) it
//! costs ||e_k||², the remote estimation error simulated with Gaussian noise by the recursions of
//! the lane kernels' state mode (the sensor's steady-state Kalman filter; on an arrival the remote
//! estimate is reset to the sensor's, else predicted), whose mean given the holding time is
//! Tr h^τ_k(P̄): both modes estimate the same J. A run's protocol stream is the same in both
//! modes, so for one seed they see the same arrivals, flag-ACKs and attacker moves; state mode
//! draws its noise from a second stream of the run's seed. The remote error starts at the
//! sensor's (e_0 = e^s_0 ~ N(0, P̄), τ_0 = 0), which matters where the first packet may be lost.
//!
//! Initial condition (the paper's): τ_0 = 0, c_1 drawn from the stationary law of P, high power
//! at k = 1 (online), zero count 0 (memory all ones), the attacker at its start state. An offline
//! sensor ignores flag-ACKs: there is no detector and no attacker, and the flag counts are zero.
//!
//! # Engineering
//!
//! Each (state, event) of the attacker and each channel row is an alias table (Walker, Vose), so
//! a draw is one 64-bit random word, one multiplication and one compare, whatever the number of
//! transitions; the arrival is a compare of 63 random bits with ⌊p 2^63⌋ (exact at p = 0 and 1).
//! Runs are split into blocks of [`BLOCK_RUNS`] as in the other kernels:
//! block b draws from SplitMix64 sub-stream (seed, b), each run from its own xoshiro256++ seeded
//! from it, and blocks are folded in block order, so the results depend on the seed only, never
//! on the number of threads. Within a block, [`WIDTH`] runs advance together so that their
//! independent dependency chains overlap; every run is still simulated on its own.
//!
//! The traces `tr[τ]` come from [`LinearSystem::h_traces`]: +inf past the double range (never
//! NaN), so an overflowing run gives an infinite J and standard error, as in the other kernels.
//! τ never exceeds the horizon; the table stops early where it has settled (it is increasing, so
//! once it reaches +inf or stops changing in f64 every later entry is the same) and lookups clamp
//! their index to its end, so huge holding times cost no memory.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use rayon::prelude::*;

use super::config::{McResult, Mode};
use super::cpu::Avx2;
use super::BLOCK_RUNS;
use crate::error::{Error, Result};
use crate::system::LinearSystem;

mod kernel;
#[cfg(test)]
mod state_tests;
pub(super) mod tables;
#[cfg(test)]
mod tests;

use kernel::{run_block, BlockOut};
use tables::Plan;

/// Runs of a block that advance together in the kernel.
pub const WIDTH: usize = 4;
const _: () = assert!(BLOCK_RUNS as usize % WIDTH == 0);

/// A finite-state Markov channel.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkovChannel {
    /// Row-stochastic K × K: `p[i][j]` = P(c_{k+1} = j | c_k = i); one closed class.
    pub p: Vec<Vec<f64>>,
    /// Arrival probability of a low-power packet in each state.
    pub low: Vec<f64>,
    /// Arrival probability of a high-power packet in each state.
    pub high: Vec<f64>,
}

impl MarkovChannel {
    /// The paper's channel: one state, a low-power packet arrives with probability `lam` and a
    /// high-power one always.
    pub fn bernoulli(lam: f64) -> Self {
        MarkovChannel {
            p: vec![vec![1.0]],
            low: vec![lam],
            high: vec![1.0],
        }
    }
}

/// The sensor's power schedule.
#[derive(Debug, Clone, PartialEq)]
pub enum Sensor {
    /// The ACK-based online schedule: z0-bit memory with probability `mu`, else z0 + 1 bits.
    Online {
        /// The short memory length, >= 1.
        z0: u64,
        /// The probability of the z0-bit memory at a step, in [0, 1].
        mu: f64,
    },
    /// An offline pattern repeated periodically (true = high power), first entry = step 1.
    Offline {
        /// One period, non-empty.
        pattern: Vec<bool>,
    },
}

/// One transition of an attacker's event.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Its probability, in [0, 1].
    pub p: f64,
    /// Whether the sensor receives a flag-ACK at the end of the step.
    pub deliver: bool,
    /// The attacker's next state.
    pub next: usize,
}

/// An attacker as a finite automaton on the events "flag" and "quiet".
#[derive(Debug, Clone, PartialEq)]
pub struct Attacker {
    /// Per state, the transitions on a step with a genuine flag-ACK (probabilities summing to 1).
    pub flag: Vec<Vec<Transition>>,
    /// Per state, the transitions on a step without one.
    pub quiet: Vec<Vec<Transition>>,
    /// The state at step 1.
    pub start: usize,
}

impl Attacker {
    /// No attack: every genuine flag-ACK is delivered, none is forged.
    pub fn none() -> Self {
        let t = |deliver| {
            vec![vec![Transition {
                p: 1.0,
                deliver,
                next: 0,
            }]]
        };
        Attacker {
            flag: t(true),
            quiet: t(false),
            start: 0,
        }
    }
}

/// One experiment of the automaton Monte Carlo.
#[derive(Debug, Clone, PartialEq)]
pub struct AutomatonConfig {
    /// The channel.
    pub channel: MarkovChannel,
    /// The sensor's schedule.
    pub sensor: Sensor,
    /// The attacker (online only; `None`: no attack). An offline sensor ignores it.
    pub attacker: Option<Attacker>,
    /// Covariance (τ and Tr P_k) or state (Gaussian errors) fidelity; the same protocol
    /// randomness in both for one seed.
    pub mode: Mode,
    /// Steps per run, 1..=[`MAX_HORIZON`](super::MAX_HORIZON).
    pub horizon: usize,
    /// Number of independent runs, >= 1.
    pub runs: u64,
    /// The results depend on this seed only (not on the number of threads).
    pub seed: u64,
    /// Record each run's number of flag-ACKs delivered to the sensor
    /// ([`McResult::delivered_per_run`]).
    pub record_runs: bool,
}

/// Count, mean and sum of squared deviations (Welford; Chan et al. to merge), as the block
/// driver of the other kernels keeps them.
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

/// The sums over the blocks folded so far, in block order.
struct Totals {
    /// Per-step sums of Tr P_k over the runs.
    trace: Vec<f64>,
    /// The moments of the runs' time averages.
    moments: Moments,
    /// Flag-ACKs sent.
    sent: u128,
    /// Genuine flag-ACKs not delivered.
    blocked: u128,
    /// Flag-ACKs delivered on quiet steps.
    forged: u128,
    /// High-power steps.
    high: u128,
    /// Delivered flag-ACKs per run, in run order (recording only).
    delivered: Vec<u64>,
}

impl Totals {
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

    /// The averages over all the runs.
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

/// Runs the automaton Monte Carlo of `cfg` on `sys`: E Tr P_k per step (covariance mode) or
/// E ||e_k||² (state mode), J over the horizon with its standard error, and the flag-ACK counts, in an [`McResult`]
/// (`flags_blocked` counts the genuine flag-ACKs the attacker did not deliver, `flags_forged`
/// the flag-ACKs it delivered on quiet steps).
///
/// Deterministic in `cfg.seed` whatever the number of threads; checks `cancel` between blocks
/// and every 2^16 steps of a block's runs, returning [`Error::Interrupted`] once it is set; adds
/// completed runs to `progress` as blocks finish. Errors name the offending argument (`P`,
/// `low`, `high`, `z0`, `mu`, `offline`, `flag`, `quiet`, `start`, `horizon`, `runs`; in state
/// mode `R` or `sys` where the Kalman gain cannot be formed).
pub fn simulate(
    sys: &LinearSystem,
    cfg: &AutomatonConfig,
    cancel: &AtomicBool,
    progress: &AtomicU64,
) -> Result<McResult> {
    simulate_on(sys, cfg, cancel, progress, Avx2::detect())
}

/// [`simulate`] on the AVX2 build of the kernel if `avx2` holds the token, else the plain one
/// (tests run both; they give the same results bit for bit).
fn simulate_on(
    sys: &LinearSystem,
    cfg: &AutomatonConfig,
    cancel: &AtomicBool,
    progress: &AtomicU64,
    avx2: Option<Avx2>,
) -> Result<McResult> {
    let plan = Plan::new(sys, cfg)?;
    if cancel.load(Ordering::Relaxed) {
        return Err(Error::Interrupted);
    }
    let blocks = plan.runs.div_ceil(BLOCK_RUNS);
    let threads = rayon::current_num_threads().max(1) as u64;
    // As the other kernels' driver: waves of blocks whose per-step buffers fit in 64 MiB, at
    // least one and at most 64 blocks per thread.
    let buffer_bytes = plan.horizon as u64 * 8;
    let wave = ((64u64 << 20) / buffer_bytes.max(1)).clamp(threads, 64 * threads);
    let mut totals = Totals {
        trace: vec![0.0; plan.horizon],
        moments: Moments::default(),
        sent: 0,
        blocked: 0,
        forged: 0,
        high: 0,
        delivered: Vec::new(),
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
                let out = run_block(&plan, avx2, b, cancel)?;
                progress.fetch_add(out.runs, Ordering::Relaxed);
                Ok(out)
            })
            .collect();
        for out in outs {
            totals.add(&out?);
        }
        start = end;
    }
    Ok(totals.result(&plan))
}
