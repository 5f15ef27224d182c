//! The fake-ACK attack chain S_k = (τ_k, σ_k) of Sec. IV-B, with transition rules 1)-4) and the
//! state order of the paper: levels σ = 0..t-1, within a level τ = 0, 1, .... Level σ ≤ r holds
//! τ = 0..z0(σ+1); level σ > r holds τ = 0..z0. A flag-ACK is due when τ > 0 and τ mod z0 = 0;
//! the attacker blocks it while σ < r (Model note 3: "<", not "≤").
//!
//! This module groups the explicit chains, one of the routes the crate cross-checks the renewal
//! forms of [`crate::renewal`] with: the paper's chain here (and its sparse matrix [`Csr`]), the
//! chain in full generality by exploration ([`general`]), their stationary laws ([`stationary`])
//! and exact finite-horizon curves by propagating the state law ([`transient`]).

pub mod general;
pub mod stationary;
pub mod transient;

use crate::attack::Attack;
use crate::error::{Error, Result};
use crate::schedule::{check_lam, one_minus_apow, OnlineDesign};

/// Largest chain [`AttackChain::build_csr`] will materialise (about 0.5 GB as CSR).
pub const MAX_BUILD_STATES: u128 = 20_000_000;

/// Number of states r(r+1)z0/2 + t(z0+1), exact.
pub fn num_states(z0: u64, r: u64, t: u64) -> u128 {
    let (z0, r, t) = (z0 as u128, r as u128, t as u128);
    r * (r + 1) / 2 * z0 + t * (z0 + 1)
}

/// A row-stochastic sparse matrix in CSR form.
#[derive(Debug, Clone, PartialEq)]
pub struct Csr {
    /// Number of rows (= columns).
    pub n: usize,
    /// Row pointers, `n + 1` entries: row i is `indptr[i]..indptr[i + 1]`.
    pub indptr: Vec<usize>,
    /// Column of each stored entry.
    pub indices: Vec<usize>,
    /// Value of each stored entry.
    pub data: Vec<f64>,
}

impl Csr {
    /// Checks the CSR invariants: `indptr` starts at 0, never decreases and ends at the number
    /// of entries; `indices` and `data` have that length; every column is below `n`.
    pub fn validate(&self) -> Result<()> {
        let ok = self.indptr.len() == self.n + 1
            && self.indptr.first() == Some(&0)
            && self.indptr.windows(2).all(|w| w[0] <= w[1])
            && self.indptr.last() == Some(&self.indices.len())
            && self.indices.len() == self.data.len()
            && self.indices.iter().all(|&j| j < self.n);
        if ok {
            Ok(())
        } else {
            Err(Error::invalid("T", "malformed CSR arrays"))
        }
    }
}

/// The attack chain for memory length z0 (μ = 1) under "block the first r of every t flag-ACKs".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttackChain {
    /// Arrival probability λ at low power.
    pub lam: f64,
    /// Memory length z0.
    pub z0: u64,
    /// Blocked flag-ACKs per period.
    pub r: u64,
    /// Period in flag-ACKs.
    pub t: u64,
}

/// One transition: destination (τ, σ) and its probability.
pub type Step = ((u64, u64), f64);

impl AttackChain {
    /// The chain for arrival probability `lam`, memory `z0` and "block the first r of every t".
    pub fn new(lam: f64, z0: u64, r: u64, t: u64) -> Result<Self> {
        check_lam(lam)?;
        OnlineDesign::fixed(z0)?;
        Attack::periodic(r, t)?;
        Ok(AttackChain { lam, z0, r, t })
    }

    /// c̃(j) of [`crate::chain::stationary`]'s docs: the relative rate at which level j's walk is
    /// entered at τ = 0 (1 - u after a blocked flag, 1 otherwise).
    pub fn c_tilde(&self, j: u64) -> f64 {
        if j == 0 || j > self.r {
            1.0
        } else {
            one_minus_apow(self.lam, self.z0)
        }
    }

    /// Segment of τ: 0 for τ ≤ z0, else ⌈τ/z0⌉ - 1.
    pub fn segment(&self, tau: u64) -> u64 {
        if tau <= self.z0 {
            0
        } else {
            (tau - 1) / self.z0
        }
    }

    /// |S| = r(r+1)z0/2 + t(z0+1).
    pub fn num_states(&self) -> u128 {
        num_states(self.z0, self.r, self.t)
    }

    /// Largest τ of level σ: z0(σ+1) while σ ≤ r, z0 after.
    pub fn tau_max(&self, sigma: u64) -> u64 {
        if sigma <= self.r {
            self.z0 * (sigma + 1)
        } else {
            self.z0
        }
    }

    /// Index of (0, σ) in the paper's order.
    pub fn level_offset(&self, sigma: u64) -> u64 {
        let z0 = self.z0;
        if sigma <= self.r {
            z0 * sigma * (sigma + 1) / 2 + sigma
        } else {
            let r = self.r;
            z0 * (r + 1) * (r + 2) / 2 + (r + 1) + (sigma - r - 1) * (z0 + 1)
        }
    }

    /// Index of state (τ, σ).
    pub fn index(&self, tau: u64, sigma: u64) -> u64 {
        self.level_offset(sigma) + tau
    }

    /// Whether the detector sends a flag-ACK at holding time τ.
    pub fn is_trigger(&self, tau: u64) -> bool {
        tau > 0 && tau % self.z0 == 0
    }

    /// Transition rules 1)-4): up to two successors of (τ, σ).
    pub fn successors(&self, tau: u64, sigma: u64) -> ([Step; 2], usize) {
        let (lam, a) = (self.lam, 1.0 - self.lam);
        if !self.is_trigger(tau) {
            // Rule 1): no flag-ACK.
            ([((0, sigma), lam), ((tau + 1, sigma), a)], 2)
        } else if sigma < self.r {
            // Rule 2): the flag-ACK is blocked, the counter advances, the sensor stays on low power.
            ([((0, sigma + 1), lam), ((tau + 1, sigma + 1), a)], 2)
        } else {
            // Rules 3) and 4): the flag-ACK passes, high power next step, counter advances mod t.
            let next = if sigma + 1 == self.t { 0 } else { sigma + 1 };
            ([((0, next), 1.0), ((0, next), 0.0)], 1)
        }
    }

    /// All states as (τ, σ) in the paper's order.
    pub fn states(&self) -> Result<Vec<(u64, u64)>> {
        self.check_buildable()?;
        let mut out = Vec::with_capacity(self.num_states() as usize);
        for sigma in 0..self.t {
            for tau in 0..=self.tau_max(sigma) {
                out.push((tau, sigma));
            }
        }
        Ok(out)
    }

    fn check_buildable(&self) -> Result<()> {
        let n = self.num_states();
        if n > MAX_BUILD_STATES {
            return Err(Error::TooLarge {
                arg: "(z0, r, t)".into(),
                requested: n,
                limit: MAX_BUILD_STATES,
            });
        }
        Ok(())
    }

    /// The row-stochastic transition matrix T[i, j] = P[S_{k+1} = j | S_k = i].
    pub fn build_csr(&self) -> Result<Csr> {
        self.check_buildable()?;
        let n = self.num_states() as usize;
        let mut indptr = Vec::with_capacity(n + 1);
        let mut indices = Vec::with_capacity(2 * n);
        let mut data = Vec::with_capacity(2 * n);
        indptr.push(0);
        for sigma in 0..self.t {
            for tau in 0..=self.tau_max(sigma) {
                let (steps, k) = self.successors(tau, sigma);
                let mut row: Vec<(usize, f64)> = steps[..k]
                    .iter()
                    .map(|&((ta, si), p)| (self.index(ta, si) as usize, p))
                    .collect();
                row.sort_by_key(|e| e.0);
                for (j, p) in row {
                    indices.push(j);
                    data.push(p);
                }
                indptr.push(indices.len());
            }
        }
        Ok(Csr {
            n,
            indptr,
            indices,
            data,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each CSR invariant on its own: one broken at a time is refused, naming `T` (kills a
    /// validate that accepts everything, and any `&&` turned `||`).
    #[test]
    fn csr_validate_checks_every_invariant() {
        let good = Csr {
            n: 2,
            indptr: vec![0, 1, 3],
            indices: vec![1, 0, 1],
            data: vec![1.0, 0.5, 0.5],
        };
        assert!(good.validate().is_ok());
        let broken: [fn(&mut Csr); 6] = [
            |c| c.indptr.push(3),         // n + 1 row pointers
            |c| c.indptr = vec![1, 1, 3], // starts at 0
            |c| c.indptr = vec![0, 4, 3], // never decreases
            |c| c.indptr = vec![0, 1, 2], // ends at the number of entries
            |c| c.data.push(0.0),         // data as long as indices
            |c| c.indices[0] = 2,         // columns below n
        ];
        for (k, breaks) in broken.iter().enumerate() {
            let mut c = good.clone();
            breaks(&mut c);
            let e = c.validate().expect_err(&format!("invariant {k}"));
            assert!(e.to_string().starts_with("T:"), "{e}");
        }
    }

    /// The limit is inclusive: exactly MAX_BUILD_STATES states may be built, one more is refused
    /// (checked without allocating; kills `>` → `>=` in check_buildable).
    #[test]
    fn build_limit_is_inclusive() {
        let at = AttackChain::new(0.5, 1, 0, 10_000_000).unwrap(); // 2 t states
        assert_eq!(at.num_states(), MAX_BUILD_STATES);
        assert!(at.check_buildable().is_ok());
        let over = AttackChain::new(0.5, 2, 0, 6_666_667).unwrap(); // 3 t states
        assert_eq!(over.num_states(), MAX_BUILD_STATES + 1);
        let e = over.check_buildable().unwrap_err().to_string();
        assert!(e.contains("20000001") && e.contains("20000000"), "{e}");
    }

    #[test]
    fn state_count_formula() {
        for z0 in 1..5 {
            for t in 1..9 {
                for r in 0..t {
                    let c = AttackChain::new(0.3, z0, r, t).unwrap();
                    assert_eq!(c.states().unwrap().len() as u128, c.num_states());
                    assert_eq!(
                        c.level_offset(t - 1) + c.tau_max(t - 1) + 1,
                        c.num_states() as u64
                    );
                }
            }
        }
    }

    /// The paper's 11x11 example (z0 = 2, r = 1, t = 3), written out by hand from rules 1)-4) in
    /// the paper's column-stochastic convention, with Model note 4 applied (column 3's λ in row 4).
    #[test]
    #[allow(clippy::needless_range_loop)]
    fn paper_example_matrix() {
        let (l, a) = (0.37, 0.63);
        #[rustfmt::skip]
        let ts: [[f64; 11]; 11] = [
            [l, l, 0., 0., 0., 0., 0., 0., 0., 0., 1.],
            [a, 0., 0., 0., 0., 0., 0., 0., 0., 0., 0.],
            [0., a, 0., 0., 0., 0., 0., 0., 0., 0., 0.],
            [0., 0., l, l, l, 0., l, 0., 0., 0., 0.],
            [0., 0., 0., a, 0., 0., 0., 0., 0., 0., 0.],
            [0., 0., 0., 0., a, 0., 0., 0., 0., 0., 0.],
            [0., 0., a, 0., 0., 0., 0., 0., 0., 0., 0.],
            [0., 0., 0., 0., 0., 0., a, 0., 0., 0., 0.],
            [0., 0., 0., 0., 0., 1., 0., 1., l, l, 0.],
            [0., 0., 0., 0., 0., 0., 0., 0., a, 0., 0.],
            [0., 0., 0., 0., 0., 0., 0., 0., 0., a, 0.],
        ];
        let c = AttackChain::new(l, 2, 1, 3).unwrap();
        let csr = c.build_csr().unwrap();
        assert_eq!(csr.n, 11);
        let mut dense = [[0.0; 11]; 11];
        for i in 0..11 {
            for k in csr.indptr[i]..csr.indptr[i + 1] {
                dense[i][csr.indices[k]] += csr.data[k];
            }
        }
        for i in 0..11 {
            for j in 0..11 {
                // Row-stochastic T is the transpose of the paper's T_s.
                assert!((dense[i][j] - ts[j][i]).abs() < 1e-15, "entry ({i}, {j})");
            }
        }
    }

    #[test]
    fn rows_sum_to_one() {
        let c = AttackChain::new(0.2, 3, 4, 7).unwrap();
        let csr = c.build_csr().unwrap();
        for i in 0..csr.n {
            let s: f64 = csr.data[csr.indptr[i]..csr.indptr[i + 1]].iter().sum();
            assert!((s - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn refuses_huge_chain() {
        let c = AttackChain::new(0.5, 2, 100_000, 200_000).unwrap();
        assert!(matches!(c.build_csr(), Err(Error::TooLarge { .. })));
    }
}
