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
//! online. Windows are not tested while offline. The remote detector and the attacker do not
//! know which schedule the sensor runs: the detector keeps its memory of ACKs and sends flags,
//! the attacker keeps counting, blocking and forging them, in every window.
//!
//! Per step: the sensor's power (online: high iff a flag-ACK reached it last step; offline: the
//! pattern), the arrival (always at high power, with probability λ at low), the holding time τ
//! and Tr P_k = Tr h^τ(P̄), the detector's zero count z (reset by an arrival; a flag sent last step
//! had reset the memory, so a loss makes z = 1), its flag (at z = z0 with probability μ, always
//! at z0 + 1), the attacker's block (its counter's mask entry, or probability β) and forgery
//! (probability γ on a step without a genuine flag). These are the rules of
//! [`crate::general::capped_attack_chain`], which the tests compare with.
//!
//! # Engineering
//! Runs advance in lock-step tiles of [`LANES`]; tile b draws from SplitMix64 sub-stream
//! (seed, b), one xoshiro256++ generator per lane, so each run's result depends on the seed and
//! its index only, not on threads or on how many runs follow. Each step takes one 64-bit output
//! per lane and splits it into four 16-bit slices for the step's four possible draws (arrival,
//! memory length, block, forgery); a slice equal to the top 16 bits of the exact threshold
//! ⌊p 2^64⌋ (probability 2^-16) is resolved with 48 further bits, so every draw is exactly
//! Bernoulli(⌊p 2^64⌋ / 2^64). Tiles run in parallel (rayon) and are collected in order; the
//! cancel flag is polled at every window (and every [`CHECK_STEPS`] steps).
//!
//! Holding times index a table of Tr h^τ(P̄) of length min(burn_in + horizon + 1,
//! [`MAX_TRACE_TABLE`]); a longer τ (only possible past 16384 steps without an arrival) reads its
//! last entry.

use std::hint::black_box;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use rayon::prelude::*;

use crate::attack::Attack;
use crate::error::{Error, Result};
use crate::online::{check_lam, OnlineDesign};
use crate::rng::{bernoulli_threshold, SplitMix64, Xoshiro256pp};
use crate::system::LinearSystem;

/// Runs simulated in lock-step by one kernel call.
pub const LANES: usize = 8;
/// Most runs in one call (per-run results take 40 bytes each).
pub const MAX_RUNS: u64 = 1 << 24;
/// Longest table of Tr h^τ(P̄).
pub const MAX_TRACE_TABLE: usize = 1 << 14;
/// Most bins of the interval test.
pub const MAX_BINS: usize = 1 << 12;
/// Longest run in steps (burn-in included).
pub const MAX_STEPS: u64 = 1 << 42;
/// Steps between two polls of the cancel flag within a window.
pub const CHECK_STEPS: u64 = 1 << 16;

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
    },
}

/// One closed-loop experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct GameConfig {
    /// Low-power arrival probability λ, in (0, 1).
    pub lam: f64,
    /// The online schedule's memory.
    pub design: OnlineDesign,
    /// The offline schedule's period (1 = high power), starting with a 1.
    pub offline: Vec<u8>,
    /// The attack (`None`: none). It runs in every window, online or not.
    pub attack: Option<Attack>,
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
    /// Windows tested (online windows, for a testing policy).
    pub tested: Vec<u64>,
    /// Tested windows with an alarm.
    pub alarms: Vec<u64>,
    /// Alarms that triggered the fall-back.
    pub fallbacks: Vec<u64>,
    /// Flag-ACKs that reached the sensor during the measured horizon (online or not).
    pub delivered: Vec<u64>,
}

const RULE_NONE: u8 = 0;
const RULE_FIRST_R: u8 = 1;
const RULE_MASK: u8 = 2;
const RULE_RANDOM: u8 = 3;

/// A Bernoulli draw from a 16-bit slice, exact to 2^-64 (see the module docs).
#[derive(Debug, Clone, Copy)]
struct Bern {
    hi: u64,
    lo: u64,
    always: bool,
}

const MASK48: u64 = (1 << 48) - 1;

impl Bern {
    fn new(p: f64) -> Self {
        let t = bernoulli_threshold(p);
        Bern {
            hi: t >> 48,
            lo: t & MASK48,
            always: p >= 1.0,
        }
    }

    #[inline(always)]
    fn draw(&self, slice: u64, rng: &mut Xoshiro256pp) -> bool {
        if slice != self.hi {
            (slice < self.hi) | self.always
        } else {
            self.always || (rng.next_u64() >> 16) < self.lo
        }
    }
}

/// The attacker's rule for genuine flags.
#[derive(Debug, Clone)]
enum Block {
    None,
    /// Blocked iff the counter is < r; counter modulo t.
    FirstR {
        r: u64,
        t: u64,
    },
    Mask(Vec<bool>),
    Random(Bern),
}

impl Block {
    fn of(attack: Option<&Attack>) -> Result<Block> {
        Ok(match attack.and_then(Attack::genuine_blocking) {
            None => Block::None,
            Some(Attack::Random { beta }) => Block::Random(Bern::new(*beta)),
            Some(a) => match a.as_first_r() {
                Some((r, t)) => Block::FirstR { r, t },
                None => Block::Mask(a.blocking_mask()?.into_owned()),
            },
        })
    }
}

/// Validated, precomputed form of a [`GameConfig`].
struct Plan<'a> {
    cfg: &'a GameConfig,
    traces: Vec<f64>,
    lam: Bern,
    mu: Bern,
    gamma: Bern,
    forging: bool,
    block: Block,
    z0: u64,
    /// Bin of each gap (gaps beyond the table read its last entry); empty without bins.
    bin_of: Vec<u16>,
    bins: usize,
}

impl GameConfig {
    /// Checks every field; the messages name the field.
    pub fn validate(&self) -> Result<()> {
        check_lam(self.lam)?;
        self.design.validate()?;
        if let Some(a) = &self.attack {
            a.validate()?;
        }
        if self.offline.is_empty() || self.offline[0] != 1 || self.offline.iter().any(|&g| g > 1) {
            return Err(Error::invalid(
                "offline",
                "must be a non-empty 0/1 pattern starting with 1",
            ));
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
        Ok(())
    }
}

impl<'a> Plan<'a> {
    fn new(sys: &LinearSystem, cfg: &'a GameConfig) -> Result<Self> {
        cfg.validate()?;
        let steps = cfg.burn_in + cfg.horizon;
        let len = (steps.min(MAX_TRACE_TABLE as u64 - 1) + 1) as usize;
        let traces = sys.h_traces(len - 1);
        let gamma = cfg.attack.as_ref().map_or(0.0, Attack::forging);
        let (bin_of, bins) = match &cfg.policy {
            Policy::Test {
                detector: Detector::Interval { edges, .. },
                ..
            } => {
                let last = *edges.last().unwrap() as usize;
                let mut table = vec![0u16; last + 1];
                let mut b = 0usize;
                for (g, slot) in table.iter_mut().enumerate().skip(1) {
                    while b + 1 < edges.len() && g as u64 >= edges[b + 1] {
                        b += 1;
                    }
                    *slot = b as u16;
                }
                (table, edges.len())
            }
            _ => (Vec::new(), 0),
        };
        Ok(Plan {
            cfg,
            traces,
            lam: Bern::new(cfg.lam),
            mu: Bern::new(cfg.design.mu),
            gamma: Bern::new(gamma),
            forging: gamma > 0.0,
            block: Block::of(cfg.attack.as_ref())?,
            z0: cfg.design.z0,
            bin_of,
            bins,
        })
    }
}

/// The state of a tile's runs.
struct Tile {
    rng: [Xoshiro256pp; LANES],
    tau: [usize; LANES],
    z: [u64; LANES],
    sigma: [u64; LANES],
    pending: [bool; LANES],
    flagged: [bool; LANES],
    gap: [usize; LANES],
    online: [bool; LANES],
    left: [u64; LANES],
    pos: [usize; LANES],
    count: [i64; LANES],
    bins: Vec<[u32; LANES]>,
    cost: [f64; LANES],
    window_cost: [f64; LANES],
    high: [u64; LANES],
    online_steps: [u64; LANES],
    delivered: [u64; LANES],
    tested: [u64; LANES],
    alarms: [u64; LANES],
    fallbacks: [u64; LANES],
}

impl Tile {
    fn new(plan: &Plan<'_>, index: u64) -> Self {
        let mut sm = SplitMix64::stream(plan.cfg.seed, index);
        let rng = std::array::from_fn(|_| Xoshiro256pp::from_splitmix(&mut sm));
        let offline = matches!(plan.cfg.policy, Policy::Offline);
        Tile {
            rng,
            tau: [0; LANES],
            z: [0; LANES],
            sigma: [0; LANES],
            // The paper's initial condition: high power at k = 1, as after a flag-ACK.
            pending: [true; LANES],
            flagged: [false; LANES],
            gap: [0; LANES],
            online: [!offline; LANES],
            left: [0; LANES],
            pos: [0; LANES],
            count: [0; LANES],
            bins: vec![[0; LANES]; plan.bins],
            cost: [0.0; LANES],
            window_cost: [0.0; LANES],
            high: [0; LANES],
            online_steps: [0; LANES],
            delivered: [0; LANES],
            tested: [0; LANES],
            alarms: [0; LANES],
            fallbacks: [0; LANES],
        }
    }

    /// `steps` steps of every lane, by the kernel instantiated for the plan's features.
    fn advance(&mut self, plan: &Plan<'_>, steps: u64) {
        let mu = plan.cfg.design.mu < 1.0;
        let bins = plan.bins > 0;
        macro_rules! go {
            ($rule:expr) => {
                match (mu, plan.forging, bins) {
                    (false, false, false) => {
                        self.kernel::<false, false, false, { $rule }>(plan, steps)
                    }
                    (false, false, true) => {
                        self.kernel::<false, false, true, { $rule }>(plan, steps)
                    }
                    (false, true, false) => {
                        self.kernel::<false, true, false, { $rule }>(plan, steps)
                    }
                    (false, true, true) => self.kernel::<false, true, true, { $rule }>(plan, steps),
                    (true, false, false) => {
                        self.kernel::<true, false, false, { $rule }>(plan, steps)
                    }
                    (true, false, true) => self.kernel::<true, false, true, { $rule }>(plan, steps),
                    (true, true, false) => self.kernel::<true, true, false, { $rule }>(plan, steps),
                    (true, true, true) => self.kernel::<true, true, true, { $rule }>(plan, steps),
                }
            };
        }
        match plan.block {
            Block::None => go!(RULE_NONE),
            Block::FirstR { .. } => go!(RULE_FIRST_R),
            Block::Mask(_) => go!(RULE_MASK),
            Block::Random(_) => go!(RULE_RANDOM),
        }
    }

    /// The step loop, branch-free except for the rare ties of the Bernoulli slices: `MU` (a
    /// memory-length draw), `FORGE` (forged flags), `BINS` (the interval test's histogram) and
    /// `RULE` (the attacker's blocking rule) are compile-time, so each plan runs only its code.
    #[inline(never)]
    fn kernel<const MU: bool, const FORGE: bool, const BINS: bool, const RULE: u8>(
        &mut self,
        plan: &Plan<'_>,
        steps: u64,
    ) {
        let offline = &plan.cfg.offline[..];
        let period = offline.len();
        let traces = &plan.traces[..];
        let last = traces.len() - 1;
        let bin_of = &plan.bin_of[..];
        let gap_last = bin_of.len().saturating_sub(1);
        let z0 = plan.z0;
        let (first_r, period_t, mask): (u64, u64, &[bool]) = match &plan.block {
            Block::FirstR { r, t } => (*r, *t, &[]),
            Block::Mask(m) => (0, m.len() as u64, &m[..]),
            _ => (0, 1, &[]),
        };
        let beta = match plan.block {
            Block::Random(b) => b,
            _ => Bern::new(0.0),
        };
        for _ in 0..steps {
            for l in 0..LANES {
                let rng = &mut self.rng[l];
                let w = rng.next_u64();
                let online = self.online[l];
                let pos = self.pos[l];
                let high = (online & self.pending[l]) | (!online & (offline[pos] != 0));
                let next_pos = pos + 1;
                self.pos[l] = if online | (next_pos == period) {
                    0
                } else {
                    next_pos
                };
                let arrive = high | plan.lam.draw(w & 0xffff, rng);
                // Masks instead of selects: the outcomes are coin flips, and a mispredicted branch
                // costs more than the whole step. `black_box` keeps LLVM from turning the
                // masked arithmetic back into branches.
                let keep = black_box(usize::from(!arrive).wrapping_neg()); // ones iff no arrival
                let tau = (self.tau[l] + 1) & keep;
                self.tau[l] = tau;
                self.window_cost[l] += traces[tau.min(last)];
                self.high[l] += u64::from(high);
                self.online_steps[l] += u64::from(online);
                let reset = black_box(u64::from(self.flagged[l]).wrapping_neg()); // ones iff flagged
                let z = (((self.z[l] + 1) & !reset) | (reset & 1)) & (keep as u64);
                self.z[l] = z;
                let mu_draw = if MU {
                    plan.mu.draw((w >> 16) & 0xffff, rng)
                } else {
                    true
                };
                let flag = (z > z0) | ((z == z0) & mu_draw);
                let sigma = self.sigma[l];
                let blocked = match RULE {
                    RULE_FIRST_R => sigma < first_r,
                    RULE_MASK => mask[sigma as usize],
                    RULE_RANDOM => beta.draw((w >> 32) & 0xffff, rng),
                    _ => false,
                };
                if RULE == RULE_FIRST_R || RULE == RULE_MASK {
                    let next = sigma + u64::from(flag);
                    self.sigma[l] = if next == period_t { 0 } else { next };
                }
                let forged = FORGE & !flag & plan.gamma.draw(w >> 48, rng);
                let delivered = (flag & !blocked) | forged;
                self.flagged[l] = flag;
                self.pending[l] = delivered;
                let gap = self.gap[l] + 1;
                self.delivered[l] += u64::from(delivered);
                let counted = delivered & online;
                self.count[l] += i64::from(counted);
                if BINS {
                    self.bins[bin_of[gap.min(gap_last)] as usize][l] += u32::from(counted);
                }
                self.gap[l] = gap & black_box(usize::from(!delivered).wrapping_neg());
            }
        }
    }

    /// The end of a window: the online lanes' tests and the mode switches; the window's test is
    /// counted in the results when `counted` (it ends after the burn-in).
    fn end_window(&mut self, plan: &Plan<'_>, counted: bool) {
        let c = u64::from(counted);
        for l in 0..LANES {
            self.cost[l] += self.window_cost[l];
            self.window_cost[l] = 0.0;
            if let Policy::Test {
                detector,
                harmful_at_most,
                fallback,
            } = &plan.cfg.policy
            {
                if self.online[l] {
                    let n = self.count[l];
                    let alarm = match detector {
                        Detector::Count { lo, hi } => n <= *lo || n >= *hi,
                        Detector::Interval {
                            expected, critical, ..
                        } => {
                            let x2: f64 = expected
                                .iter()
                                .zip(&self.bins)
                                .map(|(e, o)| {
                                    let d = f64::from(o[l]) - e;
                                    d * d / e
                                })
                                .sum();
                            x2 > *critical
                        }
                    };
                    self.tested[l] += c;
                    self.alarms[l] += c * u64::from(alarm);
                    if alarm && harmful_at_most.is_none_or(|b| n <= b) {
                        self.fallbacks[l] += c;
                        if *fallback > 0 {
                            self.online[l] = false;
                            self.left[l] = *fallback;
                            self.pos[l] = 0;
                        }
                    }
                } else {
                    self.left[l] -= 1;
                    if self.left[l] == 0 {
                        self.online[l] = true;
                    }
                }
            }
            self.count[l] = 0;
            for b in &mut self.bins {
                b[l] = 0;
            }
        }
    }

    /// Forgets the costs and rates the burn-in accumulated (the current window's flags stay: its
    /// test reads the whole window).
    fn start_measuring(&mut self) {
        self.cost = [0.0; LANES];
        self.window_cost = [0.0; LANES];
        self.high = [0; LANES];
        self.online_steps = [0; LANES];
        self.delivered = [0; LANES];
    }
}

fn run_tile(plan: &Plan<'_>, index: u64, cancel: &AtomicBool) -> Result<Tile> {
    let cfg = plan.cfg;
    let mut tile = Tile::new(plan, index);
    let chunked = |tile: &mut Tile, steps: u64| -> Result<()> {
        let mut left = steps;
        while left > 0 {
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            let n = left.min(CHECK_STEPS);
            tile.advance(plan, n);
            left -= n;
        }
        Ok(())
    };
    // Windows run from the first step; the measurement starts after the burn-in, which may end
    // inside a window.
    let total = cfg.burn_in + cfg.horizon;
    let mut at = 0u64;
    let mut measuring = cfg.burn_in == 0;
    while at < total {
        let end = (at + cfg.window).min(total);
        if !measuring && end > cfg.burn_in {
            chunked(&mut tile, cfg.burn_in - at)?;
            tile.start_measuring();
            measuring = true;
            chunked(&mut tile, end - cfg.burn_in)?;
        } else {
            chunked(&mut tile, end - at)?;
        }
        if end - at == cfg.window {
            tile.end_window(plan, end > cfg.burn_in);
        } else {
            for l in 0..LANES {
                tile.cost[l] += tile.window_cost[l];
            }
        }
        at = end;
    }
    Ok(tile)
}

impl LinearSystem {
    /// The closed-loop game Monte Carlo (see the [module docs](crate::game_mc)).
    pub fn simulate_game(&self, cfg: &GameConfig) -> Result<GameRuns> {
        self.simulate_game_with(cfg, &AtomicBool::new(false), &AtomicU64::new(0))
    }

    /// [`LinearSystem::simulate_game`] that stops with [`Error::Interrupted`] soon after
    /// `cancel` is set and adds finished runs to `progress`.
    pub fn simulate_game_with(
        &self,
        cfg: &GameConfig,
        cancel: &AtomicBool,
        progress: &AtomicU64,
    ) -> Result<GameRuns> {
        let plan = Plan::new(self, cfg)?;
        let tiles = cfg.runs.div_ceil(LANES as u64);
        let done: Vec<Tile> = (0..tiles)
            .into_par_iter()
            .map(|b| {
                let t = run_tile(&plan, b, cancel)?;
                progress.fetch_add(LANES as u64, Ordering::Relaxed);
                Ok(t)
            })
            .collect::<Result<Vec<_>>>()?;
        let runs = cfg.runs as usize;
        let h = cfg.horizon as f64;
        let mut out = GameRuns::default();
        for t in &done {
            for l in 0..LANES {
                if out.cost.len() == runs {
                    break;
                }
                out.cost.push(t.cost[l] / h);
                out.high_power.push(t.high[l] as f64 / h);
                out.online.push(t.online_steps[l] as f64 / h);
                out.tested.push(t.tested[l]);
                out.alarms.push(t.alarms[l]);
                out.fallbacks.push(t.fallbacks[l]);
                out.delivered.push(t.delivered[l]);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests;
