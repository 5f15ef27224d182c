//! The optimal offline schedule (Theorem 3.1, corrected as in Model note 1): its blocks, one
//! explicit period and its cost J_offline.
//!
//! The cost takes the weighted traces `w_i = a^i Tr h^i(P̄)` (a = 1 - λ), see
//! [`crate::LinearSystem::weighted_traces`].

use super::params::{check_lam, Ratio};
use crate::error::{Error, Result};

// The blocks are the offline schedule's reading of the budget, so this method lives with the
// schedule rather than with `Ratio` in `params`.
impl Ratio {
    /// Block structure of the optimal offline schedule (Theorem 3.1, Model note 1).
    pub fn offline_blocks(&self) -> OfflineBlocks {
        let s0 = self.q() / self.p() - 1;
        OfflineBlocks {
            s0,
            long: self.q() - self.p() * (s0 + 1),
            short: self.p() * (s0 + 2) - self.q(),
        }
    }
}

/// The optimal offline schedule's blocks (Theorem 3.1 as corrected in Model note 1): `long`
/// blocks of length s0 + 2 and `short` blocks of length s0 + 1, each a 1 followed by zeros.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OfflineBlocks {
    /// s0 = ⌊q/p⌋ - 1.
    pub s0: u64,
    /// m = q - p (s0 + 1): blocks `1 0^(s0+1)`.
    pub long: u64,
    /// n = p (s0 + 2) - q: blocks `1 0^s0`.
    pub short: u64,
}

/// Largest period q accepted for an explicit offline schedule (one byte per step).
pub const MAX_PERIOD: u64 = 1 << 32;

/// A period of `q` steps may be written out (at most [`MAX_PERIOD`]), checked before allocating.
fn check_period(q: u64) -> Result<()> {
    if q > MAX_PERIOD {
        return Err(Error::TooLarge {
            arg: "ratio".into(),
            requested: q as u128,
            limit: MAX_PERIOD as u128,
        });
    }
    Ok(())
}

/// One period of the optimal offline schedule: `m` blocks `1 0^(s0+1)` then `n` blocks `1 0^s0`.
pub fn offline_schedule(ratio: Ratio) -> Result<Vec<u8>> {
    let OfflineBlocks { s0, long, short } = ratio.offline_blocks();
    let q = ratio.q();
    check_period(q)?;
    let mut out = Vec::with_capacity(q as usize);
    for (count, len) in [(long, s0 + 2), (short, s0 + 1)] {
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
/// `w` must hold at least s0 + 2 weighted traces. `+inf` (never NaN) when the cost exceeds the
/// double range, which a long period reaches where (1-λ) ρ(A)² >= 1.
pub fn j_offline(w: &[f64], lam: f64, ratio: Ratio) -> Result<f64> {
    check_lam(lam)?;
    let OfflineBlocks { s0, long, short } = ratio.offline_blocks();
    if (w.len() as u64) < s0 + 2 {
        return Err(Error::invalid(
            "w",
            format!("needs {} weighted traces", s0 + 2),
        ));
    }
    // A block kind that does not occur adds nothing, even where its cost is beyond the double
    // range (0 * inf would be NaN); a J beyond the double range is +inf.
    let part = |count: u64, len: u64| {
        if count == 0 {
            0.0
        } else {
            count as f64 * block_cost(w, lam, len)
        }
    };
    Ok((part(long, s0 + 2) + part(short, s0 + 1)) / ratio.q() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::schedule::params::gcd;

    fn ratio(p: u64, q: u64) -> Ratio {
        Ratio::new(p, q).unwrap()
    }

    /// The period limit is inclusive, checked without allocating (kills `>` turned `>=` or
    /// `==`): exactly MAX_PERIOD steps may be written, one more is refused naming both counts.
    #[test]
    fn period_limit_is_inclusive() {
        assert!(check_period(MAX_PERIOD).is_ok());
        let e = check_period(MAX_PERIOD + 1).unwrap_err().to_string();
        assert!(
            e.contains(&(MAX_PERIOD + 1).to_string()) && e.contains(&MAX_PERIOD.to_string()),
            "{e}"
        );
        assert!(offline_schedule(ratio(1, MAX_PERIOD + 1)).is_err());
    }

    /// z0 + 2 weighted traces are enough for J_online, z0 + 1 are not; with μ = 1 the trace
    /// at τ = z0 + 1 is never reached, so even an infinite one leaves J finite (kills the
    /// length check's `<` turned `<=`, and `mu < 1` turned `<=`, which made it 0 · inf = NaN).
    #[test]
    fn offline_pattern_of_the_model_note() {
        // Model note 1: p/q = 1/7 gives one block of length 7.
        let blocks = ratio(1, 7).offline_blocks();
        assert_eq!((blocks.s0, blocks.long, blocks.short), (6, 0, 1));
        assert_eq!(
            offline_schedule(ratio(1, 7)).unwrap(),
            vec![1, 0, 0, 0, 0, 0, 0]
        );
        assert_eq!(offline_schedule(ratio(2, 3)).unwrap(), vec![1, 0, 1]);
        assert_eq!(
            offline_schedule(ratio(3, 8)).unwrap(),
            vec![1, 0, 0, 1, 0, 0, 1, 0]
        );
    }

    #[test]
    fn offline_has_p_ones_per_q() {
        for q in 2..40u64 {
            for p in (1..q).filter(|&p| gcd(p, q) == 1) {
                let s = offline_schedule(ratio(p, q)).unwrap();
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
            let sched = offline_schedule(ratio(p, q)).unwrap();
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
            let closed = j_offline(&w, lam, ratio(p, q)).unwrap();
            assert!(
                (closed - direct).abs() < 1e-12 * direct,
                "{p}/{q}: {closed} vs {direct}"
            );
        }
    }

    /// A silent NaN, fixed: with m = 0 long blocks (p/q = 1/q), 0 · block_cost was NaN when
    /// that unused block's cost overflowed. A finite J stays finite, an overflowing one is +inf.
    #[test]
    fn j_offline_is_inf_or_finite_never_nan() {
        let lam = 0.25;
        let q = 16u64; // s0 = 15: one short block of length 16, no long block (length 17)
        let mut w = vec![1.0; 17];
        w[16] = f64::INFINITY; // only the (absent) long block reaches τ = 16
        let j = j_offline(&w, lam, ratio(1, q)).unwrap();
        let direct: f64 = (0..16).map(|i| 1.0 + lam * (15 - i) as f64).sum::<f64>() / 16.0;
        assert!((j - direct).abs() < 1e-15 * direct, "{j} vs {direct}");
        w[15] = f64::INFINITY; // now the short block overflows
        assert_eq!(j_offline(&w, lam, ratio(1, q)).unwrap(), f64::INFINITY);
        // and with both kinds of block present (3/8: two long blocks of 3, one short of 2)
        let mut w = vec![1.0; 3];
        w[2] = f64::INFINITY;
        assert_eq!(j_offline(&w, lam, ratio(3, 8)).unwrap(), f64::INFINITY);
    }

    #[test]
    fn offline_cost_beyond_the_double_range_is_inf() {
        // p/q = 1/8: only blocks of length 8 (long = 0); traces overflowing from i = 7 on.
        let mut w = vec![1.0; 7];
        w.extend([f64::INFINITY; 3]);
        assert_eq!(ratio(1, 8).offline_blocks().long, 0);
        assert_eq!(j_offline(&w, 0.25, ratio(1, 8)).unwrap(), f64::INFINITY);
    }
}
