//! Exact finite-horizon curves E[Tr P_k], k = 1..horizon, by propagating the state law (no
//! sampling), from the paper's initial condition: high power at k = 1 (τ_1 = 0), memory all ones,
//! attacker counter 0.

use crate::chain::Csr;
use crate::error::{Error, Result};

/// Largest horizon × transitions a curve may cost.
pub const MAX_WORK: u128 = 1_000_000_000;

fn check_horizon(horizon: usize, per_step: usize) -> Result<()> {
    if horizon == 0 {
        return Err(Error::invalid("horizon", "must be at least 1"));
    }
    let work = horizon as u128 * per_step.max(1) as u128;
    if work > MAX_WORK {
        return Err(Error::TooLarge {
            arg: "horizon".into(),
            requested: work,
            limit: MAX_WORK,
        });
    }
    Ok(())
}

/// Trace at holding time τ, +inf beyond the table (never reached for bounded τ).
fn trace_at(tr: &[f64], tau: usize) -> f64 {
    tr.get(tau).copied().unwrap_or(f64::INFINITY)
}

/// Offline periodic schedule: `pattern[(k-1) % q] == 1` is high power at step k.
/// `tr` must cover the longest run of zeros.
pub fn offline(tr: &[f64], lam: f64, pattern: &[u8], horizon: usize) -> Result<Vec<f64>> {
    if pattern.first() != Some(&1) {
        return Err(Error::invalid(
            "pattern",
            "must start with a high-power step (1)",
        ));
    }
    let cap = tr.len().max(1);
    check_horizon(horizon, cap)?;
    let a = 1.0 - lam;
    // law[τ]: probability of holding time τ (τ < cap; beyond the table mass is kept in `over`).
    let mut law = vec![0.0; cap];
    let mut out = Vec::with_capacity(horizon);
    let mut over = 0.0;
    for k in 0..horizon {
        if pattern[k % pattern.len()] == 1 {
            law.iter_mut().for_each(|x| *x = 0.0);
            law[0] = 1.0;
            over = 0.0;
        } else {
            let total: f64 = law.iter().sum::<f64>() + over;
            over = a * (over + law[cap - 1]);
            for tau in (1..cap).rev() {
                law[tau] = a * law[tau - 1];
            }
            law[0] = lam * total;
        }
        // Holding times not yet reached have probability 0 and may have an infinite trace.
        let mut e: f64 = law
            .iter()
            .zip(tr)
            .filter(|(p, _)| **p > 0.0)
            .map(|(p, t)| p * t)
            .sum();
        if over > 0.0 {
            e = f64::INFINITY;
        }
        out.push(e);
    }
    Ok(out)
}

/// Any chain: `states_tau[i]` is state i's holding time, state 0 the initial state.
pub fn chain(csr: &Csr, states_tau: &[u64], tr: &[f64], horizon: usize) -> Result<Vec<f64>> {
    check_horizon(horizon, csr.indices.len())?;
    let n = csr.n;
    if states_tau.len() != n || n == 0 {
        return Err(Error::invalid(
            "states_tau",
            "must give one holding time per state",
        ));
    }
    let mut law = vec![0.0; n];
    let mut next = vec![0.0; n];
    law[0] = 1.0;
    let trs: Vec<f64> = states_tau
        .iter()
        .map(|&t| trace_at(tr, t as usize))
        .collect();
    let mut out = Vec::with_capacity(horizon);
    for k in 0..horizon {
        out.push(
            law.iter()
                .zip(&trs)
                .filter(|(p, _)| **p > 0.0)
                .map(|(p, t)| p * t)
                .sum(),
        );
        if k + 1 == horizon {
            break;
        }
        next.iter_mut().for_each(|x| *x = 0.0);
        for (i, &p) in law.iter().enumerate() {
            if p == 0.0 {
                continue;
            }
            for e in csr.indptr[i]..csr.indptr[i + 1] {
                next[csr.indices[e]] += p * csr.data[e];
            }
        }
        std::mem::swap(&mut law, &mut next);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::general;

    #[test]
    fn online_curve_converges_to_stationary() {
        let lam = 0.5;
        let tr: Vec<f64> = (0..40).map(|i| 1.0 + i as f64).collect();
        let design = crate::schedule::OnlineDesign::fixed(2).unwrap();
        let no_attack = crate::attack::Attack::mask(vec![false]).unwrap();
        let (states, csr) = general::general_attack_chain(lam, design, &no_attack).unwrap();
        let taus: Vec<u64> = states.iter().map(|s| s.tau).collect();
        let c = chain(&csr, &taus, &tr, 200).unwrap();
        assert_eq!(c[0], tr[0]);
        // Step 2: low power, τ = 0 or 1 with probability 1/2 each.
        assert!((c[1] - 0.5 * (tr[0] + tr[1])).abs() < 1e-15);
        // J_on = λ/(1-a^3) (tr0 + a tr1 + a² tr2).
        let jon = 0.5 / (1.0 - 0.125) * (tr[0] + 0.5 * tr[1] + 0.25 * tr[2]);
        assert!((c[199] - jon).abs() < 1e-12);
    }

    /// Holding times not yet reached carry probability 0: an infinite trace there must not turn
    /// E Tr P_k into 0 · inf = NaN (a long offline period past the double range).
    #[test]
    fn unreached_infinite_traces_do_not_poison_the_curve() {
        let mut tr: Vec<f64> = (0..10).map(|i| 1.0 + i as f64).collect();
        tr[9] = f64::INFINITY;
        let pattern = [1, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        let c = offline(&tr, 0.5, &pattern, 10).unwrap();
        assert_eq!(c[0], 1.0);
        assert!((c[1] - (0.5 * 1.0 + 0.5 * 2.0)).abs() < 1e-15);
        assert!(c[..9].iter().all(|x| x.is_finite()));
        assert_eq!(c[9], f64::INFINITY); // reached with probability 2^-9
    }

    #[test]
    fn offline_curve_is_periodic() {
        let tr: Vec<f64> = (0..10).map(|i| 2.0f64.powi(i)).collect();
        let c = offline(&tr, 0.3, &[1, 0, 0], 9).unwrap();
        assert_eq!(c[0], 1.0);
        assert!((c[1] - (0.3 + 0.7 * 2.0)).abs() < 1e-15);
        assert_eq!(c[3], 1.0);
        assert!((c[4] - c[1]).abs() < 1e-15);
    }

    /// The work limit is inclusive (horizon × transitions = MAX_WORK passes, one step more is
    /// refused) and a zero horizon is refused (kills a check that accepts everything, `*` turned
    /// `+` or `/`, `>` turned `>=` or `==`).
    #[test]
    fn horizon_limits() {
        assert!(check_horizon(0, 5).is_err());
        assert!(check_horizon(1, 5).is_ok());
        let per = 1000usize;
        let h = (MAX_WORK / per as u128) as usize;
        assert!(check_horizon(h, per).is_ok());
        let e = check_horizon(h + 1, per).unwrap_err().to_string();
        assert!(e.contains(&(MAX_WORK + per as u128).to_string()), "{e}");
    }

    /// A table shorter than a run of low-power steps: the mass beyond it makes E Tr P_k
    /// infinite until the next high-power step (kills `over` accumulated with `-` or `*`).
    #[test]
    fn mass_beyond_the_table_is_infinite() {
        let tr = [1.0, 2.0];
        let c = offline(&tr, 0.5, &[1, 0, 0, 0], 6).unwrap();
        assert_eq!(c[0], 1.0);
        assert!((c[1] - 1.5).abs() < 1e-15);
        assert_eq!((c[2], c[3]), (f64::INFINITY, f64::INFINITY)); // τ = 2 has no trace
        assert_eq!(c[4], 1.0);
        assert!((c[5] - 1.5).abs() < 1e-15);
    }

    /// One holding time per state, and at least one state (kills the check's `||` turned `&&`).
    #[test]
    fn chain_needs_one_holding_time_per_state() {
        let two = Csr {
            n: 2,
            indptr: vec![0, 1, 2],
            indices: vec![1, 0],
            data: vec![1.0, 1.0],
        };
        assert!(chain(&two, &[0, 1], &[1.0, 2.0], 3).is_ok());
        assert!(chain(&two, &[0], &[1.0, 2.0], 3).is_err());
        let empty = Csr {
            n: 0,
            indptr: vec![0],
            indices: vec![],
            data: vec![],
        };
        assert!(chain(&empty, &[], &[1.0], 3).is_err());
    }

    /// States not yet reached carry probability 0: their infinite trace must not make the
    /// curve NaN (kills `p > 0` turned `>=`).
    #[test]
    fn chain_skips_unreached_infinite_traces() {
        // A cycle 0 -> 1 -> 2 -> 0 with holding times 0, 1, 2; the table stops at τ = 1.
        let cycle = Csr {
            n: 3,
            indptr: vec![0, 1, 2, 3],
            indices: vec![1, 2, 0],
            data: vec![1.0, 1.0, 1.0],
        };
        let c = chain(&cycle, &[0, 1, 2], &[1.0, 2.0], 3).unwrap();
        assert_eq!(c, vec![1.0, 2.0, f64::INFINITY]);
    }
}
