//! Power schedules without attack: the optimal offline schedule (Theorem 3.1, corrected as in
//! ERRATA item 1), the ACK-based online schedule (Theorem 4.5 of Han et al., corrected as in ERRATA
//! item 2) and the all-blocked cost J_max.
//!
//! Every cost takes the weighted traces `w_i = a^i Tr h^i(P̄)` (a = 1 - λ), see
//! [`crate::LinearSystem::weighted_traces`].

use crate::error::{check_lam, check_mu, Error, Result};
use crate::system::LinearSystem;
use nalgebra::DMatrix;

/// Largest period q accepted for an explicit offline schedule (one byte per step).
pub const MAX_PERIOD: u64 = 1 << 32;

/// Block structure of the optimal offline schedule for energy ratio p/q (0 < p < q coprime):
/// `(s0, m, n)` with s0 = ⌊q/p⌋ - 1, `m` blocks of length s0 + 2 and `n` blocks of length s0 + 1
/// (a 1 followed by zeros), m(s0+2) + n(s0+1) = q and m + n = p.
pub fn offline_blocks(p: u64, q: u64) -> Result<(u64, u64, u64)> {
    if q == 0 {
        return Err(Error::invalid("q", "must be positive"));
    }
    if p == 0 || p >= q {
        return Err(Error::invalid(
            "ratio",
            format!("the energy ratio p/q must lie in (0, 1), got {p}/{q}"),
        ));
    }
    let s0 = q / p - 1;
    let m = q - p * (s0 + 1);
    let n = p * (s0 + 2) - q;
    Ok((s0, m, n))
}

/// One period of the optimal offline schedule: `m` blocks `1 0^(s0+1)` then `n` blocks `1 0^s0`.
pub fn offline_schedule(p: u64, q: u64) -> Result<Vec<u8>> {
    let (s0, m, n) = offline_blocks(p, q)?;
    if q > MAX_PERIOD {
        return Err(Error::TooLarge {
            arg: "ratio".into(),
            requested: q as u128,
            limit: MAX_PERIOD as u128,
        });
    }
    let mut out = Vec::with_capacity(q as usize);
    for (count, len) in [(m, s0 + 2), (n, s0 + 1)] {
        for _ in 0..count {
            out.push(1);
            out.extend(std::iter::repeat_n(0, (len - 1) as usize));
        }
    }
    Ok(out)
}

/// Expected cost of one offline block of length `len` (a 1 then len-1 zeros), summed over its steps:
/// Σ_{i<len} [1 + λ(len-1-i)] w_i.
fn block_cost(w: &[f64], lam: f64, len: u64) -> f64 {
    (0..len as usize)
        .map(|i| (1.0 + lam * (len as f64 - 1.0 - i as f64)) * w[i])
        .sum()
}

/// J of the optimal offline schedule (Proposition after Theorem 3.1, with m and n as corrected).
/// `w` must hold at least s0 + 2 weighted traces.
pub fn j_offline(w: &[f64], lam: f64, p: u64, q: u64) -> Result<f64> {
    check_lam(lam)?;
    let (s0, m, n) = offline_blocks(p, q)?;
    if (w.len() as u64) < s0 + 2 {
        return Err(Error::invalid(
            "w",
            format!("needs {} weighted traces", s0 + 2),
        ));
    }
    let total = m as f64 * block_cost(w, lam, s0 + 2) + n as f64 * block_cost(w, lam, s0 + 1);
    Ok(total / q as f64)
}

/// a^k with a = 1 - lam, via exp(k ln(1 - lam)) so that tiny lam keeps its precision.
pub(crate) fn apow(lam: f64, k: u64) -> f64 {
    (k as f64 * (-lam).ln_1p()).exp()
}

/// 1 - a^k without cancellation: for lam below ~1e-16, 1 - lam rounds to 1 and the naive
/// difference would be 0 (a division by zero in every cost).
pub(crate) fn one_minus_apow(lam: f64, k: u64) -> f64 {
    -(k as f64 * (-lam).ln_1p()).exp_m1()
}

/// 1 - u with u = a^z0 (μ + (1-μ) a), the chance of a flag before the next arrival:
/// (1 - a^z0) + a^z0 (1-μ) λ.
pub(crate) fn one_minus_u(lam: f64, z0: u64, mu: f64) -> f64 {
    one_minus_apow(lam, z0) + apow(lam, z0) * (1.0 - mu) * lam
}

/// Denominator 1 - μ a^(z0+1) - (1-μ) a^(z0+2) of the online formulas (ERRATA item 2), as
/// μ (1 - a^(z0+1)) + (1-μ) (1 - a^(z0+2)).
fn online_denominator(lam: f64, z0: u64, mu: f64) -> f64 {
    mu * one_minus_apow(lam, z0 + 1) + (1.0 - mu) * one_minus_apow(lam, z0 + 2)
}

/// Long-run fraction of high-power steps of the online schedule:
/// λ a^z0 (μ + (1-μ) a) / (1 - μ a^(z0+1) - (1-μ) a^(z0+2)).
pub fn online_high_power_rate(lam: f64, z0: u64, mu: f64) -> Result<f64> {
    check_lam(lam)?;
    check_mu(mu)?;
    if z0 < 1 {
        return Err(Error::invalid("z0", "must be at least 1"));
    }
    let a = 1.0 - lam;
    Ok(lam * apow(lam, z0) * (mu + (1.0 - mu) * a) / online_denominator(lam, z0, mu))
}

/// J of the online schedule (corrected Theorem 4.5): λ / (1 - μ a^(z0+1) - (1-μ) a^(z0+2)) ·
/// [Σ_{i≤z0} w_i + (1-μ) w_(z0+1)]. `w` must hold at least z0 + 2 weighted traces.
pub fn j_online(w: &[f64], lam: f64, z0: u64, mu: f64) -> Result<f64> {
    check_lam(lam)?;
    check_mu(mu)?;
    if z0 < 1 {
        return Err(Error::invalid("z0", "must be at least 1"));
    }
    let z = z0 as usize;
    if w.len() < z + 2 {
        return Err(Error::invalid(
            "w",
            format!("needs {} weighted traces", z + 2),
        ));
    }
    let head: f64 = w[..=z].iter().sum();
    let tail = if mu < 1.0 { (1.0 - mu) * w[z + 1] } else { 0.0 };
    Ok(lam * (head + tail) / online_denominator(lam, z0, mu))
}

/// J with every flag-ACK blocked: Σ_i λ a^i Tr h^i(P̄) = Tr X with X = a A X A' + λ P̄ + a Q
/// (a Stein equation). `+inf` when a ρ(A)² >= 1 (ERRATA item 5).
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
    fn offline_pattern_errata_example() {
        // ERRATA item 1: p/q = 1/7 gives one block of length 7.
        assert_eq!(offline_blocks(1, 7).unwrap(), (6, 0, 1));
        assert_eq!(offline_schedule(1, 7).unwrap(), vec![1, 0, 0, 0, 0, 0, 0]);
        assert_eq!(offline_schedule(2, 3).unwrap(), vec![1, 0, 1]);
        assert_eq!(
            offline_schedule(3, 8).unwrap(),
            vec![1, 0, 0, 1, 0, 0, 1, 0]
        );
    }

    #[test]
    fn offline_has_p_ones_per_q() {
        for q in 2..40u64 {
            for p in 1..q {
                let s = offline_schedule(p, q).unwrap();
                assert_eq!(s.len() as u64, q);
                assert_eq!(s.iter().map(|&x| x as u64).sum::<u64>(), p);
                assert_eq!(s[0], 1);
                // Gaps between ones differ by at most one (the optimal spreading).
                let ones: Vec<usize> = (0..s.len()).filter(|&i| s[i] == 1).collect();
                let mut gaps: Vec<usize> = ones.windows(2).map(|w| w[1] - w[0]).collect();
                gaps.push(q as usize - ones[ones.len() - 1] + ones[0]);
                let (lo, hi) = (gaps.iter().min().unwrap(), gaps.iter().max().unwrap());
                assert!(hi - lo <= 1, "{p}/{q}: {s:?}");
            }
        }
    }

    /// J_offline equals the period average of E Tr P_k obtained by propagating the τ law.
    #[test]
    fn j_offline_matches_direct_propagation() {
        let lam = 0.35;
        let a: f64 = 1.0 - lam;
        let tr: Vec<f64> = (0..50)
            .map(|i| 1.0 + 0.3 * i as f64 + 0.01 * (i * i) as f64)
            .collect();
        let w: Vec<f64> = tr
            .iter()
            .enumerate()
            .map(|(i, t)| a.powi(i as i32) * t)
            .collect();
        for (p, q) in [(1u64, 7u64), (2, 7), (3, 8), (5, 12), (1, 2)] {
            let sched = offline_schedule(p, q).unwrap();
            let mut direct = 0.0;
            let mut law = vec![0.0; 60];
            for &g in &sched {
                let mut next = vec![0.0; 60];
                if g == 1 {
                    next[0] = 1.0;
                } else {
                    for (k, &pk) in law.iter().enumerate().take(59) {
                        next[0] += lam * pk;
                        next[k + 1] += a * pk;
                    }
                }
                law = next;
                direct += law.iter().zip(&tr).map(|(p, t)| p * t).sum::<f64>();
            }
            direct /= q as f64;
            let closed = j_offline(&w, lam, p, q).unwrap();
            assert!(
                (closed - direct).abs() < 1e-12 * direct,
                "{p}/{q}: {closed} vs {direct}"
            );
        }
    }

    #[test]
    fn tiny_lambda_keeps_precision() {
        // λ = 1e-20: 1 - λ rounds to 1, but the rate is λ a^z0 / (1 - a^(z0+1)) ≈ 1/(z0+1).
        let r = online_high_power_rate(1e-20, 2, 1.0).unwrap();
        assert!((r - 1.0 / 3.0).abs() < 1e-12, "{r}");
        assert!((one_minus_u(1e-20, 3, 0.5) - 3.5e-20).abs() < 1e-32);
    }

    #[test]
    fn online_reduces_to_fixed_memory() {
        // ERRATA item 2: λ = 0.5, z0 = 2, μ = 1 uses high power 1/7 of the time.
        assert!((online_high_power_rate(0.5, 2, 1.0).unwrap() - 1.0 / 7.0).abs() < 1e-15);
        // μ = 0 is the fixed memory z0 + 1.
        let r0 = online_high_power_rate(0.3, 3, 0.0).unwrap();
        let r1 = online_high_power_rate(0.3, 4, 1.0).unwrap();
        assert!((r0 - r1).abs() < 1e-15);
        let w: Vec<f64> = (0..10).map(|i| 0.7f64.powi(i) * (1.0 + i as f64)).collect();
        let j0 = j_online(&w, 0.3, 3, 0.0).unwrap();
        let j1 = j_online(&w, 0.3, 4, 1.0).unwrap();
        assert!((j0 - j1).abs() < 1e-14 * j1);
    }
}
