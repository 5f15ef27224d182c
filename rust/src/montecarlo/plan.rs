//! The validated, precomputed experiment ([`Plan`]) shared by all blocks, and which kernel takes
//! it.

use std::borrow::Cow;

use super::bitslice::{self, BsChannel, BsPlan, Prob};
use super::config::{McConfig, McSchedule, Mode, Protocol, TwoStateChannel};
use super::kernel::{Params, SlicedThreshold};
use super::state::StateModel;
use super::{KernelFlags, MAX_HORIZON, MAX_RECORDED_RUNS};
use crate::attack::{longest_cyclic_run, Attack};
use crate::chain::general::capped_attack_chain;
use crate::chain::stationary::gth;
use crate::error::{Error, Result};
use crate::montecarlo::rng::bernoulli_threshold;
use crate::schedule::{check_lam, OnlineDesign};
use crate::system::LinearSystem;

/// The largest holding time τ a run can reach (before capping by the horizon) under the
/// blocking mask `mask`; `None` if unbounded (every flag blocked).
pub(super) fn max_tau(schedule: &McSchedule, mask: Option<&[bool]>) -> Option<u64> {
    match schedule {
        McSchedule::Offline { pattern } => {
            let zeros: Vec<bool> = pattern.iter().map(|&g| g == 0).collect();
            Some(longest_cyclic_run(&zeros) as u64)
        }
        McSchedule::Online { z0, mu } => {
            let memory = if *mu < 1.0 { z0.saturating_add(1) } else { *z0 };
            let blocked_in_a_row = match mask {
                None => 0,
                Some(mask) if mask.iter().all(|&b| b) => return None,
                Some(mask) => longest_cyclic_run(mask) as u64,
            };
            Some(memory.saturating_mul(blocked_in_a_row + 1))
        }
    }
}

/// How the attacker treats the genuine flag-ACKs and whether it forges, validated; what
/// [`Plan`] records of an [`Attack`].
struct AttackPlan<'a> {
    /// The blocking mask over the attacker's flag counter (true = blocked), for a periodic
    /// blocking attack. A mask of all ones is accepted: every flag is blocked and the runs
    /// estimate J_max.
    mask: Option<Cow<'a, [bool]>>,
    /// β, for independent blocking.
    beta: Option<f64>,
    /// γ, for an injection.
    gamma: Option<f64>,
}

/// The attack as the Monte Carlo runs it. Every kind of [`Attack`] is matched by name, so a new
/// kind fails to compile here until the Monte Carlo simulates it or refuses it.
fn attack_plan(attack: &Attack) -> Result<AttackPlan<'_>> {
    attack.validate()?;
    match attack {
        Attack::Periodic { .. } | Attack::Mask(_) | Attack::Random { .. } => {
            blocking_plan(Some(attack))
        }
        Attack::Injection { gamma, block } => Ok(AttackPlan {
            gamma: Some(*gamma),
            ..blocking_plan(block.as_deref())?
        }),
    }
}

/// The plan of a blocking attack on the genuine flag-ACKs (`None`: no blocking).
fn blocking_plan(block: Option<&Attack>) -> Result<AttackPlan<'_>> {
    let none = AttackPlan {
        mask: None,
        beta: None,
        gamma: None,
    };
    match block {
        None => Ok(none),
        Some(b @ (Attack::Periodic { .. } | Attack::Mask(_))) => Ok(AttackPlan {
            mask: Some(b.blocking_mask()?),
            ..none
        }),
        Some(Attack::Random { beta }) => Ok(AttackPlan {
            beta: Some(*beta),
            ..none
        }),
        Some(Attack::Injection { .. }) => Err(Error::invalid(
            "block",
            "must be a blocking attack, not another injection",
        )),
    }
}

/// Packs a blocking mask into 64-bit words, flag-ACK i at bit i % 64 of word i / 64.
fn pack_mask(mask: &[bool]) -> Vec<u64> {
    let mut words = vec![0u64; mask.len().div_ceil(64)];
    for (i, &b) in mask.iter().enumerate() {
        words[i / 64] |= u64::from(b) << (i % 64);
    }
    words
}

/// Checks λ and the experiment's size: the horizon, the number of runs and, when recording,
/// that the per-run record fits.
fn check_size(cfg: &McConfig) -> Result<()> {
    match &cfg.channel {
        None => check_lam(cfg.lam)?,
        Some(ch) => check_channel(ch)?,
    }
    if cfg.channel.is_some() && cfg.mode != Mode::Covariance {
        return Err(Error::invalid(
            "mode",
            "must be covariance on a Markov channel (state mode takes the i.i.d. channel only)",
        ));
    }
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
    Ok(())
}

/// Checks a two-state channel: probabilities in [0, 1], and p + q > 0 (one closed class, so
/// the stationary law of the first state exists).
fn check_channel(ch: &TwoStateChannel) -> Result<()> {
    let probs = [("channel.p", ch.p), ("channel.q", ch.q)];
    let lows = [("channel.low[0]", ch.low[0]), ("channel.low[1]", ch.low[1])];
    for (name, x) in probs.into_iter().chain(lows) {
        if !(0.0..=1.0).contains(&x) {
            return Err(Error::invalid(name, format!("must lie in [0, 1], got {x}")));
        }
    }
    if ch.p + ch.q <= 0.0 {
        return Err(Error::invalid(
            "channel",
            "p = q = 0 has two closed classes (no stationary law for the first state)",
        ));
    }
    Ok(())
}

/// The bit-sliced kernel's draws of a two-state channel.
fn bs_channel(ch: &TwoStateChannel) -> BsChannel {
    BsChannel {
        low: ch.low.map(Prob::new),
        switch: [Prob::new(ch.p), Prob::new(ch.q)],
        start_bad: Prob::new(ch.p / (ch.p + ch.q)),
    }
}

/// The low-power arrival probability the thermometer's top level is chosen from: λ, or on a
/// Markov channel its stationary mean (the choice only sets the speed).
fn mean_lam(cfg: &McConfig) -> f64 {
    match &cfg.channel {
        None => cfg.lam,
        Some(ch) => {
            let good = ch.q / (ch.p + ch.q);
            good * ch.low[0] + (1.0 - good) * ch.low[1]
        }
    }
}

/// Checks an offline pattern: non-empty, of zeros and ones, starting with a one.
fn check_pattern(pattern: &[u8]) -> Result<()> {
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
    Ok(())
}

/// `tr[τ]` = Tr h^τ(P̄) for τ = 0..=bound, refused if any is NaN.
fn trace_table(sys: &LinearSystem, bound: u64) -> Result<Vec<f64>> {
    let tr = sys.h_traces(bound as usize);
    if tr.len() != bound as usize + 1 || tr.iter().any(|t| t.is_nan()) {
        return Err(Error::invalid("sys", "Tr h^i(P̄) is not a number"));
    }
    Ok(tr)
}

/// Largest fraction of steps with τ at or above a thermometer's top level for which the
/// bit-sliced kernel keeps that level (about one run in 256 per step, tracked one by one).
const DEEP_TAIL: f64 = 1.0 / 256.0;
/// Beyond this fraction of steps with τ >= [`bitslice::MAX_DEPTH`], the one-by-one tracking
/// would cost more than the lane kernels.
const DEEP_TAIL_MAX: f64 = 1.0 / 8.0;
/// Largest chain explored to estimate the law of τ for [`deep_level_for`].
const DEEP_CHAIN_STATES: u64 = 50_000;

/// The thermometer level at which the bit-sliced kernel stops counting τ level by level under
/// an attack that blocks or forges at random (a power of two, at least the memory): the
/// smallest whose share of steps at or above it, in the stationary law of the general attack
/// chain capped at [`bitslice::MAX_DEPTH`], is at most [`DEEP_TAIL`]. `None` when even the
/// deepest level leaves more than [`DEEP_TAIL_MAX`] there (the lane kernels are faster). The
/// choice only sets the speed: runs beyond the level are tracked exactly.
fn deep_level_for(cfg: &McConfig, memory: usize, period: u64) -> Option<usize> {
    let levels = [2usize, 4, 8, 16, bitslice::MAX_DEPTH];
    let deepest = bitslice::MAX_DEPTH;
    let states = (deepest as u64 + 1) * (memory as u64 + 2) * period;
    let (McSchedule::Online { z0, mu }, Some(attack)) = (&cfg.schedule, &cfg.attack) else {
        return Some(deepest);
    };
    let tails = if states <= DEEP_CHAIN_STATES {
        tau_tails(mean_lam(cfg), *z0, *mu, attack)
    } else {
        None
    };
    let Some(tail) = tails else {
        return Some(deepest);
    };
    levels
        .iter()
        .copied()
        .filter(|&d| d >= memory)
        .find(|&d| tail[d] <= DEEP_TAIL)
        .or((tail[deepest] <= DEEP_TAIL_MAX).then_some(deepest))
}

/// P(τ >= d) for d = 0..=[`bitslice::MAX_DEPTH`] in the stationary law of the attack chain
/// (holding times above the cap folded into it); `None` if the chain cannot be solved.
fn tau_tails(lam: f64, z0: u64, mu: f64, attack: &Attack) -> Option<Vec<f64>> {
    let cap = bitslice::MAX_DEPTH;
    let design = OnlineDesign::new(z0, mu).ok()?;
    let (states, csr) = capped_attack_chain(lam, design, attack, Some(cap as u64)).ok()?;
    let pi = gth(&csr).ok()?;
    let mut at = vec![0.0; cap + 1];
    for (s, p) in states.iter().zip(&pi) {
        at[(s.tau as usize).min(cap)] += p;
    }
    let mut tail = vec![0.0; cap + 2];
    for d in (0..=cap).rev() {
        tail[d] = tail[d + 1] + at[d];
    }
    tail.truncate(cap + 1);
    Some(tail)
}

/// The validated, precomputed experiment shared by all blocks.
pub(super) struct Plan {
    /// Steps per run.
    pub(super) horizon: usize,
    /// Number of runs.
    pub(super) runs: u64,
    /// The experiment's seed.
    pub(super) seed: u64,
    /// Keep each run's delivered flag-ACK count ([`McConfig::record_runs`]).
    pub(super) record_runs: bool,
    /// The channel's Bernoulli threshold ⌊λ 2^64⌋ on low power.
    pub(super) lam_thr: u64,
    /// The online schedule (else the offline pattern).
    pub(super) online: bool,
    /// A μ draw every step (0 < μ < 1).
    pub(super) mu_draw: bool,
    /// The threshold ⌊μ 2^64⌋ of the z0-bit memory.
    pub(super) mu_thr: u64,
    /// The short memory length z0.
    z0: u64,
    /// Memory length when there is no draw: z0 for μ = 1, z0+1 for μ = 0.
    pub(super) fixed_memory: u64,
    /// The offline pattern (empty online).
    pub(super) pattern: Vec<u8>,
    /// Ones among the first `horizon` steps of the offline pattern.
    pub(super) offline_high: u64,
    /// The blocking mask packed into words (`None`: no mask blocking).
    pub(super) mask: Option<Vec<u64>>,
    /// Flag-ACKs per period of the mask (1 without one).
    pub(super) mask_len: u64,
    /// The threshold ⌊β 2^64⌋ of independent blocking (`None`: none).
    pub(super) beta_thr: Option<u64>,
    /// The threshold ⌊γ 2^64⌋ of forging (`None`: no forging).
    pub(super) gamma_thr: Option<u64>,
    /// How the flag-ACK travels.
    pub(super) protocol: Protocol,
    /// Largest reachable τ, capped by the horizon.
    pub(super) bound: u64,
    /// `tr[τ]` = Tr h^τ(P̄), τ = 0..=bound (covariance mode; empty in state mode).
    pub(super) tr: Vec<f64>,
    /// The error recursions (state mode; `None` in covariance mode).
    pub(super) state: Option<StateModel>,
    /// The bit-sliced covariance kernel's plan, when the plan fits it (shallow τ bound, short
    /// memory, few runs of ones in the mask); else the lane kernels run.
    pub(super) bitslice: Option<BsPlan>,
    /// Whether the channel is a two-state Markov one (only the bit-sliced kernel simulates it).
    pub(super) markov: bool,
}

impl Plan {
    /// Validates `cfg` (errors name the offending argument) and precomputes what the kernels
    /// need.
    pub(super) fn new(sys: &LinearSystem, cfg: &McConfig) -> Result<Self> {
        check_size(cfg)?;
        let mut plan = Plan::unscheduled(cfg);
        let attack = match &cfg.schedule {
            McSchedule::Offline { pattern } => {
                plan.schedule_offline(pattern, cfg)?;
                None
            }
            McSchedule::Online { z0, mu } => {
                plan.schedule_online(*z0, *mu)?;
                cfg.attack.as_ref().map(attack_plan).transpose()?
            }
        };
        let mask = attack.as_ref().and_then(|a| a.mask.as_deref());
        if let Some(mask) = mask {
            plan.mask = Some(pack_mask(mask));
            plan.mask_len = mask.len() as u64;
        }
        let beta = attack.as_ref().and_then(|a| a.beta);
        plan.beta_thr = beta.map(bernoulli_threshold);
        plan.gamma_thr = attack
            .as_ref()
            .and_then(|a| a.gamma)
            .map(bernoulli_threshold);
        // Independent blocking with β > 0 can block any number of flags in a row.
        let reach = match beta {
            Some(beta) if beta > 0.0 => None,
            _ => max_tau(&cfg.schedule, mask),
        };
        plan.bound = reach.unwrap_or(u64::MAX).min(cfg.horizon as u64);
        match cfg.mode {
            Mode::Covariance => plan.tr = trace_table(sys, plan.bound)?,
            Mode::State => plan.state = Some(StateModel::new(sys)?),
        }
        plan.bitslice = plan.bitslice_plan(cfg, mask);
        Ok(plan)
    }

    /// The plan of `cfg` before its schedule, attack, τ bound and tables are filled in.
    fn unscheduled(cfg: &McConfig) -> Self {
        Plan {
            horizon: cfg.horizon,
            runs: cfg.runs,
            seed: cfg.seed,
            record_runs: cfg.record_runs,
            lam_thr: bernoulli_threshold(cfg.lam),
            online: false,
            mu_draw: false,
            mu_thr: 0,
            z0: 0,
            fixed_memory: 0,
            pattern: Vec::new(),
            offline_high: 0,
            mask: None,
            mask_len: 1,
            beta_thr: None,
            gamma_thr: None,
            protocol: cfg.protocol,
            bound: 0,
            tr: Vec::new(),
            state: None,
            bitslice: None,
            markov: cfg.channel.is_some(),
        }
    }

    /// Checks and records the offline schedule `pattern` (which sends no flag-ACK, so `cfg`
    /// must have no attack).
    fn schedule_offline(&mut self, pattern: &[u8], cfg: &McConfig) -> Result<()> {
        check_pattern(pattern)?;
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
        self.offline_high = full as u64 * ones + head;
        self.pattern = pattern.to_vec();
        Ok(())
    }

    /// Checks and records the online schedule: z0-bit memory with probability μ, else z0+1.
    fn schedule_online(&mut self, z0: u64, mu: f64) -> Result<()> {
        OnlineDesign::new(z0, mu)?;
        self.online = true;
        self.z0 = z0;
        // μ = 1 and μ = 0 are deterministic memory lengths: no draw.
        self.mu_draw = mu > 0.0 && mu < 1.0;
        self.mu_thr = bernoulli_threshold(mu);
        self.fixed_memory = if mu >= 1.0 { z0 } else { z0.saturating_add(1) };
        Ok(())
    }

    /// The bit-sliced kernel's plan if this experiment fits it.
    fn bitslice_plan(&self, cfg: &McConfig, mask: Option<&[bool]>) -> Option<BsPlan> {
        let memory = if self.mu_draw {
            self.z0.saturating_add(1)
        } else {
            self.fixed_memory
        };
        let attack = self.mask.is_some() || self.beta_thr.is_some();
        let mask_runs = mask.map(bitslice::mask_runs).unwrap_or_default();
        let mut depth = self.bound as usize;
        let mut deep_level = 0;
        let fits = self.state.is_none()
            && (!attack || memory <= bitslice::MAX_DEPTH as u64)
            && mask_runs.len() <= bitslice::MAX_MASK_RUNS;
        // The attacks the Monte Carlo added later (independent blocking, forging) may hold
        // the holding time in a shallower thermometer, with the rare runs beyond it tracked
        // exactly one by one; the others keep the exact thermometer of their bound.
        let new_kind = self.beta_thr.is_some() || self.gamma_thr.is_some();
        if fits && new_kind && memory <= bitslice::MAX_DEPTH as u64 {
            // On a Markov channel no lane kernel is faster (none takes it): keep the deepest
            // level even when many runs pass it.
            let fallback = cfg.channel.map(|_| bitslice::MAX_DEPTH);
            match deep_level_for(cfg, memory as usize, self.mask_len).or(fallback) {
                Some(level) if level < depth => (depth, deep_level) = (level, level),
                Some(_) => {}
                None => return None,
            }
        }
        (fits && depth <= bitslice::MAX_DEPTH).then(|| BsPlan {
            lam_thr: self.lam_thr,
            mu_thr: self.mu_thr,
            beta_thr: self.beta_thr.unwrap_or(0),
            gamma_thr: self.gamma_thr.unwrap_or(0),
            // Memory lengths beyond the depth never trigger (τ <= depth); clamp them.
            z0: self.z0.min(depth as u64 + 1) as usize,
            fixed_memory: self.fixed_memory.min(depth as u64 + 1) as usize,
            pattern: self.pattern.clone(),
            mask_runs,
            mask_len: self.mask_len,
            deep_level,
            tr: self.tr[..=depth.min(self.tr.len().saturating_sub(1))].to_vec(),
            channel: cfg.channel.as_ref().map(bs_channel),
        })
    }

    /// The protocol paths the kernels need.
    pub(super) fn flags(&self) -> KernelFlags {
        KernelFlags {
            online: self.online,
            mu_draw: self.mu_draw,
            attack: self.mask.is_some() || self.beta_thr.is_some(),
            protocol_a: self.protocol == Protocol::A,
            random_block: self.beta_thr.is_some(),
            forge: self.gamma_thr.is_some(),
        }
    }

    /// The lane kernels' constants.
    pub(super) fn params(&self) -> Params<'_> {
        let cap = self.horizon as u64 + 1;
        Params {
            lam: SlicedThreshold::new(self.lam_thr),
            mu: SlicedThreshold::new(self.mu_thr),
            beta: SlicedThreshold::new(self.beta_thr.unwrap_or(0)),
            gamma: SlicedThreshold::new(self.gamma_thr.unwrap_or(0)),
            // Zero counts never exceed the horizon, so memory lengths beyond it are all alike;
            // the clamp keeps every lane value below 2^63 (signed vector compares are exact).
            z0: self.z0.min(cap),
            long_memory: self.z0.min(cap) + 1,
            fixed_memory: self.fixed_memory.min(cap),
            mask: self.mask.as_deref().unwrap_or(&[0]),
            mask_len: self.mask_len,
            pattern: if self.pattern.is_empty() {
                &[1]
            } else {
                &self.pattern
            },
            max_tau: self.bound,
        }
    }
}
