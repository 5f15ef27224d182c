//! Closed-loop Monte Carlo of the sensor-attacker game: the protocol of [`crate::montecarlo`]
//! (sensor, lossy channel, remote estimator, event detector, attacker) with the sensor's detector
//! and its fall-back to the offline schedule in the loop.
//!
//! Each run plays `burn_in + horizon` steps from the paper's initial condition (high power at
//! k = 1, memory all ones, counter 0), cut into windows of `window` steps from the first; costs
//! and rates are measured after the burn-in. In an online window the sensor follows the flag-ACKs it receives and records, for each
//! one, its gap since the previous (the count and the interval tests read nothing else); at the
//! window's end it applies its test, and an alarm that triggers the fall-back (any alarm, or only
//! one whose count is low enough, the "harmful" rule) makes it run the offline schedule, from
//! the start of its period, for the next `fallback` windows, ignoring flag-ACKs, then return
//! online. Windows are not tested while offline. With the support check (`min_gap` > 1) a
//! window also alarms when some flag-ACK that reached the sensor in it came fewer than `min_gap`
//! steps after the previous one: the gap that straddles the window's start counts, the run's
//! start counting as a flag-ACK at step 0 (the exact engine's k_last = 0), but not the first gap
//! after an offline stretch (offline, the sensor's power does not follow the flags, so a flag may
//! come z0 steps after the previous one without attack). Forged flag-ACKs count like genuine
//! ones, and a support alarm triggers the fall-back under the harmful rule as any other alarm
//! does: only with a count N <= `harmful_at_most`. The remote detector and the attacker do not
//! know which schedule the sensor runs: the detector keeps its memory of ACKs and sends flags,
//! the attacker keeps counting, blocking and forging them, in every window.
//!
//! The CUSUM policy ([`Policy::Cusum`]) tests at every online step instead of every window: with
//! y the steps since the last flag-ACK that reached the sensor (y = 1 on the step after it) and x
//! whether one reaches it at this step, W <- max(0, W + inc), inc = `inc_flag[min(y, Y) - 1]` if
//! x else `inc_quiet[min(y, Y) - 1]`, and W >= `threshold` is an alarm: the sensor runs the
//! offline schedule, from the start of its period, for the next `fallback` * `window` steps, then
//! returns online with W = 0 and the statistic dormant until a flag-ACK reaches it (y = 1 on the
//! step after that one). The run starts with W = 0 and the statistic running, y = 1 at step 1
//! (the initial condition is that of a flag-ACK delivered at step 0). Windows then only measure
//! the fall-back. An increment of +inf is an immediate alarm (a gap the attack-free protocol
//! cannot produce: the support check), one of -inf resets W to 0.
//!
//! The likelihood-ratio window test ([`Detector::Likelihood`]) reads the same per-step
//! increments as the CUSUM, without the reflection at 0: an online window's Λ starts at
//! `opening[min(y, Y) - 1]` (y the gap of its first step; beyond Y the opening grows by the last
//! quiet increment per step) and adds each step's increment; an increment of +inf makes Λ = +inf
//! for the rest of the window (the support check), and the window alarms iff Λ >= `critical`. As
//! for the support check, the first gap after an offline stretch is not read: back online, the
//! statistic is dormant (Λ = 0, no increments) until a flag-ACK reaches the sensor, and runs from
//! the next step; the run's start counts as a flag-ACK at step 0.
//!
//! Per step: the sensor's power (online: high iff a flag-ACK reached it last step; offline: the
//! pattern), the arrival (on the i.i.d. channel always at high power, with probability λ at low;
//! on a Markov channel in state c_k with probability `high[c_k]` or `low[c_k]`, see below), the
//! holding time τ
//! and Tr P_k = Tr h^τ(P̄), the detector's zero count z (reset by an arrival; a flag sent last step
//! had reset the memory, so a loss makes z = 1), its flag (at z = z0 with probability μ, always
//! at z0 + 1), the attacker's block (its counter's mask entry, or probability β) and forgery
//! (probability γ on a step without a genuine flag), the delivery (a genuine flag not blocked, or
//! a forged one) and its gap since the previous delivery, which an online sensor sorts into the
//! interval test's bins and, if online since that delivery, compares with `min_gap` for the
//! support check. These are the rules of
//! [`crate::chain::general::capped_attack_chain`], which the tests compare with.
//!
//! Any other attacker is an automaton ([`GameConfig::automaton`], the exact engine's
//! [`AttackerAutomaton`]: every built-in attack, injection with a minimum gap, mimicry, or one
//! written by hand): the block and the forgery are then one move, as in the automaton Monte Carlo
//! ([`crate::montecarlo::automaton`]) and the exact engine: the attacker in state s sees the event
//! "flag" (the detector sent a genuine flag-ACK this step) or "quiet", takes one of that event's
//! moves (p, deliver, next), and the sensor receives a flag-ACK iff `deliver`. It starts in its
//! start state and moves at every step, offline included, as the built-in attacks do.
//!
//! A Markov channel ([`MarkovChannel`], the package's convention): K states, P row-stochastic
//! with one closed class, `P[i][j]` = P(c_{k+1} = j | c_k = i); given c_k the step's packet
//! arrives independently of everything else with probability `low[c_k]` at low power and
//! `high[c_k]` at high power (a high-power packet may be lost); c_1 has the stationary law of P.
//! Flag-ACKs are not subject to the channel. The exact engine ([`crate::engine`]) has the same
//! conventions, and the tests compare with it.
//!
//! # Engineering
//! Two kernels, with the same protocol and different random streams (so one seed gives equally
//! distributed, not equal, samples on the two):
//!
//! * The bit-sliced kernel (`sliced.rs`) takes every plan with a memory of at most 31 steps, an
//!   interval test of at most 64 bins whose last edge is at most 64 steps, a support check of
//!   `min_gap` at most 64, and a blocking mask of at most 8 runs of ones: the paper's example and every game `fakeack` builds for it. Blocks of 256 runs are the bit lanes of four u64 words,
//!   each per-run quantity a thermometer or binary bit-planes, as in the plain Monte Carlo's
//!   bit-sliced kernel; block b draws from SplitMix64 sub-stream (seed, b), one xoshiro256++
//!   generator per word, with bit-serial Bernoulli draws exact to 2^-64.
//! * The lane kernel takes the rest: every Markov channel, every attacker automaton and the
//!   CUSUM policy (on every attack). Runs
//!   advance in lock-step tiles of [`LANES`]; tile b draws
//!   from SplitMix64 sub-stream (seed, b), one xoshiro256++ generator per lane. Each step takes
//!   one 64-bit output per lane and splits it into four 16-bit slices for the step's four
//!   possible draws (arrival, memory length, block, forgery); a slice equal to the top 16 bits
//!   of the exact threshold ⌊p 2^64⌋ (probability 2^-16) is resolved with 48 further bits, so
//!   every draw is exactly Bernoulli(⌊p 2^64⌋ / 2^64). On a Markov channel the arrival's slice
//!   draws with the state's and the power's probability, and one further 64-bit output per step
//!   draws the next state by inverse CDF on the thresholds ⌊F_j 2^64⌋ of the cumulative row
//!   (exact to 2^-64 likewise); c_1 takes one output per lane before the first step. An
//!   attacker automaton takes one further output per step (after the arrival's, before the
//!   channel's), which draws its move from the (state, event)'s alias table as the automaton
//!   Monte Carlo does (each move's probability exact to n 2^-63 for an event of n moves); the
//!   block's and the forgery's slices then go unused.
//!
//! Either way each run's result depends on the seed and its index only, not on threads or on
//! how many runs follow. Blocks and tiles run in parallel (rayon) and are collected in order;
//! the cancel flag is polled at every window (and every [`CHECK_STEPS`] steps).
//!
//! Holding times index a table of Tr h^τ(P̄) of length min(burn_in + horizon + 1,
//! [`MAX_TRACE_TABLE`]); a longer τ (only possible past 16384 steps without an arrival) reads its
//! last entry (exact wherever the table has settled: a stable A, or +inf; on a Markov channel
//! with a state where packets rarely arrive, long holding times are less rare).

use std::hint::black_box;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use rayon::prelude::*;

use super::bitslice::RUNS;
use super::cpu::Avx2;
use crate::attack::Attack;
use crate::engine::{AttackerAutomaton, Channel};
use crate::error::{Error, Result};
pub use crate::montecarlo::automaton::MarkovChannel;
use crate::montecarlo::rng::{bernoulli_threshold, SplitMix64, Xoshiro256pp};
use crate::schedule::{check_lam, OnlineDesign, MAX_PERIOD};
use crate::system::LinearSystem;

/// Runs simulated in lock-step by one kernel call.
pub const LANES: usize = 8;
/// Most runs in one call (per-run results take 48 bytes each).
pub const MAX_RUNS: u64 = 1 << 24;
/// Longest table of Tr h^τ(P̄).
pub const MAX_TRACE_TABLE: usize = 1 << 14;
/// Most bins of the interval test.
pub const MAX_BINS: usize = 1 << 12;
/// Longest run in steps (burn-in included).
pub const MAX_STEPS: u64 = 1 << 42;
/// Steps between two polls of the cancel flag within a window.
pub const CHECK_STEPS: u64 = 1 << 16;
/// Most states of a Markov channel (its transition draws take K² words).
pub const MAX_CHANNEL_STATES: usize = 1 << 10;
/// Longest increment table of the CUSUM policy.
pub const MAX_CUSUM_TABLE: usize = 1 << 14;

/// The sensor's test of one window, applied to the flag-ACKs that reached it.
#[derive(Debug, Clone, PartialEq)]
pub enum Detector {
    /// The count test: alarm iff the window's count N satisfies `N <= lo` or `N >= hi`.
    Count {
        /// Largest count that is too low (-1: none).
        lo: i64,
        /// Smallest count that is too high (above the window length: none).
        hi: i64,
    },
    /// The interval test: Pearson's X² = Σ (O_i - E_i)² / E_i over bins of gap lengths; alarm
    /// iff X² > `critical`.
    Interval {
        /// Lower edges of the bins (steps), increasing from 1; the last bin is open above.
        edges: Vec<u64>,
        /// Expected flag-ACKs per bin in a window without attack (all positive).
        expected: Vec<f64>,
        /// The critical value.
        critical: f64,
    },
    /// The likelihood-ratio test: Λ, the window's sum of per-step log-likelihood ratios opened by
    /// that of the gap running at its start (see the module docs); alarm iff Λ >= `critical`.
    Likelihood {
        /// Increment at a step where a flag-ACK reaches the sensor, by y = 1..Y (the last entry
        /// for every y >= Y); +inf and -inf allowed, NaN not.
        inc_flag: Vec<f64>,
        /// Increment at a step where none does, by y likewise; the same length Y.
        inc_quiet: Vec<f64>,
        /// The opening at the window's first gap y = 1..Y; beyond Y it grows by the last quiet
        /// increment per step.
        opening: Vec<f64>,
        /// The critical value (finite).
        critical: f64,
    },
}

/// The sensor's policy in the repeated game.
#[derive(Debug, Clone, PartialEq)]
pub enum Policy {
    /// Online schedule, never tested.
    Online,
    /// Offline schedule throughout.
    Offline,
    /// Online, testing every online window; a triggering alarm means `fallback` offline windows.
    Test {
        /// The test.
        detector: Detector,
        /// Only alarms with a count N <= this bound trigger the fall-back (the "harmful" rule:
        /// the estimated budget exceeds β̄); `None`: every alarm does.
        harmful_at_most: Option<i64>,
        /// Offline windows after a triggering alarm.
        fallback: u64,
        /// The support check: the window also alarms when a flag-ACK reaches the sensor fewer
        /// than `min_gap` steps after the previous one (the shortest gap possible without
        /// attack, z0 + 1 on the paper's channel); 0 or 1: no check.
        min_gap: u64,
    },
    /// Online, with the CUSUM statistic W run at every online step (see the module docs); an
    /// alarm (W >= `threshold`) means `fallback` windows' worth of offline steps.
    Cusum {
        /// Increment at a step where a flag-ACK reaches the sensor, by y = 1..Y (the last entry
        /// for every y >= Y); +inf and -inf allowed, NaN not.
        inc_flag: Vec<f64>,
        /// Increment at a step where none does, by y likewise; the same length Y >= 1.
        inc_quiet: Vec<f64>,
        /// Alarm threshold, finite and positive.
        threshold: f64,
        /// Offline windows (of `window` steps) after an alarm.
        fallback: u64,
    },
}

/// One closed-loop experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct GameConfig {
    /// Low-power arrival probability λ, in (0, 1), of the i.i.d. channel (ignored, and not
    /// checked, when `channel` is given).
    pub lam: f64,
    /// A Markov channel (`None`: the i.i.d. channel of `lam`, where high power always arrives).
    pub channel: Option<MarkovChannel>,
    /// The online schedule's memory.
    pub design: OnlineDesign,
    /// The offline schedule's period (1 = high power), first entry = the first step of an
    /// offline stretch; at most [`MAX_PERIOD`] steps.
    pub offline: Vec<u8>,
    /// The attack (`None`: none). It runs in every window, online or not.
    pub attack: Option<Attack>,
    /// An attacker automaton instead of `attack` (`None`: `attack` decides; giving both is
    /// refused): any attacker, built-in, mimicry or written by hand, in the exact engine's form.
    /// It runs in every window too, on the lane kernel.
    pub automaton: Option<AttackerAutomaton>,
    /// The sensor's policy.
    pub policy: Policy,
    /// Window length in steps, >= 1.
    pub window: u64,
    /// Measured steps per run, >= 1.
    pub horizon: u64,
    /// Steps played (policy, tests and fall-backs included) before the measured horizon, so that
    /// the measurement starts near the game's stationary regime. Windows run from the first step;
    /// a window's test counts in the results when the window ends after the burn-in.
    pub burn_in: u64,
    /// Independent runs, 1..=[`MAX_RUNS`].
    pub runs: u64,
    /// The results depend on this seed only.
    pub seed: u64,
}

/// Per-run results, in run order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GameRuns {
    /// Mean of Tr P_k over the measured horizon.
    pub cost: Vec<f64>,
    /// Fraction of measured steps at high power.
    pub high_power: Vec<f64>,
    /// Fraction of measured steps run online.
    pub online: Vec<f64>,
    /// Windows tested (online windows, for a testing policy); for the CUSUM, measured steps at
    /// which the statistic ran (online and not dormant).
    pub tested: Vec<u64>,
    /// Tested windows with an alarm; for the CUSUM, alarms at measured steps.
    pub alarms: Vec<u64>,
    /// Alarms that triggered the fall-back (for the CUSUM, every alarm).
    pub fallbacks: Vec<u64>,
    /// Measured steps run online.
    pub online_steps: Vec<u64>,
    /// Flag-ACKs that reached the sensor during the measured horizon (online or not).
    pub delivered: Vec<u64>,
}

mod channel;
mod plan;
mod sliced;
mod tile;

use plan::Plan;
use sliced::Sliced;
use tile::{run_tile, Tile};

impl GameConfig {
    /// Checks every field; the messages name the field (a channel's: `P`, `low`, `high`).
    pub fn validate(&self) -> Result<()> {
        self.stationary()?;
        self.design.validate()?;
        if let Some(a) = &self.attack {
            a.validate()?;
        }
        if self.attack.is_some() && self.automaton.is_some() {
            return Err(Error::invalid(
                "automaton",
                "give either an attack or an attacker automaton, not both",
            ));
        }
        if self.offline.is_empty() || self.offline.iter().any(|&g| g > 1) {
            return Err(Error::invalid("offline", "must be a non-empty 0/1 pattern"));
        }
        if self.offline.len() as u64 > MAX_PERIOD {
            return Err(Error::TooLarge {
                arg: "offline".into(),
                requested: self.offline.len() as u128,
                limit: u128::from(MAX_PERIOD),
            });
        }
        if self.window < 1 {
            return Err(Error::invalid("window", "must be at least 1"));
        }
        if self.horizon < 1 {
            return Err(Error::invalid("horizon", "must be at least 1"));
        }
        if self.runs < 1 || self.runs > MAX_RUNS {
            return Err(Error::invalid(
                "runs",
                format!("must lie in 1..={MAX_RUNS}, got {}", self.runs),
            ));
        }
        if self.horizon.saturating_add(self.burn_in) > MAX_STEPS {
            return Err(Error::invalid(
                "horizon",
                format!("burn_in + horizon must be at most {MAX_STEPS}"),
            ));
        }
        if let Policy::Test {
            detector:
                Detector::Interval {
                    edges,
                    expected,
                    critical,
                },
            ..
        } = &self.policy
        {
            let increasing = edges.windows(2).all(|w| w[0] < w[1]);
            if edges.is_empty() || edges[0] != 1 || !increasing || edges.len() > MAX_BINS {
                return Err(Error::invalid(
                    "edges",
                    format!("must increase from 1, at most {MAX_BINS} bins"),
                ));
            }
            if *edges.last().unwrap() > MAX_TRACE_TABLE as u64 * 64 {
                return Err(Error::invalid("edges", "the last edge is too large"));
            }
            if expected.len() != edges.len()
                || expected.iter().any(|&e| !(e.is_finite() && e > 0.0))
            {
                return Err(Error::invalid(
                    "expected",
                    "needs one positive finite value per bin",
                ));
            }
            if critical.is_nan() {
                return Err(Error::invalid("critical", "must not be NaN"));
            }
        }
        if let Policy::Test {
            detector:
                Detector::Likelihood {
                    inc_flag,
                    inc_quiet,
                    opening,
                    critical,
                },
            ..
        } = &self.policy
        {
            increment_tables(inc_flag, inc_quiet)?;
            if opening.len() != inc_flag.len() || opening.iter().any(|v| v.is_nan()) {
                return Err(Error::invalid(
                    "opening",
                    format!(
                        "must have as many entries as inc_flag ({}), none NaN",
                        inc_flag.len()
                    ),
                ));
            }
            if !critical.is_finite() {
                return Err(Error::invalid(
                    "critical",
                    format!("must be finite, got {critical}"),
                ));
            }
        }
        if let Policy::Test { min_gap, .. } = &self.policy {
            // No gap is longer than the run.
            if *min_gap > MAX_STEPS {
                return Err(Error::invalid(
                    "min_gap",
                    format!("must be at most {MAX_STEPS}, got {min_gap}"),
                ));
            }
        }
        if let Policy::Cusum {
            inc_flag,
            inc_quiet,
            threshold,
            fallback,
        } = &self.policy
        {
            increment_tables(inc_flag, inc_quiet)?;
            if !(threshold.is_finite() && *threshold > 0.0) {
                return Err(Error::invalid(
                    "threshold",
                    format!("must be finite and positive, got {threshold}"),
                ));
            }
            if fallback.checked_mul(self.window).is_none() {
                return Err(Error::invalid(
                    "fallback",
                    "fallback * window must fit in 64 bits",
                ));
            }
        }
        Ok(())
    }

    /// Checks `lam` or the channel; the channel's stationary law (empty for the i.i.d. one).
    fn stationary(&self) -> Result<Vec<f64>> {
        let Some(ch) = &self.channel else {
            check_lam(self.lam)?;
            return Ok(Vec::new());
        };
        if ch.p.len() > MAX_CHANNEL_STATES {
            return Err(Error::TooLarge {
                arg: "P".into(),
                requested: ch.p.len() as u128,
                limit: MAX_CHANNEL_STATES as u128,
            });
        }
        // The engine's validation: square, stochastic rows, one closed class, low and high of
        // length K in [0, 1].
        let valid = Channel::markov(ch.p.clone(), ch.low.clone(), ch.high.clone())?;
        Ok(valid.stationary().to_vec())
    }
}

/// The increment tables of the CUSUM or the likelihood-ratio test: 1 to [`MAX_CUSUM_TABLE`]
/// entries each, the same length, no NaN.
fn increment_tables(inc_flag: &[f64], inc_quiet: &[f64]) -> Result<()> {
    for (name, table) in [("inc_flag", inc_flag), ("inc_quiet", inc_quiet)] {
        if table.is_empty() || table.len() > MAX_CUSUM_TABLE {
            return Err(Error::invalid(
                name,
                format!(
                    "must have 1 to {MAX_CUSUM_TABLE} entries, got {}",
                    table.len()
                ),
            ));
        }
        if table.iter().any(|v| v.is_nan()) {
            return Err(Error::invalid(name, "must not contain NaN"));
        }
    }
    if inc_flag.len() != inc_quiet.len() {
        return Err(Error::invalid(
            "inc_quiet",
            format!(
                "must have as many entries as inc_flag ({}), got {}",
                inc_flag.len(),
                inc_quiet.len()
            ),
        ));
    }
    Ok(())
}

/// [`LinearSystem::simulate_game_with`], on the bit-sliced kernel when `sliced` and the plan
/// fits it, else on the lane kernel. The method itself is in `analysis`, with the system's other
/// quantities.
pub(crate) fn simulate_on(
    sys: &LinearSystem,
    cfg: &GameConfig,
    cancel: &AtomicBool,
    progress: &AtomicU64,
    sliced: bool,
) -> Result<GameRuns> {
    let plan = Plan::new(sys, cfg)?;
    let runs = cfg.runs as usize;
    let h = cfg.horizon as f64;
    let mut out = GameRuns::default();
    let mut keep = |cost: f64, high: u64, online: u64, counts: [u64; 4]| {
        if out.cost.len() < runs {
            out.cost.push(cost / h);
            out.high_power.push(high as f64 / h);
            out.online.push(online as f64 / h);
            out.online_steps.push(online);
            out.tested.push(counts[0]);
            out.alarms.push(counts[1]);
            out.fallbacks.push(counts[2]);
            out.delivered.push(counts[3]);
        }
    };
    if let Some(s) = Sliced::of(&plan).filter(|_| sliced) {
        let blocks = cfg.runs.div_ceil(RUNS as u64);
        let avx2 = Avx2::detect();
        let done = (0..blocks)
            .into_par_iter()
            .map(|b| {
                let out = sliced::run_block(&s, &plan, b, avx2, cancel)?;
                // The runs this block holds (the last may be partial).
                progress.fetch_add(
                    (RUNS as u64).min(cfg.runs - b * RUNS as u64),
                    Ordering::Relaxed,
                );
                Ok(out)
            })
            .collect::<Result<Vec<_>>>()?;
        for t in &done {
            for l in 0..RUNS {
                let counts = [t.tested[l], t.alarms[l], t.fallbacks[l], t.delivered[l]];
                keep(t.cost[l], t.high[l], t.online_steps[l], counts);
            }
        }
        return Ok(out);
    }
    let tiles = cfg.runs.div_ceil(LANES as u64);
    let done: Vec<Tile> = (0..tiles)
        .into_par_iter()
        .map(|b| {
            let t = run_tile(&plan, b, cancel)?;
            progress.fetch_add(
                (LANES as u64).min(cfg.runs - b * LANES as u64),
                Ordering::Relaxed,
            );
            Ok(t)
        })
        .collect::<Result<Vec<_>>>()?;
    for t in &done {
        for l in 0..LANES {
            let counts = [t.tested[l], t.alarms[l], t.fallbacks[l], t.delivered[l]];
            keep(t.cost[l], t.high[l], t.online_steps[l], counts);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
