//! The β sweep over every r/t in lowest terms, and the attacker threshold β̄.
//!
//! "Block the first r of every t" is a renewal cycle, so J(r, t) = (t W_0 + a_r) / (t M_0 + b_r)
//! with a_r, b_r accumulated once per r ([`Segments::first_r_offsets`]). The
//! fractions come from the Farey sequence of order t_max, already sorted by β, at O(1) each.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::renewal::periodic::Segments;

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

/// The reduced fractions r/t with 1 <= r < t <= n in increasing order (the Farey sequence of
/// order n without its ends), O(1) per term by the next-term recurrence.
pub struct Farey {
    n: i64,
    prev: (i64, i64),
    cur: (i64, i64),
}

impl Farey {
    /// The fractions r/t in lowest terms with 1 <= r < t <= n, in increasing order.
    pub fn new(n: u64) -> Self {
        let n = n.max(1) as i64;
        Farey {
            n,
            prev: (0, 1),
            cur: (1, n),
        }
    }
}

impl Iterator for Farey {
    type Item = (u32, u32);

    fn next(&mut self) -> Option<(u32, u32)> {
        let ((a, b), (c, d)) = (self.prev, self.cur);
        if c >= d {
            return None;
        }
        let k = (self.n + b) / d;
        self.prev = (c, d);
        self.cur = (k * c - a, k * d - b);
        Some((c as u32, d as u32))
    }
}

/// All reduced r/t with 1 <= r < t <= n, in increasing order of r/t.
pub fn farey(n: u64) -> Vec<(u32, u32)> {
    Farey::new(n).collect()
}

/// Checks t_max and returns the per-r offsets (a_r, b_r) and (W_0, M_0) a sweep needs.
/// What J(r, t) = (t W_0 + a_r) / (t M_0 + b_r) needs for every r < t_max (see
/// [`Segments::first_r_offsets`]).
struct FirstR {
    a: Vec<f64>,
    b: Vec<f64>,
    w0: f64,
    m0: f64,
}

impl FirstR {
    #[inline]
    fn j(&self, r: u32, t: u32) -> f64 {
        let (a, b) = (self.a[r as usize], self.b[r as usize]);
        crate::renewal::periodic::first_r_j(t as f64, self.w0, a, self.m0, b)
    }
}

fn offsets(seg: &Segments, t_max: u64) -> Result<FirstR> {
    check_t_max(t_max)?;
    offsets_to(seg, (t_max - 1) as usize)
}

fn check_t_max(t_max: u64) -> Result<()> {
    if t_max < 2 {
        return Err(Error::invalid(
            "t_max",
            format!("must be at least 2, got {t_max}"),
        ));
    }
    Ok(())
}

/// The offsets for r = 0..=rmax: those of a deeper call, cut (each a_r reads segments 0..=r).
fn offsets_to(seg: &Segments, rmax: usize) -> Result<FirstR> {
    if seg.w.len() <= rmax {
        return Err(Error::invalid(
            "t_max",
            format!("needs segments up to {rmax}"),
        ));
    }
    let (a, b) = seg.first_r_offsets(rmax);
    Ok(FirstR {
        a,
        b,
        w0: seg.w[0],
        m0: seg.m[0],
    })
}

/// Result of a sweep: one entry per fraction, in increasing β.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    /// Blocked flag-ACKs per period.
    pub r: Vec<u32>,
    /// Period in flag-ACKs.
    pub t: Vec<u32>,
    /// β = r / t.
    pub beta: Vec<f64>,
    /// J(r, t) under "block the first r of every t".
    pub j: Vec<f64>,
}

/// J(r, t) for every reduced r/t with t <= t_max. `seg` must hold segments 0..t_max-1.
pub fn sweep(seg: &Segments, t_max: u64) -> Result<Sweep> {
    if t_max > u32::MAX as u64 || farey_bound(t_max) > MAX_FRACTIONS {
        return Err(Error::TooLarge {
            arg: "t_max".into(),
            requested: farey_bound(t_max),
            limit: MAX_FRACTIONS,
        });
    }
    let first_r = offsets(seg, t_max)?;
    let fr = farey(t_max);
    let j: Vec<f64> = fr
        .par_iter()
        .with_min_len(1 << 16)
        .map(|&(r, t)| first_r.j(r, t))
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
    let first_r = offsets(seg, t_max)?;
    Ok(Farey::new(t_max).find(|&(r, t)| first_r.j(r, t) >= j_ref))
}

/// [`first_crossing`], building only the segments it reaches: `build(k)` gives segments 0..=k.
///
/// The fractions are visited in increasing order, as there, with segments 0..=`depth`, until one
/// needs a deeper segment (r > depth); then the depth doubles (at most t_max - 1) and the visit
/// goes on. The segments and offsets of a depth are the first entries of the deeper ones
/// (segment k and offset r read nothing beyond k and r), so the answer is
/// [`first_crossing`]'s, bit for bit, at a fraction of the O(t_max²) work of the segments when
/// the crossing is at a small β (a grid study's common case). `depth` is the first depth tried.
pub fn first_crossing_by_depth(
    build: impl Fn(u64) -> Result<Segments>,
    t_max: u64,
    j_ref: f64,
    depth: u64,
) -> Result<Option<(u32, u32)>> {
    check_t_max(t_max)?;
    let full = t_max - 1;
    let mut depth = depth.clamp(1, full);
    let mut fractions = Farey::new(t_max).peekable();
    loop {
        let first_r = offsets_to(&build(depth)?, depth as usize)?;
        while let Some(&(r, t)) = fractions.peek() {
            if u64::from(r) > depth {
                break;
            }
            fractions.next();
            if first_r.j(r, t) >= j_ref {
                return Ok(Some((r, t)));
            }
        }
        if fractions.peek().is_none() {
            return Ok(None);
        }
        depth = (2 * depth).min(full);
    }
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
        // The bound is 0.31 n² + n (3/π² n² < 0.304 n² is the count's growth): exact values,
        // and never below the count.
        assert_eq!(farey_bound(1000), 311_000);
        assert_eq!(farey_bound(7), 22);
        for n in [2u64, 3, 10, 100, 1000] {
            assert!(farey_bound(n) >= farey_count(n), "{n}");
        }
    }

    #[test]
    fn sweep_matches_single_calls() {
        let lam = 0.5;
        let w: Vec<f64> = (0..400)
            .map(|i| 0.5f64.powi(i) * (1.0 + 1.44f64.powi(i)))
            .collect();
        let design = crate::schedule::OnlineDesign::fixed(2).unwrap();
        let seg = Segments::new(&w, lam, design, 60).unwrap();
        let s = sweep(&seg, 61).unwrap();
        for i in 0..s.r.len() {
            assert_eq!(s.beta[i], s.r[i] as f64 / s.t[i] as f64);
        }
        for i in (0..s.r.len()).step_by(7) {
            let single = seg.j_first_r(s.r[i] as usize, s.t[i] as usize);
            assert!((s.j[i] - single).abs() <= 1e-13 * single);
        }
        let jref = 1.9;
        let first = first_crossing(&seg, 61, jref).unwrap().unwrap();
        let idx = s.j.iter().position(|&j| j >= jref).unwrap();
        assert_eq!(first, (s.r[idx], s.t[idx]));
    }

    /// t_max from 2 on; the first t_max whose Farey bound passes MAX_FRACTIONS (35,920) is
    /// refused as too large before any segment is read (kills the size check's `||` turned
    /// `&&` and `>` turned `==`, and `t_max < 2` turned `<=` or `==`).
    #[test]
    fn sweep_limits() {
        let w: Vec<f64> = (0..40).map(|i| 0.5f64.powi(i)).collect();
        let design = crate::schedule::OnlineDesign::fixed(2).unwrap();
        let seg = Segments::new(&w, 0.5, design, 2).unwrap();
        assert_eq!(sweep(&seg, 2).unwrap().r, vec![1]);
        assert!(first_crossing(&seg, 2, 0.0).unwrap().is_some());
        for bad in [0, 1] {
            assert!(sweep(&seg, bad).is_err() && first_crossing(&seg, bad, 0.0).is_err());
        }
        assert!(farey_bound(35_919) <= MAX_FRACTIONS && farey_bound(35_920) > MAX_FRACTIONS);
        assert!(matches!(sweep(&seg, 35_920), Err(Error::TooLarge { .. })));
    }

    /// Depth by depth gives the full sweep's crossing for every reference cost, start depth and
    /// memory mix, including no crossing at all (kills a visit that skips the fraction at which
    /// the depth runs out, or that stops a depth too early or too late).
    #[test]
    fn crossing_by_depth_is_the_full_crossing() {
        let lam = 0.5;
        let w: Vec<f64> = (0..400)
            .map(|i| 0.5f64.powi(i) * (1.0 + 1.44f64.powi(i)))
            .collect();
        for mu in [1.0, 0.4] {
            let design = crate::schedule::OnlineDesign::new(2, mu).unwrap();
            let seg = Segments::new(&w, lam, design, 40).unwrap();
            let s = sweep(&seg, 41).unwrap();
            let build = |k| Segments::new(&w, lam, design, k);
            let mut refs: Vec<f64> = s.j.iter().step_by(5).copied().collect();
            refs.extend([
                0.0,
                f64::INFINITY,
                s.j.iter().copied().fold(0.0, f64::max) * 1.01,
            ]);
            for j_ref in refs {
                let full = first_crossing(&seg, 41, j_ref).unwrap();
                for depth in [0, 1, 3, 16, 40, 100] {
                    let got = first_crossing_by_depth(build, 41, j_ref, depth).unwrap();
                    assert_eq!(got, full, "mu {mu}, j_ref {j_ref}, depth {depth}");
                }
            }
        }
        assert!(first_crossing_by_depth(
            |k| Segments::new(&w, lam, crate::schedule::OnlineDesign::fixed(2).unwrap(), k),
            1,
            1.0,
            4
        )
        .is_err());
    }
}
