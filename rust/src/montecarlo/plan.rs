//! The validated, precomputed experiment ([`Plan`]) shared by all blocks, and which kernel takes
//! it.

use std::borrow::Cow;

use super::bitslice::{self, BsPlan};
use super::config::{McConfig, McSchedule, Mode, Protocol};
use super::kernel::{Params, SlicedThreshold};
use super::state::StateModel;
use super::{KernelFlags, MAX_HORIZON, MAX_RECORDED_RUNS};
use crate::attack::{longest_cyclic_run, Attack};
use crate::error::{Error, Result};
use crate::online::{check_lam, OnlineDesign};
use crate::rng::bernoulli_threshold;
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

/// The attack as a blocking mask over the attacker's flag counter (true = blocked), validated.
/// A mask of all ones is accepted: every flag is blocked and the runs estimate J_max.
///
/// Every kind of [`Attack`] is matched by name, so a new kind (blocking each flag
/// independently, forged flag-ACKs) fails to compile here until the Monte Carlo simulates it or
/// refuses it with `Error::invalid("attack", "... not supported by the Monte Carlo yet")`.
fn blocking_mask(attack: &Attack) -> Result<Cow<'_, [bool]>> {
    match attack {
        Attack::Periodic { .. } | Attack::Mask(_) => attack.blocking_mask(),
        Attack::Random { .. } | Attack::Injection { .. } => Err(Error::invalid(
            "attack",
            format!(
                "{attack}: not supported by the Monte Carlo yet (its costs are exact: j_attack)"
            ),
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
    Ok(())
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
    /// The blocking mask packed into words (`None`: no attacker).
    pub(super) mask: Option<Vec<u64>>,
    /// Flag-ACKs per period of the mask (1 without an attacker).
    pub(super) mask_len: u64,
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
}

impl Plan {
    /// Validates `cfg` (errors name the offending argument) and precomputes what the kernels
    /// need.
    pub(super) fn new(sys: &LinearSystem, cfg: &McConfig) -> Result<Self> {
        check_size(cfg)?;
        let mut plan = Plan::unscheduled(cfg);
        let mask = match &cfg.schedule {
            McSchedule::Offline { pattern } => {
                plan.schedule_offline(pattern, cfg)?;
                None
            }
            McSchedule::Online { z0, mu } => {
                plan.schedule_online(*z0, *mu)?;
                cfg.attack.as_ref().map(blocking_mask).transpose()?
            }
        };
        if let Some(mask) = &mask {
            plan.mask = Some(pack_mask(mask));
            plan.mask_len = mask.len() as u64;
        }
        let reach = max_tau(&cfg.schedule, mask.as_deref()).unwrap_or(u64::MAX);
        plan.bound = reach.min(cfg.horizon as u64);
        match cfg.mode {
            Mode::Covariance => plan.tr = trace_table(sys, plan.bound)?,
            Mode::State => plan.state = Some(StateModel::new(sys)?),
        }
        plan.bitslice = plan.bitslice_plan(mask.as_deref());
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
            protocol: cfg.protocol,
            bound: 0,
            tr: Vec::new(),
            state: None,
            bitslice: None,
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
    fn bitslice_plan(&self, mask: Option<&[bool]>) -> Option<BsPlan> {
        let depth = self.bound as usize;
        let memory = if self.mu_draw {
            self.z0.saturating_add(1)
        } else {
            self.fixed_memory
        };
        let mask_runs = mask.map(bitslice::mask_runs).unwrap_or_default();
        let fits = self.state.is_none()
            && depth <= bitslice::MAX_DEPTH
            && (mask.is_none() || memory <= bitslice::MAX_DEPTH as u64)
            && mask_runs.len() <= bitslice::MAX_MASK_RUNS;
        fits.then(|| BsPlan {
            lam_thr: self.lam_thr,
            mu_thr: self.mu_thr,
            // Memory lengths beyond the depth never trigger (τ <= depth); clamp them.
            z0: self.z0.min(depth as u64 + 1) as usize,
            fixed_memory: self.fixed_memory.min(depth as u64 + 1) as usize,
            pattern: self.pattern.clone(),
            mask_runs,
            mask_len: self.mask_len,
            tr: self.tr.clone(),
        })
    }

    /// The protocol paths the kernels need.
    pub(super) fn flags(&self) -> KernelFlags {
        KernelFlags {
            online: self.online,
            mu_draw: self.mu_draw,
            attack: self.mask.is_some(),
            protocol_a: self.protocol == Protocol::A,
        }
    }

    /// The lane kernels' constants.
    pub(super) fn params(&self) -> Params<'_> {
        let cap = self.horizon as u64 + 1;
        Params {
            lam: SlicedThreshold::new(self.lam_thr),
            mu: SlicedThreshold::new(self.mu_thr),
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
