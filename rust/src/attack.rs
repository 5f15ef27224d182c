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
/// Further kinds of attack (blocking each flag independently, forging flag-ACKs) become new
/// variants; every consumer matches on the enum, so the compiler lists what each must handle.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
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

    /// Checks the attack's own parameters: `0 <= r < t` for [`Attack::Periodic`]; a mask is
    /// non-empty and no longer than [`MAX_MASK`]. A mask may block every flag-ACK (the Monte
    /// Carlo runs it; its stationary cost is J_max, which the analytic costs leave to
    /// `LinearSystem::j_max`, see [`Attack::blocks_every_flag`]).
    pub fn validate(&self) -> Result<()> {
        match self {
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

    /// True when no flag-ACK ever reaches the sensor (a mask of all ones). The holding time then
    /// grows without bound, and the cost is J_max.
    pub fn blocks_every_flag(&self) -> bool {
        self.blocked() == self.period()
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

    /// Period in flag-ACKs.
    pub fn period(&self) -> u64 {
        match self {
            Attack::Periodic { t, .. } => *t,
            Attack::Mask(m) => m.len() as u64,
        }
    }

    /// Blocked flag-ACKs per period.
    pub fn blocked(&self) -> u64 {
        match self {
            Attack::Periodic { r, .. } => *r,
            Attack::Mask(m) => m.iter().filter(|&&b| b).count() as u64,
        }
    }

    /// The budget β: the long-run fraction of flag-ACKs blocked.
    pub fn beta(&self) -> f64 {
        self.blocked() as f64 / self.period() as f64
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
        }
    }

    /// Longest run of consecutive blocked flag-ACKs, counted cyclically over periods. It bounds
    /// how many memory resets the detector can go through between two arrivals.
    pub fn longest_blocked_run(&self) -> u64 {
        match self {
            Attack::Periodic { r, .. } => *r,
            Attack::Mask(m) => longest_cyclic_run(m) as u64,
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
        }
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
