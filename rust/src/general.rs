//! The attack chain in full generality, built by exploration: states (τ, z, σ) with z the zeros
//! in the detector's memory since its last reset, any memory mix μ and any periodic blocking
//! mask. It shares no formula with [`crate::pattern`], so it is the independent check of the
//! structured costs, solved by [`crate::stationary::gth`].

use std::collections::HashMap;

use crate::attack::Attack;
use crate::chain::Csr;
use crate::error::{Error, Result};
use crate::online::{check_lam, OnlineDesign};

/// Largest chain [`general_attack_chain`] explores (hashing makes it slower per state than the (τ, σ) chain).
pub const MAX_GENERAL_STATES: u128 = 5_000_000;

/// A state of the general chain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GeneralState {
    /// Holding time since the last arrival.
    pub tau: u64,
    /// Zeros in the detector's memory since its last reset.
    pub zeros: u64,
    /// The attacker's flag-ACK counter.
    pub sigma: u64,
}

const START: GeneralState = GeneralState {
    tau: 0,
    zeros: 0,
    sigma: 0,
};

/// The chain of the protocol with memory z0 used with probability μ (z0 + 1 otherwise) and the
/// attacker blocking flag number σ of each period iff `mask[σ]`. States are numbered in
/// breadth-first order from the paper's initial state (0, 0, 0).
pub fn general_attack_chain(
    lam: f64,
    design: OnlineDesign,
    attack: &Attack,
) -> Result<(Vec<GeneralState>, Csr)> {
    check_lam(lam)?;
    design.validate()?;
    attack.validate()?;
    if attack.blocks_every_flag() {
        return Err(Error::invalid(
            "mask",
            "blocks every flag-ACK: the chain is infinite (its cost is J_max)",
        ));
    }
    let mask = attack.blocking_mask()?;
    let OnlineDesign { z0, mu } = design;
    let a = 1.0 - lam;
    let t = mask.len() as u64;
    let state = |tau, zeros, sigma| GeneralState { tau, zeros, sigma };
    let succ = |GeneralState {
                    tau,
                    zeros: z,
                    sigma,
                }: GeneralState|
     -> Vec<(GeneralState, f64)> {
        let flag = if z == z0 + 1 {
            1.0
        } else if z == z0 {
            mu
        } else {
            0.0
        };
        let mut out = Vec::with_capacity(4);
        if flag > 0.0 {
            let next = (sigma + 1) % t;
            if mask[sigma as usize] {
                // Blocked: memory reset, sensor stays on low power.
                out.push((state(0, 0, next), flag * lam));
                out.push((state(tau + 1, 1, next), flag * a));
            } else {
                // Delivered: high power next step, the packet arrives.
                out.push((state(0, 0, next), flag));
            }
        }
        if flag < 1.0 {
            out.push((state(0, 0, sigma), (1.0 - flag) * lam));
            out.push((state(tau + 1, z + 1, sigma), (1.0 - flag) * a));
        }
        out
    };
    let mut index: HashMap<GeneralState, usize> = HashMap::new();
    let mut states = vec![START];
    index.insert(START, 0);
    let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut i = 0;
    while i < states.len() {
        let mut row: Vec<(usize, f64)> = Vec::new();
        for (s, p) in succ(states[i]) {
            if p == 0.0 {
                continue;
            }
            let j = match index.get(&s) {
                Some(&j) => j,
                None => {
                    if states.len() as u128 >= MAX_GENERAL_STATES {
                        return Err(Error::TooLarge {
                            arg: "(z0, mask)".into(),
                            requested: states.len() as u128 + 1,
                            limit: MAX_GENERAL_STATES,
                        });
                    }
                    states.push(s);
                    index.insert(s, states.len() - 1);
                    states.len() - 1
                }
            };
            match row.iter_mut().find(|e| e.0 == j) {
                Some(e) => e.1 += p,
                None => row.push((j, p)),
            }
        }
        row.sort_by_key(|e| e.0);
        rows.push(row);
        i += 1;
    }
    let n = states.len();
    let mut csr = Csr {
        n,
        indptr: Vec::with_capacity(n + 1),
        indices: Vec::new(),
        data: Vec::new(),
    };
    csr.indptr.push(0);
    for row in rows {
        for (j, p) in row {
            csr.indices.push(j);
            csr.data.push(p);
        }
        csr.indptr.push(csr.indices.len());
    }
    Ok((states, csr))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attack::longest_cyclic_run;
    use crate::pattern::{tau_needed, Segments};
    use crate::stationary::gth;

    fn tr(i: u64) -> f64 {
        1.0 + 0.5 * i as f64 + 1.25f64.powi(i as i32)
    }

    fn j_chain(lam: f64, z0: u64, mu: f64, mask: &[bool]) -> f64 {
        let design = OnlineDesign::new(z0, mu).unwrap();
        let attack = Attack::mask(mask.to_vec()).unwrap();
        let (states, csr) = general_attack_chain(lam, design, &attack).unwrap();
        let pi = gth(&csr).unwrap();
        states.iter().zip(&pi).map(|(s, p)| p * tr(s.tau)).sum()
    }

    #[test]
    fn structured_matches_general_chain() {
        let masks: Vec<Vec<bool>> = vec![
            vec![true, false, false],
            vec![true, true, false, true, false],
            vec![false, true, true, true, false, false, true],
            vec![true, false, true, true],
            vec![false],
        ];
        for &lam in &[0.2f64, 0.5, 0.85] {
            for &mu in &[1.0, 0.6, 0.0] {
                for z0 in 1..4u64 {
                    for mask in &masks {
                        let kmax = longest_cyclic_run(mask) as u64;
                        let w: Vec<f64> = (0..=tau_needed(z0, kmax) as u64)
                            .map(|i| (1.0 - lam).powi(i as i32) * tr(i))
                            .collect();
                        let design = OnlineDesign::new(z0, mu).unwrap();
                        let seg = Segments::new(&w, lam, design, kmax).unwrap();
                        let got = seg.j_mask(mask).unwrap();
                        let expect = j_chain(lam, z0, mu, mask);
                        assert!(
                            (got - expect).abs() < 1e-12 * expect,
                            "lam {lam} mu {mu} z0 {z0} {mask:?}: {got} vs {expect}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn all_blocked_refused() {
        let all = Attack::mask(vec![true, true]).unwrap();
        let design = OnlineDesign::fixed(2).unwrap();
        assert!(general_attack_chain(0.5, design, &all).is_err());
    }
}
