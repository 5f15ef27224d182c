//! The validated, precomputed experiment ([`Plan`]) shared by all blocks, and which kernel takes
//! it.

use super::bitslice::{self, BsPlan};
use super::config::{McConfig, McSchedule, Mode, Protocol};
use super::kernel::Params;
use super::state::StateModel;
use super::{MAX_HORIZON, MAX_RECORDED_RUNS, SLICE_BITS};
use crate::error::{check_lam, check_mu, Error, Result};
use crate::riccati::LinearSystem;
use crate::rng::bernoulli_threshold;

/// Longest run of `true` in the cyclic sequence (`len` if all are true).
pub(super) fn longest_cyclic_run(v: &[bool]) -> usize {
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
pub(super) fn max_tau(schedule: &McSchedule, attack: Option<&[bool]>) -> Option<u64> {
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
pub(super) struct Plan {
    pub(super) horizon: usize,
    pub(super) runs: u64,
    pub(super) seed: u64,
    /// Keep each run's delivered flag-ACK count ([`McConfig::record_runs`]).
    pub(super) record_runs: bool,
    pub(super) lam_thr: u64,
    pub(super) online: bool,
    pub(super) mu_draw: bool,
    pub(super) mu_thr: u64,
    z0: u64,
    /// Memory length when there is no draw: z0 for μ = 1, z0+1 for μ = 0.
    pub(super) l_fixed: u64,
    pub(super) pattern: Vec<u8>,
    /// Ones among the first `horizon` steps of the offline pattern.
    pub(super) offline_high: u64,
    pub(super) mask: Option<Vec<u64>>,
    pub(super) mask_len: u64,
    pub(super) protocol: Protocol,
    /// Largest reachable τ, capped by the horizon.
    pub(super) bound: u64,
    /// tr[τ] = Tr h^τ(P̄), τ = 0..=bound (covariance mode; empty in state mode).
    pub(super) tr: Vec<f64>,
    pub(super) state: Option<StateModel>,
    /// The bit-sliced covariance kernel's plan, when the plan fits it (shallow τ bound, short
    /// memory, few runs of ones in the mask); else the lane kernels run.
    pub(super) bitslice: Option<BsPlan>,
}

impl Plan {
    pub(super) fn new(sys: &LinearSystem, cfg: &McConfig) -> Result<Self> {
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
                if *z0 < 1 {
                    return Err(Error::invalid(
                        "z0",
                        format!("must be at least 1, got {z0}"),
                    ));
                }
                check_mu(*mu)?;
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
    pub(super) fn flags(&self) -> (bool, bool, bool, bool) {
        (
            self.online,
            self.mu_draw,
            self.mask.is_some(),
            self.protocol == Protocol::A,
        )
    }

    pub(super) fn params(&self) -> Params<'_> {
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
