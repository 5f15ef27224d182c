//! The attack chain in full generality, built by exploration: states (τ, z, σ) with z the zeros
//! in the detector's memory since its last reset, any memory mix μ and any periodic blocking
//! mask. It shares no formula with [`crate::renewal::periodic`], so it is the independent check
//! of the structured costs, solved by [`crate::chain::stationary::gth`].

use std::collections::HashMap;

use crate::attack::Attack;
use crate::chain::Csr;
use crate::error::{Error, Result};
use crate::schedule::{check_lam, OnlineDesign};

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

/// The chain of the protocol with memory z0 used with probability μ (z0 + 1 otherwise) under
/// any attack: flag number σ of each period is blocked with probability `mask[σ]` (0 or 1 for
/// a periodic attack; β for independent blocking, with a period of one), and a flag-ACK is forged
/// with probability γ on every step without a genuine one. States are numbered in breadth-first
/// order from the paper's initial state (0, 0, 0).
///
/// An attack that can block flags without end (independent blocking with β > 0, a mask of all
/// ones) makes the chain infinite: it is refused, unless `tau_cap` bounds the holding time (the
/// exact transient curves over H steps need τ < H only, since τ_k <= k - 1).
pub fn general_attack_chain(
    lam: f64,
    design: OnlineDesign,
    attack: &Attack,
) -> Result<(Vec<GeneralState>, Csr)> {
    capped_attack_chain(lam, design, attack, None)
}

/// [`general_attack_chain`] with holding times above `tau_cap` (if given) folded into
/// `tau_cap`: exact for the first `tau_cap + 1` steps from the initial state.
pub fn capped_attack_chain(
    lam: f64,
    design: OnlineDesign,
    attack: &Attack,
    tau_cap: Option<u64>,
) -> Result<(Vec<GeneralState>, Csr)> {
    check_lam(lam)?;
    design.validate()?;
    attack.validate()?;
    let gamma = attack.forging();
    let block: Vec<f64> = match attack.genuine_blocking() {
        None => vec![0.0],
        Some(Attack::Random { beta }) => vec![*beta],
        Some(b) => b
            .blocking_mask()?
            .iter()
            .map(|&x| f64::from(u8::from(x)))
            .collect(),
    };
    let endless = match attack.genuine_blocking() {
        Some(Attack::Random { beta }) => *beta > 0.0,
        Some(b) => b.blocks_every_flag(),
        None => false,
    };
    if endless && tau_cap.is_none() {
        return Err(Error::invalid(
            "attack",
            "can block flag-ACKs without end: the chain is infinite (its cost is J_max for a \
             mask of all ones; independent blocking is solved in closed form)",
        ));
    }
    let cap = tau_cap.unwrap_or(u64::MAX);
    let OnlineDesign { z0, mu } = design;
    let a = 1.0 - lam;
    let t = block.len() as u64;
    let state = |tau: u64, zeros, sigma| GeneralState {
        tau: tau.min(cap),
        zeros,
        sigma,
    };
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
        let mut out = Vec::with_capacity(5);
        if flag > 0.0 {
            let next = (sigma + 1) % t;
            let b = block[sigma as usize];
            // Blocked: memory reset, the sensor stays on low power.
            out.push((state(0, 0, next), flag * b * lam));
            out.push((state(tau + 1, 1, next), flag * b * a));
            // Delivered: high power next step, the packet arrives.
            out.push((state(0, 0, next), flag * (1.0 - b)));
        }
        if flag < 1.0 {
            // No genuine flag: a forged one or an arrival restarts the walk.
            out.push((
                state(0, 0, sigma),
                (1.0 - flag) * (gamma + (1.0 - gamma) * lam),
            ));
            out.push((
                state(tau + 1, z + 1, sigma),
                (1.0 - flag) * (1.0 - gamma) * a,
            ));
        }
        out
    };
    explore(succ, MAX_GENERAL_STATES)
}

/// Breadth-first exploration from [`START`] with the successor function `succ`: the states in
/// discovery order and the row-stochastic CSR matrix of their transitions.
fn explore(
    succ: impl Fn(GeneralState) -> Vec<(GeneralState, f64)>,
    limit: u128,
) -> Result<(Vec<GeneralState>, Csr)> {
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
                    if states.len() as u128 >= limit {
                        return Err(Error::TooLarge {
                            arg: "(z0, mask)".into(),
                            requested: states.len() as u128 + 1,
                            limit,
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
    use crate::chain::stationary::gth;
    use crate::renewal::periodic::{tau_needed, Segments};

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
    fn random_blocking_and_forging_match_the_closed_form() {
        // A cap far beyond where the mass lives makes the capped chain's J the stationary one.
        let sys = crate::LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap();
        let tr = sys.h_traces(300);
        let design = OnlineDesign::new(2, 0.7).unwrap();
        for attack in [
            Attack::random(0.4).unwrap(),
            Attack::injection(0.1, None).unwrap(),
            Attack::injection(0.05, Some(Attack::periodic(1, 3).unwrap())).unwrap(),
            Attack::injection(0.2, Some(Attack::random(0.6).unwrap())).unwrap(),
        ] {
            let (states, csr) = capped_attack_chain(0.5, design, &attack, Some(300)).unwrap();
            let pi = gth(&csr).unwrap();
            let j: f64 = states
                .iter()
                .zip(&pi)
                .map(|(s, p)| p * tr[s.tau as usize])
                .sum();
            let expect = sys.j_attack(0.5, design, &attack).unwrap();
            assert!(
                (j - expect).abs() < 1e-10 * expect,
                "{attack}: {j} vs {expect}"
            );
        }
        let endless = general_attack_chain(0.5, design, &Attack::random(0.4).unwrap());
        assert!(endless.unwrap_err().to_string().starts_with("attack:"));
    }

    #[test]
    fn all_blocked_refused() {
        let all = Attack::mask(vec![true, true]).unwrap();
        let design = OnlineDesign::fixed(2).unwrap();
        assert!(general_attack_chain(0.5, design, &all).is_err());
        assert!(general_attack_chain(0.5, design, &Attack::Random { beta: 0.3 }).is_err());
    }

    /// The state limit is inclusive and the error names the first state over it (kills a wrong
    /// count in the message): a walk τ = 0, 1, 2, ... restarting at `len` has `len` states.
    #[test]
    fn exploration_limit_is_inclusive() {
        let walk = |len: u64| {
            move |s: GeneralState| {
                let next = if s.tau + 1 == len { 0 } else { s.tau + 1 };
                vec![(GeneralState { tau: next, ..s }, 1.0)]
            }
        };
        let (states, _) = explore(walk(5), 5).unwrap();
        assert_eq!(states.len(), 5);
        let e = explore(walk(6), 5).unwrap_err().to_string();
        assert!(e.contains('6') && e.contains('5'), "{e}");
    }

    /// Independent blocking with β = 0 blocks nothing: a finite chain, the unattacked one
    /// (kills refusing every independent attack, `beta > 0` turned `>=`).
    #[test]
    fn random_blocking_of_nothing_is_the_unattacked_chain() {
        let design = OnlineDesign::fixed(2).unwrap();
        let none = Attack::Random { beta: 0.0 };
        let (states, t) = general_attack_chain(0.5, design, &none).unwrap();
        // (τ, z): (0, 0) -> (1, 1) -> (2, 2), whose flag brings the next arrival.
        assert_eq!(states.len(), 3);
        assert_eq!(t.n, 3);
        let unattacked = Attack::mask(vec![false]).unwrap();
        let (states_u, t_u) = general_attack_chain(0.5, design, &unattacked).unwrap();
        assert_eq!((states, t), (states_u, t_u));
    }
}
