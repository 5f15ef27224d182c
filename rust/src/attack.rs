//! One model of an attack on the flag-ACKs, used by the analysis, the β sweep and the Monte Carlo.
//!
//! The attacker sees every flag-ACK the remote detector sends and keeps a counter σ of them,
//! modulo the attack's period; it blocks (Type B) or flips to an ordinary ACK (Type A) the ones its
//! pattern marks, and both types have the same statistics. "No attack" is `Option::<Attack>::None`
//! wherever an attack is optional.

use crate::error::{Error, Result};
use std::borrow::Cow;
use std::fmt;

/// Longest blocking mask (flag-ACKs per period) accepted; a mask is held one byte per flag-ACK.
pub const MAX_MASK: usize = 10_000_000;

/// An attack on the flag-ACKs.
///
/// Further kinds of attack become new variants; every consumer matches on the enum, so the
/// compiler lists what each must handle.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Attack {
    /// Block the first `r` of every `t` flag-ACKs: the paper's Algorithm 1, read as blocking r of
    /// t (Model note 3). `(2, 6)` is not `(1, 3)`: it blocks two flags in a row.
    Periodic {
        /// Blocked flag-ACKs per period, `0 <= r < t`.
        r: u64,
        /// Period in flag-ACKs, `t >= 1`.
        t: u64,
    },
    /// Block the flag-ACK counted σ in each period of `mask.len()` flags whenever `mask[σ]`.
    Mask(Vec<bool>),
    /// Block each flag-ACK independently with probability `beta`: a memoryless jammer with no
    /// counter.
    Random {
        /// Probability of blocking each flag-ACK, in [0, 1].
        beta: f64,
    },
    /// On every step on which the detector sends no flag-ACK, forge one with probability
    /// `gamma` (Type B: a forged flag packet; Type A: the ACK bit flipped to 1); the sensor then
    /// uses high power on the next step. `block`, if any, attacks the genuine flags.
    Injection {
        /// Probability of a forged flag-ACK on a step without a genuine one, in [0, 1].
        gamma: f64,
        /// A blocking attack on the genuine flag-ACKs (not itself an injection).
        block: Option<Box<Attack>>,
    },
}

impl Attack {
    /// The paper's attack, validated: block the first `r` of every `t` flag-ACKs.
    pub fn periodic(r: u64, t: u64) -> Result<Self> {
        let a = Attack::Periodic { r, t };
        a.validate()?;
        Ok(a)
    }

    /// Any periodic blocking mask, validated (non-empty, at most [`MAX_MASK`] long).
    pub fn mask(mask: Vec<bool>) -> Result<Self> {
        let a = Attack::Mask(mask);
        a.validate()?;
        Ok(a)
    }

    /// Independent blocking with probability `beta`, validated.
    pub fn random(beta: f64) -> Result<Self> {
        let a = Attack::Random { beta };
        a.validate()?;
        Ok(a)
    }

    /// Forged flag-ACKs with probability `gamma`, with an optional blocking attack, validated.
    pub fn injection(gamma: f64, block: Option<Attack>) -> Result<Self> {
        let a = Attack::Injection {
            gamma,
            block: block.map(Box::new),
        };
        a.validate()?;
        Ok(a)
    }

    /// Checks the attack's own parameters: `0 <= r < t` for [`Attack::Periodic`]; a mask is
    /// non-empty and no longer than [`MAX_MASK`]; probabilities lie in [0, 1]; an injection's
    /// blocking attack is not itself an injection. A mask may block every flag-ACK (the Monte
    /// Carlo runs it; its stationary cost is J_max, which the analytic costs leave to
    /// `LinearSystem::j_max`, see [`Attack::blocks_every_flag`]).
    pub fn validate(&self) -> Result<()> {
        match self {
            Attack::Random { beta } => check_probability("beta", *beta),
            Attack::Injection { gamma, block } => {
                check_probability("gamma", *gamma)?;
                match block.as_deref() {
                    None => Ok(()),
                    Some(Attack::Injection { .. }) => Err(Error::invalid(
                        "block",
                        "must be a blocking attack, not another injection",
                    )),
                    Some(b) => b.validate(),
                }
            }
            Attack::Periodic { r, t } => {
                if *t < 1 {
                    return Err(Error::invalid("t", format!("must be at least 1, got {t}")));
                }
                if r >= t {
                    return Err(Error::invalid(
                        "r",
                        format!("must be smaller than t = {t}, got r = {r}"),
                    ));
                }
                Ok(())
            }
            Attack::Mask(m) => {
                if m.is_empty() {
                    return Err(Error::invalid("mask", "must not be empty"));
                }
                if m.len() > MAX_MASK {
                    return Err(Error::TooLarge {
                        arg: "mask".into(),
                        requested: m.len() as u128,
                        limit: MAX_MASK as u128,
                    });
                }
                Ok(())
            }
        }
    }

    /// True when no genuine flag-ACK ever reaches the sensor (a mask of all ones, or random
    /// blocking with β = 1) and none is forged: the holding time grows without bound, and the
    /// cost is J_max.
    pub fn blocks_every_flag(&self) -> bool {
        match self {
            Attack::Random { beta } => *beta == 1.0,
            Attack::Injection { .. } => false,
            _ => self.blocked() == self.period(),
        }
    }

    /// The probability γ of a forged flag-ACK per step without a genuine one (0 unless an
    /// injection).
    pub fn forging(&self) -> f64 {
        match self {
            Attack::Injection { gamma, .. } => *gamma,
            _ => 0.0,
        }
    }

    /// The attack on the genuine flag-ACKs: the attack itself, an injection's `block`, or
    /// `None` for an injection that blocks nothing.
    pub fn genuine_blocking(&self) -> Option<&Attack> {
        match self {
            Attack::Injection { block, .. } => block.as_deref(),
            other => Some(other),
        }
    }

    /// The refusal that the analytic costs give for an attack that blocks every flag-ACK.
    pub fn check_lets_flags_through(&self) -> Result<()> {
        if self.blocks_every_flag() {
            return Err(Error::invalid(
                "mask",
                "blocks every flag-ACK; its cost is J_max (LinearSystem::j_max)",
            ));
        }
        Ok(())
    }

    /// Period in flag-ACKs of a periodic blocking attack (1 for the others, whose blocking does
    /// not depend on a counter).
    pub fn period(&self) -> u64 {
        match self {
            Attack::Periodic { t, .. } => *t,
            Attack::Mask(m) => m.len() as u64,
            _ => 1,
        }
    }

    /// Blocked flag-ACKs per period of a periodic blocking attack (0 for the others).
    pub fn blocked(&self) -> u64 {
        match self {
            Attack::Periodic { r, .. } => *r,
            Attack::Mask(m) => m.iter().filter(|&&b| b).count() as u64,
            _ => 0,
        }
    }

    /// The budget β: the long-run fraction of genuine flag-ACKs blocked.
    pub fn beta(&self) -> f64 {
        match self {
            Attack::Random { beta } => *beta,
            Attack::Injection { block, .. } => block.as_deref().map_or(0.0, Attack::beta),
            _ => self.blocked() as f64 / self.period() as f64,
        }
    }

    /// `Some((r, t))` when the attack blocks the first `r` of every `t` flag-ACKs, written as a
    /// [`Attack::Periodic`] or as the equal mask `1^r 0^(t-r)`; the structured μ = 1 solver
    /// needs that form.
    pub fn as_first_r(&self) -> Option<(u64, u64)> {
        match self {
            Attack::Periodic { r, t } => Some((*r, *t)),
            Attack::Mask(m) => {
                let r = m.iter().take_while(|&&b| b).count();
                m[r..]
                    .iter()
                    .all(|&b| !b)
                    .then_some((r as u64, m.len() as u64))
            }
            _ => None,
        }
    }

    /// One period as an explicit mask (true = blocked). Refused for a period over [`MAX_MASK`].
    pub fn blocking_mask(&self) -> Result<Cow<'_, [bool]>> {
        self.validate()?;
        match self {
            Attack::Periodic { r, t } => {
                if *t > MAX_MASK as u64 {
                    return Err(Error::TooLarge {
                        arg: "t".into(),
                        requested: *t as u128,
                        limit: MAX_MASK as u128,
                    });
                }
                let mut m = vec![false; *t as usize];
                m[..*r as usize].fill(true);
                Ok(Cow::Owned(m))
            }
            Attack::Mask(m) => Ok(Cow::Borrowed(m)),
            _ => Err(Error::invalid(
                "attack",
                format!("{self} has no periodic blocking mask"),
            )),
        }
    }

    /// Longest run of consecutive blocked flag-ACKs, counted cyclically over periods. It bounds
    /// how many memory resets the detector can go through between two arrivals.
    pub fn longest_blocked_run(&self) -> u64 {
        match self {
            Attack::Periodic { r, .. } => *r,
            Attack::Mask(m) => longest_cyclic_run(m) as u64,
            Attack::Random { beta } if *beta == 0.0 => 0,
            Attack::Random { .. } => u64::MAX,
            Attack::Injection { block, .. } => {
                block.as_deref().map_or(0, Attack::longest_blocked_run)
            }
        }
    }
}

impl fmt::Display for Attack {
    /// `block 1 of every 5 flag-ACKs` or `block mask 1101000`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Attack::Periodic { r, t } => write!(f, "block {r} of every {t} flag-ACKs"),
            Attack::Mask(m) if m.len() <= 64 => {
                let bits: String = m.iter().map(|&b| if b { '1' } else { '0' }).collect();
                write!(f, "block mask {bits}")
            }
            Attack::Mask(m) => write!(
                f,
                "block {} of every {} flag-ACKs (mask)",
                self.blocked(),
                m.len()
            ),
            Attack::Random { beta } => write!(f, "block each flag-ACK with probability {beta}"),
            Attack::Injection { gamma, block } => {
                write!(f, "forge a flag-ACK with probability {gamma}")?;
                match block {
                    Some(b) => write!(f, ", and {b}"),
                    None => Ok(()),
                }
            }
        }
    }
}

fn check_probability(arg: &str, p: f64) -> Result<()> {
    if p.is_finite() && (0.0..=1.0).contains(&p) {
        Ok(())
    } else {
        Err(Error::invalid(arg, format!("must lie in [0, 1], got {p}")))
    }
}

/// Longest run of `true` in `mask` read cyclically (the length when every entry is true).
pub fn longest_cyclic_run(mask: &[bool]) -> usize {
    let n = mask.len();
    if mask.iter().all(|&b| b) {
        return n;
    }
    // Start just after a false entry so that no run wraps around the start.
    let start = mask.iter().position(|&b| !b).unwrap_or(0) + 1;
    let (mut best, mut run) = (0, 0);
    for i in 0..n {
        if mask[(start + i) % n] {
            run += 1;
            best = best.max(run);
        } else {
            run = 0;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periodic_is_validated() {
        assert!(Attack::periodic(1, 5).is_ok());
        assert!(Attack::periodic(0, 1).is_ok());
        let e = Attack::periodic(3, 3).unwrap_err();
        assert!(e.to_string().starts_with("r:"), "{e}");
        let e = Attack::periodic(0, 0).unwrap_err();
        assert!(e.to_string().starts_with("t:"), "{e}");
    }

    #[test]
    fn mask_is_validated() {
        assert!(Attack::mask(vec![true, false]).is_ok());
        assert!(Attack::mask(vec![]).is_err());
        let all = Attack::mask(vec![true, true]).unwrap();
        assert!(all.blocks_every_flag());
        let e = all.check_lets_flags_through().unwrap_err();
        assert!(e.to_string().starts_with("mask:"), "{e}");
        assert!(Attack::mask(vec![true, false])
            .unwrap()
            .check_lets_flags_through()
            .is_ok());
        assert!(!Attack::periodic(4, 5).unwrap().blocks_every_flag());
    }

    #[test]
    fn budget_and_period() {
        let a = Attack::periodic(2, 6).unwrap();
        assert_eq!((a.blocked(), a.period()), (2, 6));
        assert_eq!(a.beta(), 2.0 / 6.0);
        let m = Attack::mask(vec![true, false, true, false, false]).unwrap();
        assert_eq!((m.blocked(), m.period()), (2, 5));
        assert_eq!(m.beta(), 0.4);
    }

    #[test]
    fn first_r_form_is_recognised() {
        assert_eq!(Attack::periodic(2, 7).unwrap().as_first_r(), Some((2, 7)));
        let m = Attack::Mask(vec![true, true, false, false]);
        assert_eq!(m.as_first_r(), Some((2, 4)));
        assert_eq!(Attack::Mask(vec![false, false]).as_first_r(), Some((0, 2)));
        assert_eq!(Attack::Mask(vec![true, false, true]).as_first_r(), None);
        assert_eq!(Attack::Mask(vec![false, true]).as_first_r(), None);
    }

    #[test]
    fn explicit_mask_of_the_periodic_attack() {
        let a = Attack::periodic(2, 5).unwrap();
        assert_eq!(
            &*a.blocking_mask().unwrap(),
            &[true, true, false, false, false]
        );
        let a = Attack::Periodic {
            r: 1,
            t: MAX_MASK as u64 + 1,
        };
        assert!(matches!(a.blocking_mask(), Err(Error::TooLarge { .. })));
    }

    #[test]
    fn random_and_injection() {
        assert!(Attack::random(0.3).is_ok());
        for bad in [-0.1, 1.1, f64::NAN] {
            let e = Attack::random(bad).unwrap_err();
            assert!(e.to_string().starts_with("beta:"), "{e}");
            let e = Attack::injection(bad, None).unwrap_err();
            assert!(e.to_string().starts_with("gamma:"), "{e}");
        }
        let nested = Attack::injection(0.1, Some(Attack::injection(0.1, None).unwrap()));
        assert!(nested.unwrap_err().to_string().starts_with("block:"));
        let inj = Attack::injection(0.1, Some(Attack::periodic(1, 5).unwrap())).unwrap();
        assert_eq!(inj.forging(), 0.1);
        assert_eq!(inj.beta(), 0.2);
        assert_eq!(
            inj.genuine_blocking(),
            Some(&Attack::Periodic { r: 1, t: 5 })
        );
        assert!(!inj.blocks_every_flag() && Attack::random(1.0).unwrap().blocks_every_flag());
        assert!(Attack::random(0.5).unwrap().blocking_mask().is_err());
        assert_eq!(
            inj.to_string(),
            "forge a flag-ACK with probability 0.1, and block 1 of every 5 flag-ACKs"
        );
    }

    #[test]
    fn cyclic_runs() {
        assert_eq!(longest_cyclic_run(&[true, false, true, true]), 3);
        assert_eq!(longest_cyclic_run(&[false, true, true, false]), 2);
        assert_eq!(longest_cyclic_run(&[false, false]), 0);
        assert_eq!(longest_cyclic_run(&[false]), 0);
        assert_eq!(longest_cyclic_run(&[true, true]), 2);
        assert_eq!(
            Attack::Mask(vec![true, false, false, true]).longest_blocked_run(),
            2
        );
        assert_eq!(Attack::periodic(4, 9).unwrap().longest_blocked_run(), 4);
    }

    #[test]
    fn readable_display() {
        assert_eq!(
            Attack::periodic(1, 5).unwrap().to_string(),
            "block 1 of every 5 flag-ACKs"
        );
        assert_eq!(
            Attack::Mask(vec![true, false, true]).to_string(),
            "block mask 101"
        );
    }
}
