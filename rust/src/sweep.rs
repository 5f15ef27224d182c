//! The β sweep over every r/t in lowest terms, and the attacker threshold β̄.
//!
//! "Block the first r of every t" is a renewal cycle, so J(r, t) = (t W_0 + a_r) / (t M_0 + b_r)
//! with a_r, b_r accumulated once per r ([`crate::pattern::Segments::first_r_offsets`]). The
//! fractions come from the Farey sequence of order t_max, already sorted by β, at O(1) each.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::pattern::Segments;

/// Most fractions one sweep will hold (4 arrays, 24 bytes per fraction).
pub const MAX_FRACTIONS: u128 = 400_000_000;

/// Number of reduced fractions r/t in (0, 1) with t <= n: Σ_{t=2..n} φ(t) (exact, by sieve).
pub fn farey_count(n: u64) -> u128 {
    if n < 2 {
        return 0;
    }
    let n = n as usize;
    let mut phi: Vec<u64> = (0..=n as u64).collect();
    for i in 2..=n {
        if phi[i] == i as u64 {
            for j in (i..=n).step_by(i) {
                phi[j] -= phi[j] / i as u64;
            }
        }
    }
    phi[2..].iter().map(|&x| x as u128).sum()
}

/// Upper bound 0.31 n² + n on the count, for refusing before the sieve allocates.
fn farey_bound(n: u64) -> u128 {
    let n = n as u128;
    n * n * 31 / 100 + n
}

/// All reduced r/t with 1 <= r < t <= n, in increasing order of r/t (Farey sequence).
pub fn farey(n: u64) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    if n < 2 {
        return out;
    }
    let n = n as i64;
    let (mut a, mut b, mut c, mut d) = (0i64, 1i64, 1i64, n);
    while c < d {
        out.push((c as u32, d as u32));
        let k = (n + b) / d;
        let (nc, nd) = (k * c - a, k * d - b);
        (a, b, c, d) = (c, d, nc, nd);
    }
    out
}

/// Result of a sweep: one entry per fraction, in increasing β.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    pub r: Vec<u32>,
    pub t: Vec<u32>,
    pub beta: Vec<f64>,
    pub j: Vec<f64>,
}

/// J(r, t) for every reduced r/t with t <= t_max. `seg` must hold segments 0..t_max-1.
pub fn sweep(seg: &Segments, t_max: u64) -> Result<Sweep> {
    if t_max < 2 {
        return Err(Error::invalid(
            "t_max",
            format!("must be at least 2, got {t_max}"),
        ));
    }
    if t_max > u32::MAX as u64 || farey_bound(t_max) > MAX_FRACTIONS {
        return Err(Error::TooLarge {
            arg: "t_max".into(),
            requested: farey_bound(t_max),
            limit: MAX_FRACTIONS,
        });
    }
    let rmax = (t_max - 1) as usize;
    if seg.w.len() <= rmax {
        return Err(Error::invalid(
            "t_max",
            format!("needs segments up to {rmax}"),
        ));
    }
    let (a, b) = seg.first_r_offsets(rmax);
    let fr = farey(t_max);
    let (w0, m0) = (seg.w[0], seg.m[0]);
    let j: Vec<f64> = fr
        .par_iter()
        .with_min_len(1 << 16)
        .map(|&(r, t)| {
            let t = t as f64;
            (t * w0 + a[r as usize]) / (t * m0 + b[r as usize])
        })
        .collect();
    let beta = fr
        .par_iter()
        .with_min_len(1 << 16)
        .map(|&(r, t)| r as f64 / t as f64)
        .collect();
    let (r, t) = fr.into_iter().unzip();
    Ok(Sweep { r, t, beta, j })
}

/// Smallest r/t (t <= t_max, lowest terms) with J(r, t) >= j_ref, without storing the sweep.
pub fn first_crossing(seg: &Segments, t_max: u64, j_ref: f64) -> Result<Option<(u32, u32)>> {
    if t_max < 2 {
        return Err(Error::invalid(
            "t_max",
            format!("must be at least 2, got {t_max}"),
        ));
    }
    let rmax = (t_max - 1) as usize;
    if seg.w.len() <= rmax {
        return Err(Error::invalid(
            "t_max",
            format!("needs segments up to {rmax}"),
        ));
    }
    let (a, b) = seg.first_r_offsets(rmax);
    let (w0, m0) = (seg.w[0], seg.m[0]);
    let n = t_max as i64;
    let (mut pa, mut pb, mut c, mut d) = (0i64, 1i64, 1i64, n);
    while c < d {
        let t = d as f64;
        let j = (t * w0 + a[c as usize]) / (t * m0 + b[c as usize]);
        if j >= j_ref {
            return Ok(Some((c as u32, d as u32)));
        }
        let k = (n + pb) / d;
        let (nc, nd) = (k * c - pa, k * d - pb);
        (pa, pb, c, d) = (c, d, nc, nd);
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gcd(a: u32, b: u32) -> u32 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }

    #[test]
    fn farey_is_complete_sorted_and_reduced() {
        for n in 2..40u64 {
            let f = farey(n);
            assert_eq!(f.len() as u128, farey_count(n));
            assert!(f
                .windows(2)
                .all(|w| (w[0].0 as u64) * (w[1].1 as u64) < (w[1].0 as u64) * (w[0].1 as u64)));
            assert!(f
                .iter()
                .all(|&(r, t)| gcd(r, t) == 1 && r < t && t as u64 <= n));
        }
        assert_eq!(farey_count(10_000), 30_397_485);
        assert!(farey_bound(10_000) >= 30_397_485);
    }

    #[test]
    fn sweep_matches_single_calls() {
        let lam = 0.5;
        let w: Vec<f64> = (0..400)
            .map(|i| 0.5f64.powi(i) * (1.0 + 1.44f64.powi(i)))
            .collect();
        let seg = Segments::new(&w, lam, 2, 1.0, 60).unwrap();
        let s = sweep(&seg, 61).unwrap();
        for i in (0..s.r.len()).step_by(7) {
            let single = seg.j_first_r(s.r[i] as usize, s.t[i] as usize);
            assert!((s.j[i] - single).abs() <= 1e-13 * single);
        }
        let jref = 1.9;
        let first = first_crossing(&seg, 61, jref).unwrap().unwrap();
        let idx = s.j.iter().position(|&j| j >= jref).unwrap();
        assert_eq!(first, (s.r[idx], s.t[idx]));
    }
}
