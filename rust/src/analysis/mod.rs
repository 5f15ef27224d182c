//! The crate's front door: every quantity of the analysis as a method of [`LinearSystem`].
//!
//! A system and the channel's λ give P̄ and the costs J of both schedules; an online design
//! ([`OnlineDesign`], from [`design_online`](crate::schedule::design_online) or given) and an
//! [`Attack`] give the attacked cost, the β sweep, both thresholds β̄ and the sensor's decision;
//! a [`Schedule`] gives exact finite-horizon curves and the Monte Carlo of the protocol.
//!
//! `impl LinearSystem` is split by method family: the model's own methods (construction, P̄, the
//! traces, the Stein solve) are in [`crate::system`]; every quantity computed from them is here,
//! one file per family: costs, thresholds, decisions and curves in this file, the attacked costs
//! in `attacks`, the Monte Carlo entries (protocol and game) in `simulate`.
//!
//! ```
//! use fakeack::{Attack, LinearSystem, OnlineDesign, Ratio};
//!
//! let sys = LinearSystem::scalar(1.2, 0.7, 0.8, 0.8)?;
//! let (lam, ratio) = (0.5, Ratio::new(1, 7)?);
//! let design = fakeack::design_online(lam, ratio)?;
//! assert_eq!(design, OnlineDesign::fixed(2)?);
//! let j_off = sys.j_offline(lam, ratio)?;
//! let j_on = sys.j_online(lam, design)?;
//! let j_att = sys.j_attack(lam, design, &Attack::periodic(1, 5)?)?;
//! assert!(j_on < j_att && j_att < j_off);
//! # Ok::<(), fakeack::Error>(())
//! ```

mod attacks;
mod simulate;

pub use crate::renewal::rates::{flag_rates, FlagRates};

use crate::attack::Attack;
use crate::chain::general::capped_attack_chain;
use crate::chain::transient;
use crate::chain::AttackChain;
use crate::error::{Error, Result};
use crate::montecarlo::McSchedule;
use crate::renewal::periodic::{self, tau_needed, Segments};
use crate::renewal::sweep::{self, Sweep};
use crate::schedule::{self, offline_schedule, Ratio};
use crate::schedule::{check_lam, OnlineDesign};
use crate::system::LinearSystem;

/// The sensor's power schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Schedule {
    /// The optimal offline schedule for an energy ratio (Theorem 3.1, Model note 1): it ignores
    /// ACKs, so no attack affects it.
    Offline(Ratio),
    /// The ACK-based online schedule.
    Online(OnlineDesign),
}

impl Schedule {
    /// The Monte Carlo's form of the schedule (an offline schedule as one explicit period).
    pub fn to_monte_carlo(&self) -> Result<McSchedule> {
        Ok(match self {
            Schedule::Offline(ratio) => McSchedule::Offline {
                pattern: offline_schedule(*ratio)?,
            },
            Schedule::Online(d) => McSchedule::Online { z0: d.z0, mu: d.mu },
        })
    }
}

/// The attacker threshold β̄ in its two definitions (see [`LinearSystem::beta_bar`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BetaBar {
    /// Smallest r/t in lowest terms with t <= t_max and J(r, t) >= J_offline, as (r, t); `None`
    /// if no such attack exists.
    pub finite: Option<(u32, u32)>,
    /// The β at which the large-period limit J_∞(β) equals J_offline.
    pub limit: f64,
    /// J of the optimal offline schedule.
    pub j_offline: f64,
    /// J of the online schedule without attack.
    pub j_online: f64,
    /// J with every flag-ACK blocked (`inf` when (1-λ) ρ(A)² >= 1).
    pub j_max: f64,
}

/// The sensor's choice against an attacker of budget β (Sec. IV-C).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decision {
    /// True: keep the online schedule; false: switch to the offline one.
    pub online: bool,
    /// The large-period threshold the decision compares β with.
    pub beta_bar: f64,
    /// Worst-case online cost at budget β (the large-period limit J_∞(β)).
    pub j_online_attacked: f64,
    /// J of the optimal offline schedule.
    pub j_offline: f64,
    /// J of the online schedule without attack.
    pub j_online: f64,
}

/// Result of [`LinearSystem::worst_mask`].
#[derive(Debug, Clone, PartialEq)]
pub struct MaskSearch {
    /// The most damaging mask found (true = blocked).
    pub mask: Vec<bool>,
    /// Its J.
    pub j: f64,
    /// J of the consecutive mask (the paper's "first r of t").
    pub j_consecutive: f64,
}

impl LinearSystem {
    /// J of the optimal offline schedule for energy ratio p/q (Theorem 3.1's proposition, with
    /// the block counts of Model note 1).
    pub fn j_offline(&self, lam: f64, ratio: Ratio) -> Result<f64> {
        check_lam(lam)?;
        let s0 = ratio.offline_blocks().s0;
        let w = self.checked_weighted_traces(1.0 - lam, s0 as u128 + 1, "ratio")?;
        schedule::j_offline(&w, lam, ratio)
    }

    /// J of the online schedule without attack (Theorem 4.5 of Han et al., Model note 2).
    pub fn j_online(&self, lam: f64, design: OnlineDesign) -> Result<f64> {
        check_lam(lam)?;
        design.validate()?;
        let w = self.checked_weighted_traces(1.0 - lam, design.z0 as u128 + 1, "z0")?;
        schedule::j_online(&w, lam, design)
    }

    /// J with every flag-ACK blocked: Σ_i λ a^i Tr h^i(P̄), by a Stein equation; `inf` when
    /// (1-λ) ρ(A)² >= 1 (Model note 5).
    pub fn j_max(&self, lam: f64) -> Result<f64> {
        schedule::j_max(self, lam)
    }

    /// Segments of the memory walk deep enough for `kmax` blocked flags in a row.
    fn segments(&self, lam: f64, design: OnlineDesign, kmax: u64) -> Result<Segments> {
        Segments::for_system(self, lam, design, kmax)
    }

    /// J in the large-period limit r, t → ∞ with r/t → β: the worst an attacker with budget β
    /// can do with the consecutive pattern.
    pub fn j_attack_limit(&self, lam: f64, design: OnlineDesign, beta: f64) -> Result<f64> {
        let seg = self.segments(lam, design, 0)?;
        periodic::j_limit(&seg, lam, self.j_max(lam)?, beta)
    }

    /// J at every β = r/t in lowest terms with 1 <= r < t <= t_max, in increasing β (a Farey
    /// sweep; each J in O(1) after O(t_max) set-up).
    pub fn beta_sweep(&self, lam: f64, design: OnlineDesign, t_max: u64) -> Result<Sweep> {
        let seg = self.segments(lam, design, t_max.saturating_sub(1))?;
        sweep::sweep(&seg, t_max)
    }

    /// Both thresholds β̄ against the offline cost for `ratio` (Sec. IV-C): the smallest r/t with
    /// t <= t_max whose J reaches J_offline, and the root of J_∞(β) = J_offline.
    pub fn beta_bar(
        &self,
        lam: f64,
        ratio: Ratio,
        design: OnlineDesign,
        t_max: u64,
    ) -> Result<BetaBar> {
        let j_offline = self.j_offline(lam, ratio)?;
        let seg = self.segments(lam, design, t_max.saturating_sub(1))?;
        let j_max = self.j_max(lam)?;
        Ok(BetaBar {
            finite: sweep::first_crossing(&seg, t_max, j_offline)?,
            limit: periodic::beta_limit_threshold(&seg, lam, j_max, j_offline),
            j_offline,
            j_online: self.j_online(lam, design)?,
            j_max,
        })
    }

    /// Keep the online schedule if its worst-case cost at budget `beta` (the large-period
    /// limit) stays below J_offline, else switch to the offline schedule (Sec. IV-C's rule).
    pub fn choose_schedule(
        &self,
        lam: f64,
        ratio: Ratio,
        design: OnlineDesign,
        beta: f64,
    ) -> Result<Decision> {
        let j_offline = self.j_offline(lam, ratio)?;
        let seg = self.segments(lam, design, 0)?;
        let j_max = self.j_max(lam)?;
        let j_online_attacked = periodic::j_limit(&seg, lam, j_max, beta)?;
        Ok(Decision {
            online: j_online_attacked < j_offline,
            beta_bar: periodic::beta_limit_threshold(&seg, lam, j_max, j_offline),
            j_online_attacked,
            j_offline,
            j_online: self.j_online(lam, design)?,
        })
    }

    /// The most damaging mask with `blocked` of `t` flag-ACKs blocked, by exhaustive search
    /// (t <= 24), beside the consecutive mask's J.
    pub fn worst_mask(
        &self,
        lam: f64,
        design: OnlineDesign,
        t: usize,
        blocked: usize,
    ) -> Result<MaskSearch> {
        let seg = self.segments(lam, design, t.saturating_sub(1) as u64)?;
        let (mask, j, j_consecutive) = periodic::worst_mask(&seg, t, blocked)?;
        Ok(MaskSearch {
            mask,
            j,
            j_consecutive,
        })
    }

    /// Exact E[Tr P_k], k = 1..=horizon, from the paper's initial condition, by propagating the
    /// protocol's state law (no sampling). An offline schedule takes no attack.
    pub fn expected_trace_curve(
        &self,
        lam: f64,
        schedule: Schedule,
        attack: Option<&Attack>,
        horizon: usize,
    ) -> Result<Vec<f64>> {
        check_lam(lam)?;
        match schedule {
            Schedule::Offline(ratio) => {
                if attack.is_some() {
                    return Err(offline_takes_no_attack());
                }
                let pattern = offline_schedule(ratio)?;
                let gap = pattern.iter().filter(|&&g| g == 0).count();
                let tr = self.checked_weighted_traces(1.0, gap as u128, "ratio")?;
                transient::offline(&tr, lam, &pattern, horizon)
            }
            Schedule::Online(design) => {
                let none = Attack::Mask(vec![false]);
                let attack = attack.unwrap_or(&none);
                // τ_k <= k - 1: a cap at the horizon is exact and bounds every attack's chain.
                let cap = Some(horizon as u64);
                let (states, csr) = capped_attack_chain(lam, design, attack, cap)?;
                let taus: Vec<u64> = states.iter().map(|s| s.tau).collect();
                let top = taus.iter().copied().max().unwrap_or(0);
                let tr = self.checked_weighted_traces(1.0, top as u128, "attack")?;
                transient::chain(&csr, &taus, &tr, horizon)
            }
        }
    }
}

fn offline_takes_no_attack() -> Error {
    Error::invalid(
        "attack",
        "an offline schedule ignores ACKs, so an attack has no effect",
    )
}

/// The paper's attack chain (τ, σ) for a fixed memory (μ = 1) and "first r of t" (Sec. IV-B).
pub fn attack_chain(lam: f64, z0: u64, attack: &Attack) -> Result<AttackChain> {
    let (r, t) = attack.as_first_r().ok_or_else(|| {
        Error::invalid(
            "attack",
            "the (τ, σ) chain models 'block the first r of every t'; use general_attack_chain for other masks",
        )
    })?;
    AttackChain::new(lam, z0, r, t)
}

/// Weighted traces a^τ Tr h^τ(P̄) that the structured attack cost needs (τ up to
/// (r + 1)(z0 + 1)).
pub fn traces_needed(design: OnlineDesign, attack: &Attack) -> u128 {
    tau_needed(design.z0, Segments::depth(attack))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::stationary;

    fn paper() -> LinearSystem {
        LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
    }

    #[test]
    fn attack_cost_matches_the_structured_chain() {
        // The facade's J against Σ π(τ, σ) Tr h^τ(P̄) with π from the structured stationary law.
        let sys = paper();
        for &(lam, z0, r, t) in &[(0.5, 2u64, 1u64, 5u64), (0.5, 2, 2, 3), (0.3, 3, 4, 7)] {
            let attack = Attack::periodic(r, t).unwrap();
            let chain = attack_chain(lam, z0, &attack).unwrap();
            let pi = stationary::structured(&chain).unwrap();
            let tr = sys.h_traces(chain.tau_max(0).max(z0 * (r + 1)) as usize + 1);
            let states = chain.states().unwrap();
            let expect: f64 = states
                .iter()
                .zip(&pi)
                .map(|(&(tau, _), p)| p * tr[tau as usize])
                .sum();
            let got = sys
                .j_attack(lam, OnlineDesign::fixed(z0).unwrap(), &attack)
                .unwrap();
            assert!((got - expect).abs() < 1e-12 * expect, "{got} vs {expect}");
            // The same attack written as a mask gives the same J.
            let mask = Attack::mask(attack.blocking_mask().unwrap().into_owned()).unwrap();
            let via_mask = sys
                .j_attack(lam, OnlineDesign::fixed(z0).unwrap(), &mask)
                .unwrap();
            assert!((via_mask - got).abs() < 1e-13 * got);
        }
    }

    #[test]
    fn beta_bar_brackets_the_offline_cost() {
        let sys = paper();
        let (lam, ratio) = (0.5, Ratio::new(1, 7).unwrap());
        let d = OnlineDesign::fixed(2).unwrap();
        let bar = sys.beta_bar(lam, ratio, d, 60).unwrap();
        let (r, t) = bar.finite.unwrap();
        let at = sys
            .j_attack(lam, d, &Attack::periodic(r as u64, t as u64).unwrap())
            .unwrap();
        assert!(at >= bar.j_offline);
        let at_limit = sys.j_attack_limit(lam, d, bar.limit).unwrap();
        assert!((at_limit - bar.j_offline).abs() < 1e-12 * bar.j_offline);
        let below = sys
            .choose_schedule(lam, ratio, d, bar.limit * 0.99)
            .unwrap();
        let above = sys
            .choose_schedule(lam, ratio, d, bar.limit * 1.01)
            .unwrap();
        assert!(below.online && !above.online);
        assert_eq!(below.beta_bar, bar.limit);
    }

    #[test]
    fn offline_schedules_take_no_attack() {
        let sys = paper();
        let sched = Schedule::Offline(Ratio::new(1, 7).unwrap());
        let a = Attack::periodic(1, 5).unwrap();
        let e = sys
            .expected_trace_curve(0.5, sched, Some(&a), 10)
            .unwrap_err();
        assert!(e.to_string().starts_with("attack:"), "{e}");
    }
}
