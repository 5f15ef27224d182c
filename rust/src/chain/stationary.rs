//! Stationary distribution of the attack chain and the attacked cost J(θ̃_on).
//!
//! Two independent solvers:
//! * [`structured`]: O(|S|), never builds the matrix. Level σ is a reset-to-zero walk in τ whose
//!   segment k (τ in (z0 k, z0(k+1)], segment 0 = 0..z0) is fed by the trigger of segment k-1 in
//!   level σ-1. Balancing the level-crossing (flag-ACK) rate F gives, with u = a^z0,
//!   π(τ, σ) = (F/u) c̃(σ - k) a^τ, where c̃(0) = 1, c̃(1..=r) = 1 - u and c̃(σ > r) = 1.
//! * [`gth`]: Grassmann-Taksar-Heyman state reduction on any row-stochastic CSR matrix, free of
//!   subtractions and so accurate to a few ulps; general but slower.
//!
//! [`j_attack`] sums the structured law against the weighted traces per segment (the renewal
//! form of [`crate::renewal::periodic`]): O(r z0), so |S| = 10^7 and beyond costs microseconds.

use std::collections::BTreeMap;

use crate::chain::{AttackChain, Csr};
use crate::error::{Error, Result};
use crate::renewal::periodic::{tau_needed, Segments};
use crate::schedule::{apow, OnlineDesign};

/// Largest stationary vector [`structured`] will allocate (0.8 GB of f64).
pub const MAX_VECTOR_STATES: u128 = 100_000_000;

/// Pairwise summation: error O(log n · eps) instead of O(n · eps).
pub fn pairwise_sum(x: &[f64]) -> f64 {
    if x.len() <= 256 {
        x.iter().sum()
    } else {
        let (l, r) = x.split_at(x.len() / 2);
        pairwise_sum(l) + pairwise_sum(r)
    }
}

/// A stationary vector of `n` states may be allocated (at most [`MAX_VECTOR_STATES`]).
fn check_vector(n: u128) -> Result<()> {
    if n > MAX_VECTOR_STATES {
        return Err(Error::TooLarge {
            arg: "(z0, r, t)".into(),
            requested: n,
            limit: MAX_VECTOR_STATES,
        });
    }
    Ok(())
}

/// Stationary law in the paper's state order, in O(|S|) without building the matrix.
pub fn structured(chain: &AttackChain) -> Result<Vec<f64>> {
    let n = chain.num_states();
    check_vector(n)?;
    let a = 1.0 - chain.lam;
    // Normaliser D = Σ c̃(σ-k) a^τ over all states: the renewal form's denominator.
    let mass: Vec<f64> = (0..=tau_needed(chain.z0, chain.r))
        .map(|tau| apow(chain.lam, tau as u64))
        .collect();
    let seg = Segments::new(&mass, chain.lam, OnlineDesign::fixed(chain.z0)?, chain.r)?;
    let scale = 1.0 / seg.first_r_numerator(chain.r as usize, chain.t as usize);
    let mut pi = Vec::with_capacity(n as usize);
    for sigma in 0..chain.t {
        let mut pow = scale;
        for tau in 0..=chain.tau_max(sigma) {
            let k = chain.segment(tau);
            pi.push(chain.c_tilde(sigma - k) * pow);
            pow *= a;
        }
    }
    Ok(pi)
}

/// J(θ̃_on) = Σ_S π(τ, σ) Tr h^τ(P̄) from the weighted traces w_τ = a^τ Tr h^τ(P̄),
/// τ = 0..=(r+1)(z0+1): the structured law summed per segment (the renewal form of
/// [`crate::renewal::periodic`] with μ = 1). O(r z0).
pub fn j_attack(chain: &AttackChain, w: &[f64]) -> Result<f64> {
    let seg = Segments::new(w, chain.lam, OnlineDesign::fixed(chain.z0)?, chain.r)?;
    Ok(seg.j_first_r(chain.r as usize, chain.t as usize))
}

/// ||π T - π||_1 for the attack chain, applying rules 1)-4) on the fly (no matrix).
pub fn balance_residual(chain: &AttackChain, pi: &[f64]) -> f64 {
    let mut next = vec![0.0; pi.len()];
    let mut i = 0;
    for sigma in 0..chain.t {
        for tau in 0..=chain.tau_max(sigma) {
            let (steps, k) = chain.successors(tau, sigma);
            for &((ta, si), p) in &steps[..k] {
                next[chain.index(ta, si) as usize] += p * pi[i];
            }
            i += 1;
        }
    }
    next.iter().zip(pi).map(|(x, y)| (x - y).abs()).sum()
}

/// Stationary law of any irreducible row-stochastic CSR matrix by GTH state reduction.
pub fn gth(m: &Csr) -> Result<Vec<f64>> {
    let n = m.n;
    if n == 0 {
        return Err(Error::invalid("T", "has no states"));
    }
    // Rows as ordered maps (fill-in lands here); columns as the set of rows pointing in.
    let mut rows: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); n];
    let mut cols: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, row) in rows.iter_mut().enumerate() {
        for k in m.indptr[i]..m.indptr[i + 1] {
            let (j, p) = (m.indices[k], m.data[k]);
            if !(p.is_finite() && p >= 0.0) || j >= n {
                return Err(Error::invalid("T", format!("bad entry ({i}, {j}) = {p}")));
            }
            if p > 0.0 {
                *row.entry(j).or_insert(0.0) += p;
                cols[j].push(i);
            }
        }
    }
    let mut s = vec![0.0; n];
    for k in (1..n).rev() {
        let sk: f64 = rows[k].range(..k).map(|(_, p)| p).sum();
        if sk <= 0.0 {
            return Err(Error::invalid(
                "T",
                format!("the chain is reducible (state {k} cannot reach a lower state)"),
            ));
        }
        s[k] = sk;
        let outs: Vec<(usize, f64)> = rows[k].range(..k).map(|(&j, &p)| (j, p / sk)).collect();
        let mut ins = std::mem::take(&mut cols[k]);
        ins.sort_unstable();
        ins.dedup();
        for &i in ins.iter().filter(|&&i| i < k) {
            let pik = rows[i][&k];
            for &(j, pkj) in &outs {
                let e = rows[i].entry(j).or_insert_with(|| {
                    cols[j].push(i);
                    0.0
                });
                *e += pik * pkj;
            }
        }
        cols[k] = ins;
    }
    let mut pi = vec![0.0; n];
    pi[0] = 1.0;
    for k in 1..n {
        let v: f64 = cols[k]
            .iter()
            .filter(|&&i| i < k)
            .map(|&i| pi[i] * rows[i][&k])
            .sum();
        pi[k] = v / s[k];
    }
    let total = pairwise_sum(&pi);
    pi.iter_mut().for_each(|x| *x /= total);
    Ok(pi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structured_matches_gth() {
        for &(lam, z0, r, t) in &[
            (0.5, 2, 1, 3),
            (0.3, 1, 0, 1),
            (0.3, 1, 0, 4),
            (0.7, 3, 4, 7),
            (0.05, 2, 5, 6),
            (0.95, 4, 2, 9),
            (0.5, 2, 6, 12),
        ] {
            let c = AttackChain::new(lam, z0, r, t).unwrap();
            let fast = structured(&c).unwrap();
            let slow = gth(&c.build_csr().unwrap()).unwrap();
            for (x, y) in fast.iter().zip(&slow) {
                assert!((x - y).abs() <= 1e-13, "{lam} {z0} {r} {t}: {x} vs {y}");
            }
            assert!((pairwise_sum(&fast) - 1.0).abs() < 1e-13);
            assert!(balance_residual(&c, &fast) < 1e-14);
        }
    }

    /// The vector limit is inclusive, checked before allocating (kills `>` turned `>=`/`==`).
    #[test]
    fn vector_limit_is_inclusive() {
        assert!(check_vector(MAX_VECTOR_STATES).is_ok());
        let e = check_vector(MAX_VECTOR_STATES + 1).unwrap_err().to_string();
        assert!(e.contains(&(MAX_VECTOR_STATES + 1).to_string()), "{e}");
    }

    /// The residual is ||π T - π||_1 itself: 0 for the stationary law; for the point mass on
    /// state 0 of the paper's chain (z0 = 2, r = 1, t = 3, λ = 1/2) the mass moves to the
    /// states (0, 0) and (1, 0) of the same level with 1/2 each, so ||π T - π||_1 = 1/2 + 1/2
    /// = 1 (kills a constant residual).
    #[test]
    fn balance_residual_measures_the_imbalance() {
        let c = AttackChain::new(0.5, 2, 1, 3).unwrap();
        let pi = structured(&c).unwrap();
        assert!(balance_residual(&c, &pi) < 1e-15);
        let mut point = vec![0.0; pi.len()];
        point[0] = 1.0;
        assert!((balance_residual(&c, &point) - 1.0).abs() < 1e-15);
    }

    /// Negative, NaN or infinite entries and columns past n are refused, each on its own
    /// (kills the entry check with `&&`/`||` swapped).
    #[test]
    fn gth_refuses_bad_entries() {
        for (j, p) in [(1, -0.5), (1, f64::NAN), (1, f64::INFINITY), (2, 0.5)] {
            let m = Csr {
                n: 2,
                indptr: vec![0, 2, 4],
                indices: vec![0, j, 0, 1],
                data: vec![0.5, p, 0.2, 0.8],
            };
            let e = gth(&m).unwrap_err().to_string();
            assert!(e.starts_with("T:"), "{e}");
        }
    }

    #[test]
    fn gth_two_state() {
        // QuantEcon's test chain: [[0.4, 0.6], [0.2, 0.8]] -> [0.25, 0.75].
        let m = Csr {
            n: 2,
            indptr: vec![0, 2, 4],
            indices: vec![0, 1, 0, 1],
            data: vec![0.4, 0.6, 0.2, 0.8],
        };
        let pi = gth(&m).unwrap();
        assert!((pi[0] - 0.25).abs() < 1e-15 && (pi[1] - 0.75).abs() < 1e-15);
    }

    #[test]
    fn j_attack_equals_pi_dot_traces() {
        let tr: Vec<f64> = (0..100).map(|i| 1.0 + 1.2f64.powi(i)).collect();
        for &(lam, z0, r, t) in &[(0.5, 2, 1, 5), (0.4, 3, 3, 4), (0.6, 1, 7, 11)] {
            let c = AttackChain::new(lam, z0, r, t).unwrap();
            let w: Vec<f64> = tr
                .iter()
                .enumerate()
                .map(|(i, x)| (1.0 - lam).powi(i as i32) * x)
                .collect();
            let pi = gth(&c.build_csr().unwrap()).unwrap();
            let direct: f64 = c
                .states()
                .unwrap()
                .iter()
                .zip(&pi)
                .map(|(&(tau, _), p)| p * tr[tau as usize])
                .sum();
            let j = j_attack(&c, &w).unwrap();
            assert!((j - direct).abs() < 1e-12 * direct, "{j} vs {direct}");
        }
    }

    /// r = 0 is the unattacked online schedule: J = λ/(1 - a^(z0+1)) Σ_{i≤z0} w_i.
    #[test]
    fn no_attack_is_online() {
        let w: Vec<f64> = (0..10).map(|i| 0.6f64.powi(i) * (2.0 + i as f64)).collect();
        let c = AttackChain::new(0.4, 3, 0, 5).unwrap();
        let expect = 0.4 / (1.0 - 0.6f64.powi(4)) * w[..4].iter().sum::<f64>();
        assert!((j_attack(&c, &w).unwrap() - expect).abs() < 1e-14 * expect);
    }

    /// The renewal form's first-r and mask costs ([`Segments`]) against the structured chain.
    #[test]
    fn first_r_matches_structured_chain() {
        for &(lam, z0, r, t) in &[
            (0.5, 2u64, 1usize, 3usize),
            (0.3, 3, 4, 7),
            (0.8, 1, 0, 5),
            (0.6, 2, 6, 13),
        ] {
            // The weighted traces of periodic's tests: a^i (1 + 1.3^i).
            let w: Vec<f64> = (0..=200usize)
                .map(|i| (1.0f64 - lam).powi(i as i32) * (1.0 + 1.3f64.powi(i as i32)))
                .collect();
            let seg = Segments::new(&w, lam, OnlineDesign::fixed(z0).unwrap(), r as u64).unwrap();
            let chain = AttackChain::new(lam, z0, r as u64, t as u64).unwrap();
            let expect = j_attack(&chain, &w).unwrap();
            let got = seg.j_first_r(r, t);
            assert!((got - expect).abs() < 1e-13 * expect, "{got} vs {expect}");
            let mask: Vec<bool> = (0..t).map(|i| i < r).collect();
            let via_mask = seg.j_mask(&mask).unwrap();
            assert!((via_mask - expect).abs() < 1e-13 * expect);
        }
    }
}
