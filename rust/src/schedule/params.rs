//! The parameters both schedules share, and their checks: the channel's λ (with the powers of
//! a = 1 - λ that every formula uses) and the energy budget p/q. They sit apart from either
//! schedule because the offline and the online files both need them.

use crate::error::{Error, Result};
use std::fmt;

/// Checks `0 < lam < 1` (the low-power arrival probability λ).
pub fn check_lam(lam: f64) -> Result<()> {
    if lam.is_finite() && lam > 0.0 && lam < 1.0 {
        Ok(())
    } else {
        Err(Error::invalid(
            "lam",
            format!("must lie in (0, 1), got {lam}"),
        ))
    }
}

/// a^k with a = 1 - lam, via exp(k ln(1 - lam)) so that tiny lam keeps its precision.
pub fn apow(lam: f64, k: u64) -> f64 {
    (k as f64 * (-lam).ln_1p()).exp()
}

/// 1 - a^k without cancellation: for lam below ~1e-16, 1 - lam rounds to 1 and the naive
/// difference would be 0 (a division by zero in every cost).
pub fn one_minus_apow(lam: f64, k: u64) -> f64 {
    -(k as f64 * (-lam).ln_1p()).exp_m1()
}

/// An energy ratio p/q = (Ψ - δ)/(Δ - δ) in lowest terms, 0 < p/q < 1: the fraction of steps at
/// high power that the budget Ψ allows (Sec. III).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Ratio {
    p: u64,
    q: u64,
}

impl Ratio {
    /// p/q, reduced to lowest terms; it must lie strictly between 0 and 1.
    pub fn new(p: u64, q: u64) -> Result<Self> {
        if q == 0 {
            return Err(Error::invalid(
                "ratio",
                "the denominator q must be positive",
            ));
        }
        if p == 0 || p >= q {
            return Err(Error::invalid(
                "ratio",
                format!("the energy ratio p/q must lie in (0, 1), got {p}/{q}"),
            ));
        }
        let g = gcd(p, q);
        Ok(Ratio { p: p / g, q: q / g })
    }

    /// Numerator p (lowest terms).
    pub fn p(&self) -> u64 {
        self.p
    }

    /// Denominator q (lowest terms): the offline schedule's period.
    pub fn q(&self) -> u64 {
        self.q
    }

    /// p/q as a double.
    pub fn value(&self) -> f64 {
        self.p as f64 / self.q as f64
    }
}

impl fmt::Display for Ratio {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.p, self.q)
    }
}

pub(super) fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ratio(p: u64, q: u64) -> Ratio {
        Ratio::new(p, q).unwrap()
    }

    #[test]
    fn lam_is_checked() {
        for bad in [0.0, 1.0, -0.1, f64::NAN, f64::INFINITY] {
            let e = check_lam(bad).unwrap_err();
            assert!(e.to_string().starts_with("lam:"), "{e}");
        }
        assert!(check_lam(1e-300).is_ok());
    }

    #[test]
    fn ratio_is_reduced_and_checked() {
        assert_eq!(ratio(2, 14), ratio(1, 7));
        assert_eq!(ratio(2, 14).to_string(), "1/7");
        let r = ratio(6, 21);
        assert_eq!((r.p(), r.q(), r.value()), (2, 7, 2.0 / 7.0));
        for (p, q) in [(0, 7), (7, 7), (8, 7), (1, 0)] {
            let e = Ratio::new(p, q).unwrap_err();
            assert!(e.to_string().starts_with("ratio:"), "{e}");
        }
    }
}
