//! The online design of the Python package's exact `design_online`, in big-integer arithmetic,
//! for parameter studies that design thousands of (λ, ratio) pairs.
//!
//! The Python package settles the design in exact rationals: z0 is the largest memory whose
//! high-power rate f(z, 1) = λ a^z / (1 - a^(z+1)) still reaches the ratio ρ = p/q, and μ the
//! correctly rounded root of the budget equation. Every quantity it compares or rounds is a
//! ratio of polynomials in the integers of λ = n/d and ρ = p/q (a = m/d with m = d - n):
//!
//! * f(z, 1) >= p/q  iff  q n m^z >= p (d^(z+1) - m^(z+1));
//! * μ = [p (d^(z0+2) - m^(z0+2)) - q n m^(z0+1)] / [n m^z0 (q n + p m)], rounded to the nearest
//!   double (ties to even), as Python's `float(Fraction)` rounds it.
//!
//! [`design_exact`] gives the same z0 and the same μ, bit for bit, or `None` for every case it
//! leaves to the exact Python path (no design, a memory beyond 2000, a λ or ratio outside the
//! plain double range), so errors and their messages stay the Python package's own.

use num_bigint::BigUint;
use num_integer::Integer;
use num_traits::{ToPrimitive, Zero};

/// Largest memory designed here (the Python package's exact range).
pub const MAX_EXACT_Z0: u64 = 2_000;

/// λ = n/d in lowest terms (d a power of two), for a normal double in (0, 1).
fn exact_parts(lam: f64) -> Option<(BigUint, BigUint)> {
    if !(lam > 0.0 && lam < 1.0 && lam.is_normal()) {
        return None;
    }
    let bits = lam.to_bits();
    let mant = (bits & ((1 << 52) - 1)) | (1 << 52);
    let exp = ((bits >> 52) & 0x7ff) as i64 - 1075; // lam = mant * 2^exp, exp < 0
    let tz = mant.trailing_zeros() as i64;
    let n = mant >> tz;
    let shift = -(exp + tz); // > 0 since lam < 1
    Some((BigUint::from(n), BigUint::from(1u8) << shift as u64))
}

/// 2^e for a normal exponent.
fn pow2(e: i64) -> Option<f64> {
    (-1022..=1023)
        .contains(&e)
        .then(|| f64::from_bits(((e + 1023) as u64) << 52))
}

/// num / den rounded to the nearest double, ties to even (`None` outside the normal range).
pub fn ratio_to_f64(num: &BigUint, den: &BigUint) -> Option<f64> {
    if num.is_zero() || den.is_zero() {
        return None;
    }
    // num/den lies in [2^(bn-bd-1), 2^(bn-bd+1)); shifting by s puts the quotient in
    // [2^54, 2^56): 55 or 56 bits, of which 53 are kept.
    let s = 55 - (num.bits() as i64 - den.bits() as i64);
    let (q, r) = if s >= 0 {
        (num << s as u64).div_rem(den)
    } else {
        num.div_rem(&(den << (-s) as u64))
    };
    let q = q.to_u64()?;
    let drop = 64 - q.leading_zeros() as i64 - 53; // 2 or 3
    let (mut mant, rest, half) = (q >> drop, q & ((1 << drop) - 1), 1u64 << (drop - 1));
    if rest > half || (rest == half && (!r.is_zero() || mant & 1 == 1)) {
        mant += 1; // at most 2^53: still exact
    }
    Some(mant as f64 * pow2(drop - s)?)
}

/// How the Python package reads λ: the float `lam` and the fraction it stands for, n/d in
/// lowest terms (the simplest one with d <= 10^9 that rounds to `lam`), or `None` for the
/// float's exact binary value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lam {
    /// λ as a double.
    pub value: f64,
    /// λ = n/d exactly, when it is such a simple fraction.
    pub fraction: Option<(u64, u64)>,
}

/// (z0, μ) of the exact design for λ and the ratio p/q in lowest terms, or `None` where the
/// Python package's exact path must decide (see the module docs).
pub fn design_exact(lam: Lam, p: u64, q: u64) -> Option<(u64, f64)> {
    const EXACT_INT: u64 = 1 << 53; // p / q as one correctly rounded division
    if p == 0 || p >= q || q > EXACT_INT {
        return None;
    }
    let (n, d) = match lam.fraction {
        Some((n, d)) if 0 < n && n < d => (BigUint::from(n), BigUint::from(d)),
        Some(_) => return None,
        None => exact_parts(lam.value)?,
    };
    let lam = lam.value;
    let m = &d - &n;
    let (pb, qb) = (BigUint::from(p), BigUint::from(q));
    // The budget beyond f(1, 1) = λ a / (1 - a²): no online design (the Python path says why).
    if &pb * (&d * &d - &m * &m) > &qb * &n * &m {
        return None;
    }
    // f(z, 1) >= ρ iff a^z (λ + ρ a) >= ρ: the bound, within one; the exact walk settles it.
    let rho = p as f64 / q as f64;
    let bound = (rho / (lam + rho * (1.0 - lam))).ln() / (-lam).ln_1p();
    if !(bound.is_finite() && bound < (1u64 << 40) as f64) {
        return None;
    }
    let estimate = bound as u64;
    if estimate > MAX_EXACT_Z0 {
        return None;
    }
    let qn = &qb * &n;
    let meets = |z: u64| -> bool {
        let mz = m.pow(z as u32);
        &qn * &mz >= &pb * (d.pow(z as u32 + 1) - &mz * &m)
    };
    let mut z0 = estimate.saturating_sub(1).max(1);
    while meets(z0 + 1) {
        z0 += 1;
        if z0 > MAX_EXACT_Z0 + 2 {
            return None;
        }
    }
    let mz = m.pow(z0 as u32);
    let mz1 = &mz * &m;
    // f(z0, 1) == p/q: a fixed memory spends the budget exactly.
    if &qn * &mz == &pb * (d.pow(z0 as u32 + 1) - &mz1) {
        return Some((z0, 1.0));
    }
    let top = &pb * (d.pow(z0 as u32 + 2) - &mz1 * &m);
    let low = &qn * &mz1;
    if top <= low {
        return None;
    }
    let den = &n * &mz * (&qn + &pb * &m);
    Some((z0, ratio_to_f64(&(top - low), &den)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn big(x: u64) -> BigUint {
        BigUint::from(x)
    }

    /// Exact quotients are returned exactly; others round to nearest, ties to even (kills a
    /// truncating or ties-away rounding, and an off-by-one shift).
    #[test]
    fn ratio_rounds_to_nearest_even() {
        assert_eq!(ratio_to_f64(&big(1), &big(4)), Some(0.25));
        assert_eq!(ratio_to_f64(&big(3), &big(4)), Some(0.75));
        assert_eq!(ratio_to_f64(&big(1), &big(3)), Some(1.0 / 3.0));
        assert_eq!(ratio_to_f64(&big(2), &big(3)), Some(2.0 / 3.0));
        assert_eq!(ratio_to_f64(&big(7), &big(7)), Some(1.0));
        // Ties: (2^53 + 1) / 2^54 lies halfway between two doubles; ties go to the even one.
        let two53 = 1u64 << 53;
        let half_way = ratio_to_f64(&big(two53 + 1), &(big(1) << 54u64)).unwrap();
        assert_eq!(half_way, 0.5);
        let up = ratio_to_f64(&big(two53 + 3), &(big(1) << 54u64)).unwrap();
        assert_eq!(up, (two53 + 4) as f64 / 2f64.powi(54));
        // Just above a tie rounds up (the remainder is the sticky bit).
        let n = (big(two53 + 1) << 10u64) + big(1);
        let above = ratio_to_f64(&n, &(big(1) << 64u64)).unwrap();
        assert_eq!(above, (two53 + 2) as f64 / 2f64.powi(54));
        // Every u32 quotient agrees with the hardware's correctly rounded division.
        for (a, b) in [
            (1u64, 7u64),
            (123_456_789, 987_654_321),
            (5, 1 << 40),
            (999, 1000),
        ] {
            assert_eq!(ratio_to_f64(&big(a), &big(b)), Some(a as f64 / b as f64));
        }
        assert_eq!(ratio_to_f64(&big(0), &big(3)), None);
    }

    /// λ = n/d exactly, in lowest terms.
    #[test]
    fn lam_parts_are_exact() {
        let (n, d) = exact_parts(0.5).unwrap();
        assert_eq!((n, d), (big(1), big(2)));
        let (n, d) = exact_parts(0.75).unwrap();
        assert_eq!((n, d), (big(3), big(4)));
        let (n, d) = exact_parts(0.1).unwrap();
        assert_eq!(n.to_f64().unwrap() / d.to_f64().unwrap(), 0.1);
        assert!(n.is_odd());
        assert!(exact_parts(1.0).is_none() && exact_parts(0.0).is_none());
        assert!(exact_parts(f64::MIN_POSITIVE / 2.0).is_none());
    }

    fn binary(value: f64) -> Lam {
        Lam {
            value,
            fraction: None,
        }
    }

    /// The paper's example: λ = 1/2, ρ = 1/7 is spent exactly by z0 = 2 (μ = 1); a ratio between
    /// two fixed memories mixes them, and the budget beyond f(1, 1) has no design.
    #[test]
    fn paper_design() {
        assert_eq!(design_exact(binary(0.5), 1, 7), Some((2, 1.0)));
        // f(1) = 1/3 >= 1/5 > f(2) = 1/7: z0 = 1, μ from the budget equation, here
        // [1 (8 - 1) - 5 (1)(1)] / [1 (1)(5 + 1)] = 2/6 = 1/3.
        assert_eq!(design_exact(binary(0.5), 1, 5), Some((1, 1.0 / 3.0)));
        assert_eq!(design_exact(binary(0.5), 1, 2), None);
        assert_eq!(design_exact(binary(0.5), 0, 2), None);
        // λ read as 3/5 or as the double nearest 0.6: μ differs in the last bit.
        let (_, mu_fraction) = design_exact(
            Lam {
                value: 0.6,
                fraction: Some((3, 5)),
            },
            1,
            10,
        )
        .unwrap();
        let (_, mu_binary) = design_exact(binary(0.6), 1, 10).unwrap();
        assert_eq!(mu_fraction, 0.9609375); // 123/128 exactly
        assert_eq!(mu_binary.to_bits(), 0.9609375f64.to_bits() - 1);
    }
}
