//! The ACK-based online schedule: its memory (z0, μ), the memory walk's probabilities, the
//! high-power rate, the design that spends a budget, its cost without attack (Theorem 4.5 of
//! Han et al., Model note 2) and the all-blocked cost J_max.
//!
//! The remote detector counts losses since its last reset; after z0 of them (z0 + 1 with
//! probability 1 - μ, Model note 2) it sends a flag-ACK and the sensor uses high power next step.
//! With a = 1 - λ, a flag comes before the next arrival with probability
//! u = a^z0 (μ + (1-μ) a), the same after every reset.

use super::params::{apow, check_lam, one_minus_apow, Ratio};
use crate::error::{Error, Result};
use crate::system::LinearSystem;
use nalgebra::DMatrix;

/// The online schedule's memory: a flag-ACK after `z0` losses, or `z0 + 1` with probability
/// `1 - mu` (Theorem 4.5 of Han et al., Model note 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnlineDesign {
    /// Memory length z0 >= 1.
    pub z0: u64,
    /// Probability of the z0-step memory at each reset, in [0, 1] (1: fixed length z0).
    pub mu: f64,
}

impl OnlineDesign {
    /// A validated design: `z0 >= 1`, `0 <= mu <= 1`.
    pub fn new(z0: u64, mu: f64) -> Result<Self> {
        if z0 < 1 {
            return Err(Error::invalid(
                "z0",
                format!("must be at least 1, got {z0}"),
            ));
        }
        if !(mu.is_finite() && (0.0..=1.0).contains(&mu)) {
            return Err(Error::invalid(
                "mu",
                format!("must lie in [0, 1], got {mu}"),
            ));
        }
        Ok(OnlineDesign { z0, mu })
    }

    /// The fixed memory z0 (μ = 1).
    pub fn fixed(z0: u64) -> Result<Self> {
        Self::new(z0, 1.0)
    }

    /// Re-checks a design whose public fields may have been set by hand.
    pub fn validate(&self) -> Result<()> {
        Self::new(self.z0, self.mu).map(|_| ())
    }

    /// u = a^z0 (μ + (1-μ) a): the chance that a flag-ACK comes before the next arrival.
    pub fn flag_probability(&self, lam: f64) -> f64 {
        apow(lam, self.z0) * (self.mu + (1.0 - self.mu) * (1.0 - lam))
    }

    /// 1 - u without cancellation: (1 - a^z0) + a^z0 (1-μ) λ.
    pub fn no_flag_probability(&self, lam: f64) -> f64 {
        one_minus_apow(lam, self.z0) + apow(lam, self.z0) * (1.0 - self.mu) * lam
    }

    /// Denominator 1 - μ a^(z0+1) - (1-μ) a^(z0+2) of the online formulas (Model note 2),
    /// written as μ (1 - a^(z0+1)) + (1-μ) (1 - a^(z0+2)).
    pub(crate) fn renewal_denominator(&self, lam: f64) -> f64 {
        self.mu * one_minus_apow(lam, self.z0 + 1)
            + (1.0 - self.mu) * one_minus_apow(lam, self.z0 + 2)
    }

    /// Long-run fraction of high-power steps without attack (= flag-ACKs per step):
    /// λ u / (1 - μ a^(z0+1) - (1-μ) a^(z0+2)).
    pub fn high_power_rate(&self, lam: f64) -> Result<f64> {
        check_lam(lam)?;
        self.validate()?;
        Ok(lam * self.flag_probability(lam) / self.renewal_denominator(lam))
    }
}

/// The detector's memory walk between two fresh starts (an arrival, or a high-power step after a
/// flag-ACK reached the sensor), with an attacker who forges a flag-ACK with probability `gamma`
/// on every step on which the detector sends none (`gamma = 0`: no forging).
///
/// Per step without a genuine flag the walk goes on (a loss at low power, no forgery) with
/// probability c = (1-λ)(1-γ); a blocked genuine flag goes on with probability a = 1-λ, since
/// nothing is forged on a step that carries a genuine flag. Relative to c^τ, each blocked flag
/// on the way to τ therefore weighs ε = 1/(1-γ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Walk {
    /// Arrival probability λ at low power.
    pub lam: f64,
    /// The online schedule's memory.
    pub design: OnlineDesign,
    /// Probability of a forged flag-ACK on a step without a genuine one.
    pub gamma: f64,
}

impl Walk {
    /// A validated walk: `0 < lam < 1`, a valid design, `0 <= gamma <= 1`.
    pub fn new(lam: f64, design: OnlineDesign, gamma: f64) -> Result<Self> {
        check_lam(lam)?;
        design.validate()?;
        if !(gamma.is_finite() && (0.0..=1.0).contains(&gamma)) {
            return Err(Error::invalid(
                "gamma",
                format!("must lie in [0, 1], got {gamma}"),
            ));
        }
        Ok(Walk { lam, design, gamma })
    }

    /// ln c, c = (1-λ)(1-γ) (-inf when γ = 1).
    fn ln_c(&self) -> f64 {
        (-self.lam).ln_1p() + (-self.gamma).ln_1p()
    }

    /// c^k, the weight of k steps without a genuine flag (1 for k = 0, also when c = 0).
    pub fn c_pow(&self, k: u64) -> f64 {
        if k == 0 {
            1.0
        } else {
            (k as f64 * self.ln_c()).exp()
        }
    }

    /// c = (1-λ)(1-γ).
    pub fn continuation(&self) -> f64 {
        self.c_pow(1)
    }

    /// u = c^z0 (μ + (1-μ) c): the chance of a genuine flag-ACK before the next fresh start, from
    /// a fresh start.
    pub fn flag_probability(&self) -> f64 {
        let c = self.continuation();
        self.c_pow(self.design.z0) * (self.design.mu + (1.0 - self.design.mu) * c)
    }

    /// 1 - u without cancellation: (1 - c^z0) + c^z0 (1-μ)(1-c).
    pub fn no_flag_probability(&self) -> f64 {
        let l = self.ln_c();
        let z0 = self.design.z0 as f64;
        let (cz, one_minus_cz) = if l == f64::NEG_INFINITY {
            (0.0, 1.0)
        } else {
            ((z0 * l).exp(), -(z0 * l).exp_m1())
        };
        one_minus_cz + cz * (1.0 - self.design.mu) * -l.exp_m1()
    }

    /// 1 - ũ with ũ = ε u = a c^(z0-1) (μ + (1-μ) c), the chance that the walk goes on from a
    /// blocked flag-ACK to the next genuine one: the relative rate of fresh starts in a counter
    /// level entered by a blocked flag (1 - u when nothing is forged).
    pub fn restart_after_block(&self) -> f64 {
        if self.gamma == 0.0 {
            return self.no_flag_probability();
        }
        let rest = match self.design.z0 - 1 {
            0 => 0.0, // no step after the blocked one before the memory is full again
            k => k as f64 * self.ln_c(),
        };
        let l = (-self.lam).ln_1p() + rest;
        let one_minus_c = -self.ln_c().exp_m1();
        -l.exp_m1() + l.exp() * (1.0 - self.design.mu) * one_minus_c
    }

    /// ln ε = -ln(1-γ): each blocked flag on a path weighs ε relative to c^τ.
    pub fn ln_block_factor(&self) -> f64 {
        -(-self.gamma).ln_1p()
    }
}

/// Largest memory [`design_online`] returns.
pub const MAX_DESIGN_Z0: u64 = 1_000_000;

/// Relative tolerance within which [`design_online`] takes the budget to equal f(z0, 1) exactly
/// and returns μ = 1 (a few roundings of the rate's floating-point evaluation).
pub const DESIGN_BOUNDARY_TOL: f64 = 1e-13;

/// The online design whose high-power rate equals the energy ratio p/q.
///
/// The rate f(z0, μ) falls from f(z0, 1) to f(z0, 0) = f(z0 + 1, 1) as μ goes from 1 to 0, so
/// the budget fixes z0 (the bracket f(z0+1, 1) < p/q <= f(z0, 1), found by bisection) and then μ
/// in closed form. This is double-precision arithmetic: a budget within
/// [`DESIGN_BOUNDARY_TOL`] (relative) of f(z0, 1) gives μ = 1. (The Python package settles that
/// boundary in exact rational arithmetic and passes its design in.)
pub fn design_online(lam: f64, ratio: Ratio) -> Result<OnlineDesign> {
    check_lam(lam)?;
    let rho = ratio.value();
    let fixed = |z: u64| OnlineDesign { z0: z, mu: 1.0 }.high_power_rate(lam);
    let top = fixed(1)?;
    if rho > top * (1.0 + DESIGN_BOUNDARY_TOL) {
        return Err(Error::invalid(
            "ratio",
            format!(
                "{ratio} exceeds the largest high-power rate an online schedule with z0 >= 1 can \
                 use at lam={lam} ({top:.6} = (1-lam)/(2-lam))"
            ),
        ));
    }
    // Largest z with f(z, 1) >= rho (up to the tolerance); f falls geometrically in z.
    let meets = |z: u64| -> Result<bool> { Ok(fixed(z)? >= rho * (1.0 - DESIGN_BOUNDARY_TOL)) };
    let (mut lo, mut hi) = (1u64, 2u64);
    while meets(hi)? && hi < 1 << 40 {
        (lo, hi) = (hi, hi * 2);
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if meets(mid)? {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let z0 = lo;
    if z0 > MAX_DESIGN_Z0 {
        return Err(Error::invalid(
            "ratio",
            format!(
                "{ratio} is so small that the online schedule would need a memory of about {z0} \
                 steps (more than {MAX_DESIGN_Z0})"
            ),
        ));
    }
    let f1 = fixed(z0)?;
    if (f1 - rho).abs() <= DESIGN_BOUNDARY_TOL * rho {
        return OnlineDesign::new(z0, 1.0);
    }
    // Solve f(z0, μ) = rho for μ: rho (1 - a^(z0+2)) - λ a^(z0+1) = μ λ a^z0 (1 - a)... written
    // as in the exact form: μ = (ρ(1 - a^(z0+2)) - λ a^(z0+1)) / (λ a^z0 (λ + ρ a)).
    let a = 1.0 - lam;
    let az = apow(lam, z0);
    let mu = (rho * one_minus_apow(lam, z0 + 2) - lam * az * a) / (lam * az * (lam + rho * a));
    OnlineDesign::new(z0, mu.clamp(0.0, 1.0))
}

/// J of the online schedule (corrected Theorem 4.5): λ / (1 - μ a^(z0+1) - (1-μ) a^(z0+2)) ·
/// [Σ_{i≤z0} w_i + (1-μ) w_(z0+1)]. `w` must hold at least z0 + 2 weighted traces.
pub fn j_online(w: &[f64], lam: f64, design: OnlineDesign) -> Result<f64> {
    check_lam(lam)?;
    design.validate()?;
    let (z, mu) = (design.z0 as usize, design.mu);
    if w.len() < z + 2 {
        return Err(Error::invalid(
            "w",
            format!("needs {} weighted traces", z + 2),
        ));
    }
    let head: f64 = w[..=z].iter().sum();
    let tail = if mu < 1.0 { (1.0 - mu) * w[z + 1] } else { 0.0 };
    Ok(lam * (head + tail) / design.renewal_denominator(lam))
}

/// J with every flag-ACK blocked: Σ_i λ a^i Tr h^i(P̄) = Tr X with X = a A X A' + λ P̄ + a Q
/// (a Stein equation). `+inf` when a ρ(A)² >= 1 (Model note 5).
pub fn j_max(sys: &LinearSystem, lam: f64) -> Result<f64> {
    check_lam(lam)?;
    let a = 1.0 - lam;
    let c0: DMatrix<f64> = sys.pbar() * lam + sys.q() * a;
    Ok(match sys.stein(a, &c0)? {
        Some(x) => x.trace(),
        None => f64::INFINITY,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn walk_without_forging_is_the_plain_memory_walk() {
        let d = OnlineDesign::new(3, 0.4).unwrap();
        let w = Walk::new(0.3, d, 0.0).unwrap();
        assert_eq!(w.flag_probability(), d.flag_probability(0.3));
        assert_eq!(w.no_flag_probability(), d.no_flag_probability(0.3));
        assert_eq!(w.restart_after_block(), d.no_flag_probability(0.3));
        assert!(Walk::new(0.3, d, 1.5)
            .unwrap_err()
            .to_string()
            .starts_with("gamma:"));
    }

    #[test]
    fn walk_with_forging() {
        // c = 0.7 * 0.8 = 0.56; u = c^3 (0.4 + 0.6 c); 1 - ũ = 1 - 0.7 c^2 (0.4 + 0.6 c).
        let d = OnlineDesign::new(3, 0.4).unwrap();
        let w = Walk::new(0.3, d, 0.2).unwrap();
        let c: f64 = 0.56;
        let u = c.powi(3) * (0.4 + 0.6 * c);
        assert!((w.flag_probability() - u).abs() < 1e-15);
        assert!((w.no_flag_probability() - (1.0 - u)).abs() < 1e-15);
        let tilde = 0.7 * c * c * (0.4 + 0.6 * c);
        assert!((w.restart_after_block() - (1.0 - tilde)).abs() < 1e-15);
        // Forging every step: the walk never goes on.
        let all = Walk::new(0.3, d, 1.0).unwrap();
        assert_eq!(
            (all.flag_probability(), all.no_flag_probability()),
            (0.0, 1.0)
        );
        assert_eq!(all.c_pow(0), 1.0);
    }

    #[test]
    fn design_is_validated() {
        assert!(OnlineDesign::new(0, 1.0)
            .unwrap_err()
            .to_string()
            .starts_with("z0:"));
        assert!(OnlineDesign::new(2, 1.5)
            .unwrap_err()
            .to_string()
            .starts_with("mu:"));
        assert!(OnlineDesign::new(2, f64::NAN).is_err());
    }

    #[test]
    fn tiny_lambda_keeps_precision() {
        // λ = 1e-20: 1 - λ rounds to 1, but the rate is λ a^z0 / (1 - a^(z0+1)) ≈ 1/(z0+1).
        let r = OnlineDesign::fixed(2)
            .unwrap()
            .high_power_rate(1e-20)
            .unwrap();
        assert!((r - 1.0 / 3.0).abs() < 1e-12, "{r}");
        let d = OnlineDesign::new(3, 0.5).unwrap();
        assert!((d.no_flag_probability(1e-20) - 3.5e-20).abs() < 1e-32);
    }

    #[test]
    fn rate_reduces_to_fixed_memory() {
        // Model note 2: λ = 0.5, z0 = 2, μ = 1 uses high power 1/7 of the time.
        let r = OnlineDesign::fixed(2)
            .unwrap()
            .high_power_rate(0.5)
            .unwrap();
        assert!((r - 1.0 / 7.0).abs() < 1e-15);
        // μ = 0 is the fixed memory z0 + 1.
        let r0 = OnlineDesign::new(3, 0.0)
            .unwrap()
            .high_power_rate(0.3)
            .unwrap();
        let r1 = OnlineDesign::fixed(4)
            .unwrap()
            .high_power_rate(0.3)
            .unwrap();
        assert!((r0 - r1).abs() < 1e-15);
    }

    #[test]
    fn design_spends_the_budget() {
        // The paper's example: λ = 1/2, ratio 1/7 is met exactly by z0 = 2, μ = 1.
        let d = design_online(0.5, Ratio::new(1, 7).unwrap()).unwrap();
        assert_eq!((d.z0, d.mu), (2, 1.0));
        for &(lam, p, q) in &[(0.3, 1u64, 5u64), (0.5, 1, 9), (0.8, 1, 11), (0.05, 1, 40)] {
            let ratio = Ratio::new(p, q).unwrap();
            let d = design_online(lam, ratio).unwrap();
            let rate = d.high_power_rate(lam).unwrap();
            assert!(
                (rate - ratio.value()).abs() < 1e-12,
                "{lam} {p}/{q}: {d:?} {rate}"
            );
            // The bracket: z0 + 1 with μ = 1 spends less than the budget.
            let next = OnlineDesign::fixed(d.z0 + 1)
                .unwrap()
                .high_power_rate(lam)
                .unwrap();
            assert!(next < ratio.value());
        }
        let e = design_online(0.5, Ratio::new(1, 2).unwrap()).unwrap_err();
        assert!(e.to_string().starts_with("ratio:"), "{e}");
    }

    #[test]
    fn j_online_needs_exactly_z0_plus_two_traces() {
        let design = OnlineDesign::new(2, 0.5).unwrap();
        assert!(j_online(&[1.0; 4], 0.5, design).is_ok());
        assert!(j_online(&[1.0; 3], 0.5, design).is_err());
        let fixed = OnlineDesign::fixed(2).unwrap();
        let j = j_online(&[1.0, 1.0, 1.0, f64::INFINITY], 0.5, fixed).unwrap();
        // λ (1 + 1 + 1) / (1 - a³) with a = 1/2: 1.5 / 0.875.
        assert!((j - 1.5 / 0.875).abs() < 1e-15, "{j}");
    }

    #[test]
    fn online_with_mu_zero_is_the_longer_fixed_memory() {
        let w: Vec<f64> = (0..10).map(|i| 0.7f64.powi(i) * (1.0 + i as f64)).collect();
        let d0 = OnlineDesign::new(3, 0.0).unwrap();
        let d1 = OnlineDesign::fixed(4).unwrap();
        let j0 = j_online(&w, 0.3, d0).unwrap();
        let j1 = j_online(&w, 0.3, d1).unwrap();
        assert!((j0 - j1).abs() < 1e-14 * j1);
    }
}
