//! Flag-ACK rates under any attack: what the detector sends, what reaches the sensor, what is
//! forged. They set the sensor's high-power rate and so its energy per step.

use crate::attack::Attack;
use crate::error::Result;
use crate::renewal::independent;
use crate::renewal::periodic::Segments;
use crate::schedule::{OnlineDesign, Walk};

/// Flag-ACKs per step in the long run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlagRates {
    /// Genuine flag-ACKs sent by the remote detector.
    pub sent: f64,
    /// Flag-ACKs reaching the sensor, genuine or forged (the sensor cannot tell them apart): the
    /// sensor's high-power rate.
    pub delivered: f64,
    /// Forged flag-ACKs (part of `delivered`).
    pub forged: f64,
}

impl FlagRates {
    /// Genuine flag-ACKs blocked per step.
    pub fn blocked(&self) -> f64 {
        self.sent - (self.delivered - self.forged)
    }
}

/// Long-run flag-ACK rates under an attack (`None`: no attack). They depend on λ, the design and
/// the attack only, not on the system.
///
/// Forged flags come on steps without a genuine one, γ of them: forged = γ (1 - sent). With
/// every genuine flag blocked and nothing forged the detector sends λ u / (1 - u) per step: each
/// arrival starts a walk that flags u/(1-u) times on average, and arrivals come at rate λ.
pub fn flag_rates(lam: f64, design: OnlineDesign, attack: Option<&Attack>) -> Result<FlagRates> {
    let walk = Walk::new(lam, design, attack.map_or(0.0, Attack::forging))?;
    if let Some(a) = attack {
        a.validate()?;
    }
    let no_attack = Attack::Mask(vec![false]);
    let genuine = attack.map_or(Some(&no_attack), Attack::genuine_blocking);
    let (sent, genuine_delivered) = match genuine {
        None => {
            let c = independent::cycle(None, &walk, 0.0)?;
            (c.sent_rate(), c.sent_rate())
        }
        Some(Attack::Random { beta }) => {
            let c = independent::cycle(None, &walk, *beta)?;
            (c.sent_rate(), (1.0 - beta) * c.sent_rate())
        }
        Some(b) if b.blocks_every_flag() => {
            let c = independent::cycle(None, &walk, 1.0)?;
            (c.sent_rate(), 0.0)
        }
        Some(b) => Segments::masses_only(&walk, Segments::depth(b))?.attack_flag_rates(Some(b))?,
    };
    let forged = walk.gamma * (1.0 - sent);
    Ok(FlagRates {
        sent,
        delivered: genuine_delivered + forged,
        forged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_attack_they_are_the_high_power_rate() {
        let d = OnlineDesign::new(3, 0.4).unwrap();
        let rates = flag_rates(0.3, d, None).unwrap();
        let rate = d.high_power_rate(0.3).unwrap();
        assert!((rates.sent - rate).abs() < 1e-15 && (rates.delivered - rate).abs() < 1e-15);
        // Blocking 1 of 5 delivers 4/5 of what is sent.
        let a = Attack::periodic(1, 5).unwrap();
        let r = flag_rates(0.3, d, Some(&a)).unwrap();
        assert!((r.delivered - 0.8 * r.sent).abs() < 1e-15 && r.forged == 0.0);
        // All blocked: the detector flags u/(1-u) times per arrival, arrivals at rate λ.
        let all = Attack::mask(vec![true]).unwrap();
        let r = flag_rates(0.3, d, Some(&all)).unwrap();
        let u = 0.7f64.powi(3) * (0.4 + 0.6 * 0.7);
        assert!((r.sent - 0.3 * u / (1.0 - u)).abs() < 1e-15 && r.delivered == 0.0);
        let r = flag_rates(0.3, d, Some(&Attack::random(1.0).unwrap())).unwrap();
        assert!((r.sent - 0.3 * u / (1.0 - u)).abs() < 1e-14 && r.delivered == 0.0);
    }

    #[test]
    fn forging_every_step_sends_one_flag_per_step() {
        let d = OnlineDesign::fixed(2).unwrap();
        let r = flag_rates(0.5, d, Some(&Attack::injection(1.0, None).unwrap())).unwrap();
        assert_eq!((r.sent, r.delivered, r.forged), (0.0, 1.0, 1.0));
    }
}
