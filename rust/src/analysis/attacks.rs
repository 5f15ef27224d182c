//! J under any attack, and the analysis of independent blocking: its β sweep and threshold.

use crate::attack::Attack;
use crate::error::{Error, Result};
use crate::renewal::independent::{self, ScaledTraces};
use crate::renewal::periodic::Segments;
use crate::schedule::Ratio;
use crate::schedule::{OnlineDesign, Walk};
use crate::system::LinearSystem;
use rayon::prelude::*;

impl LinearSystem {
    /// Stationary J under an attack: the paper's eq. (13)-(14) for "first r of t", the renewal
    /// form of [`periodic`](crate::renewal::periodic) for any mask and any μ, and
    /// [`independent`] for independent blocking; forged flags enter
    /// both through the memory walk ([`Walk`]). A periodic attack that blocks every flag-ACK and
    /// forges none is refused: its cost is [`LinearSystem::j_max`] (independent blocking with
    /// β = 1 gives that J_max).
    pub fn j_attack(&self, lam: f64, design: OnlineDesign, attack: &Attack) -> Result<f64> {
        attack.validate()?;
        let walk = Walk::new(lam, design, attack.forging())?;
        match attack.genuine_blocking() {
            None => self.j_random_walk(&walk, 0.0),
            Some(Attack::Random { beta }) => self.j_random_walk(&walk, *beta),
            Some(b) if b.blocks_every_flag() && walk.gamma > 0.0 => self.j_random_walk(&walk, 1.0),
            Some(b) => {
                b.check_lets_flags_through()?;
                Segments::for_walk(self, &walk, Segments::depth(b))?.j_attack(b)
            }
        }
    }

    fn j_random_walk(&self, walk: &Walk, beta: f64) -> Result<f64> {
        let cycle = independent::cycle(Some(&mut ScaledTraces::new(self, walk)), walk, beta)?;
        Ok(cycle.j())
    }

    /// J under independent blocking (with forged flags at probability `gamma`) at each β of
    /// `betas`, sharing the traces.
    pub fn j_random_sweep(
        &self,
        lam: f64,
        design: OnlineDesign,
        gamma: f64,
        betas: &[f64],
    ) -> Result<Vec<f64>> {
        let walk = Walk::new(lam, design, gamma)?;
        // In parallel over β, each worker with its own trace table: the table's entries do not
        // depend on how far it has grown, so the result does not depend on the split.
        betas
            .par_iter()
            .with_min_len(256)
            .map_init(
                || ScaledTraces::new(self, &walk),
                |traces, &b| Ok(independent::cycle(Some(traces), &walk, b)?.j()),
            )
            .collect()
    }

    /// The β at which independent blocking costs as much as the offline schedule for `ratio`:
    /// the root of J(β) = J_offline, by bisection (J increases with β). 0 when the online
    /// schedule does not beat the offline one even unattacked; 1 when even β = 1 (J_max) does
    /// not reach J_offline.
    pub fn beta_bar_random(&self, lam: f64, ratio: Ratio, design: OnlineDesign) -> Result<f64> {
        let j_off = self.j_offline(lam, ratio)?;
        let walk = Walk::new(lam, design, 0.0)?;
        let mut traces = ScaledTraces::new(self, &walk);
        let mut j =
            |b: f64| -> Result<f64> { Ok(independent::cycle(Some(&mut traces), &walk, b)?.j()) };
        if j(0.0)? >= j_off {
            return Ok(0.0);
        }
        if j(1.0)? < j_off {
            return Ok(1.0);
        }
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        while hi - lo > f64::EPSILON * hi {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if j(mid)? < j_off {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(Error::invalid("beta", "no threshold found"));
        }
        Ok(0.5 * (lo + hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper() -> LinearSystem {
        LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
    }

    #[test]
    fn random_blocking_runs_from_the_online_cost_to_j_max() {
        let sys = paper();
        let d = OnlineDesign::fixed(2).unwrap();
        let j = |b| sys.j_attack(0.5, d, &Attack::random(b).unwrap()).unwrap();
        let j_on = sys.j_online(0.5, d).unwrap();
        let j_max = sys.j_max(0.5).unwrap();
        assert!((j(0.0) - j_on).abs() < 1e-14 * j_on);
        assert!((j(1.0) - j_max).abs() < 1e-12 * j_max);
        let sweep = sys
            .j_random_sweep(0.5, d, 0.0, &[0.0, 0.2, 0.5, 0.8, 1.0])
            .unwrap();
        assert!(sweep.windows(2).all(|w| w[0] < w[1]), "{sweep:?}");
        assert_eq!(sweep[2], j(0.5));
    }

    #[test]
    fn forging_lowers_the_cost() {
        let sys = paper();
        let d = OnlineDesign::fixed(2).unwrap();
        let j = |g| {
            sys.j_attack(0.5, d, &Attack::injection(g, None).unwrap())
                .unwrap()
        };
        assert!(j(0.0) > j(0.1) && j(0.1) > j(0.5));
        // Forging every step keeps the sensor at high power: Tr P̄.
        assert!((j(1.0) - sys.pbar().trace()).abs() < 1e-14);
    }

    #[test]
    fn the_random_threshold_meets_the_offline_cost() {
        let sys = paper();
        let (lam, ratio) = (0.5, Ratio::new(1, 7).unwrap());
        let d = OnlineDesign::fixed(2).unwrap();
        let b = sys.beta_bar_random(lam, ratio, d).unwrap();
        let j = sys.j_attack(lam, d, &Attack::random(b).unwrap()).unwrap();
        let j_off = sys.j_offline(lam, ratio).unwrap();
        assert!(0.0 < b && b < 1.0);
        assert!((j - j_off).abs() < 1e-12 * j_off, "{j} vs {j_off}");
    }
}
