//! Attacks that need no counter: blocking each flag-ACK independently with probability β, and
//! forging flag-ACKs, alone or beside such blocking, in closed renewal form.
//!
//! Between two fresh starts (an arrival, or the high-power step after a flag-ACK reached the
//! sensor) the detector's memory walks as in [`super::periodic`]. With independent blocking the
//! walk does not depend on any counter, so one fresh start to the next is a renewal cycle and
//!
//! J = Σ_τ P_τ c^τ Tr h^τ(P̄) / Σ_τ P_τ c^τ,
//!
//! where c = (1-λ)(1-γ) keeps the walk going on a step without a genuine flag (a loss, and no
//! forgery) and P_τ is the path weight of reaching holding time τ, relative to c^τ: a step
//! without a flag multiplies it by 1 (with probability 1 - μ at z0 zeros), a blocked flag by
//! β ε with ε = 1/(1-γ) (a flag step forges nothing, so it goes on with probability a = c ε).
//! P_τ is carried over the zeros z since the memory's last reset, z = 0..=z0+1, one step at a
//! time: O(z0) per τ, no matrix. β = 0 gives the online cost without attack; β = 1 without
//! forging gives J_max.
//!
//! **When J is infinite.** Tr h^τ(P̄) grows like ρ(A)^(2τ); a blocked flag restarts a run of
//! z0 steps (z0 + 1 with probability 1 - μ), each kept with probability c, so the terms shrink
//! by q = β ε (c ρ²)^z0 (μ + (1-μ) c ρ²) per run in the long run: J is infinite iff q >= 1.
//! Without forging, q = β (a ρ(A)²)^z0 (μ + (1-μ) a ρ(A)²).
//!
//! **No overflow.** The traces are weighted by (c θ)^τ with θ = min(1, 1/(c ρ²)), so they stay
//! bounded, and P_τ is carried as P_τ / θ^τ, which decays whenever q < 1.
//!
//! **Truncation.** Sums run over windows of z0 + 1 steps until the last window's share s
//! satisfies s r / (1 - r) <= 1e-17 of the sum, r the larger of the observed window ratio and
//! the asymptotic one: the bound on a geometric tail, so J is exact to about 1e-16 relative.

use crate::error::{Error, Result};
use crate::schedule::{OnlineDesign, Walk};
use crate::system::LinearSystem;

/// Relative size of the neglected tail of each sum.
pub const TAIL_TOL: f64 = 1e-17;

/// Most holding times summed (as for the weighted traces).
pub const MAX_TAU: usize = 100_000_000;

/// q, the long-run ratio of the cost terms per run of losses (see the module docs); J is
/// finite iff q < 1.
pub fn growth_ratio(walk: &Walk, beta: f64, spectral_radius: f64) -> f64 {
    if beta == 0.0 || walk.gamma == 1.0 {
        return 0.0; // no blocked flag, or no step that goes on: one run of losses at most
    }
    let OnlineDesign { z0, mu } = walk.design;
    let c_rho2 = walk.continuation() * spectral_radius * spectral_radius;
    let eps = walk.ln_block_factor().exp();
    beta * eps * c_rho2.powf(z0 as f64) * (mu + (1.0 - mu) * c_rho2)
}

/// Long-run sums of one renewal cycle under independent blocking.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cycle {
    /// Expected Σ Tr P_k over a cycle (+inf when J is infinite).
    pub cost: f64,
    /// Expected steps per cycle.
    pub steps: f64,
    /// Expected genuine flag-ACKs the detector sends per cycle.
    pub flags: f64,
}

impl Cycle {
    /// J, the long-run average of Tr P_k.
    pub fn j(&self) -> f64 {
        self.cost / self.steps
    }

    /// Genuine flag-ACKs sent per step.
    pub fn sent_rate(&self) -> f64 {
        self.flags / self.steps
    }
}

/// Traces weighted for [`cycle`]: `(c θ)^τ Tr h^τ(P̄)` and θ, grown by doubling on demand.
pub struct ScaledTraces<'a> {
    sys: &'a LinearSystem,
    weight: f64,
    theta: f64,
    values: Vec<f64>,
}

impl<'a> ScaledTraces<'a> {
    /// Traces for the walk's c on `sys` (θ = min(1, 1/(c ρ²))).
    pub fn new(sys: &'a LinearSystem, walk: &Walk) -> Self {
        let c = walk.continuation();
        let c_rho2 = c * sys.spectral_radius() * sys.spectral_radius();
        let theta = if c_rho2 > 1.0 { 1.0 / c_rho2 } else { 1.0 };
        ScaledTraces {
            sys,
            weight: c * theta,
            theta,
            values: Vec::new(),
        }
    }

    fn get(&mut self, tau: usize) -> Result<f64> {
        if tau >= self.values.len() {
            let n = (2 * self.values.len()).max(256).max(tau + 1);
            if n > MAX_TAU {
                return Err(Error::TooLarge {
                    arg: "beta".into(),
                    requested: n as u128,
                    limit: MAX_TAU as u128,
                });
            }
            self.values = self.sys.weighted_traces(self.weight, n);
        }
        Ok(self.values[tau])
    }
}

/// The renewal cycle under independent blocking with probability `beta`, on `walk` (which
/// carries λ, the memory and γ). `traces` must come from the same walk; without them only the
/// time and flag sums are computed (`cost` is NaN).
pub fn cycle(traces: Option<&mut ScaledTraces<'_>>, walk: &Walk, beta: f64) -> Result<Cycle> {
    if !(beta.is_finite() && (0.0..=1.0).contains(&beta)) {
        return Err(Error::invalid(
            "beta",
            format!("must lie in [0, 1], got {beta}"),
        ));
    }
    if walk.gamma == 1.0 {
        // Every step without a genuine flag is forged: each cycle is the one step τ = 0.
        let cost = match traces {
            Some(t) => t.get(0)?,
            None => f64::NAN,
        };
        return Ok(Cycle {
            cost,
            steps: 1.0,
            flags: 0.0,
        });
    }
    let OnlineDesign { z0, mu } = walk.design;
    let z0 = z0 as usize;
    let mass_q = beta * walk.ln_block_factor().exp() * walk.flag_probability();
    // Past the growth condition (or without traces) only the time and flag sums are needed,
    // unscaled.
    let q = traces.as_ref().map_or(f64::INFINITY, |t| {
        growth_ratio(walk, beta, t.sys.spectral_radius())
    });
    let mut traces = traces.filter(|_| q < 1.0);
    let (theta, ct) = match &traces {
        Some(t) => (t.theta, t.weight),
        None => (1.0, walk.continuation()),
    };
    let blocked_weight = beta * walk.ln_block_factor().exp() / theta;
    // p[z]: path weight at the current τ with z zeros since the last reset, over θ^τ.
    let mut p = vec![0.0; z0 + 2];
    p[0] = 1.0;
    let (mut cost, mut steps, mut flags) = (Sum::default(), Sum::default(), Sum::default());
    let mut mass_pow = 1.0; // (c θ)^τ
    for tau in 0.. {
        let total: f64 = p.iter().sum();
        let flag = mu * p[z0] + p[z0 + 1];
        if let Some(t) = traces.as_mut() {
            cost.add(total * t.get(tau)?);
        }
        steps.add(total * mass_pow);
        flags.add(flag * mass_pow);
        if (tau + 1) % (z0 + 1) == 0 {
            let done_cost = traces.is_none() || cost.window_done(q);
            if tau >= MAX_TAU {
                return Err(Error::TooLarge {
                    arg: "beta".into(),
                    requested: tau as u128,
                    limit: MAX_TAU as u128,
                });
            }
            if steps.window_done(mass_q) && flags.window_done(mass_q) && done_cost {
                break;
            }
        }
        step(&mut p, z0, mu, blocked_weight, theta);
        mass_pow *= ct;
    }
    Ok(Cycle {
        cost: match traces {
            Some(_) => cost.total,
            None if q.is_finite() => f64::INFINITY, // past the growth condition
            None => f64::NAN,                       // no traces asked for
        },
        steps: steps.total,
        flags: flags.total,
    })
}

/// One step of the zero count: no flag moves z to z + 1 (z0 to z0 + 1 with probability 1 - μ);
/// a blocked flag restarts it at 1; the walk from a fresh start (z = 0) moves to 1.
fn step(p: &mut [f64], z0: usize, mu: f64, blocked_weight: f64, theta: f64) {
    let flag = mu * p[z0] + p[z0 + 1];
    let restart = p[0] / theta + blocked_weight * flag;
    p[z0 + 1] = (1.0 - mu) * p[z0] / theta;
    for z in (2..=z0).rev() {
        p[z] = p[z - 1] / theta;
    }
    p[1] = restart;
    p[0] = 0.0;
}

/// A running sum with the last two windows' shares, for the tail bound.
#[derive(Default)]
struct Sum {
    total: f64,
    window: f64,
    previous: f64,
}

impl Sum {
    fn add(&mut self, x: f64) {
        self.total += x;
        self.window += x;
    }

    /// Closes a window; true once a geometric tail from here is negligible.
    fn window_done(&mut self, asymptotic: f64) -> bool {
        let observed = if self.previous > 0.0 {
            self.window / self.previous
        } else {
            1.0
        };
        let r = asymptotic.max(observed);
        let done =
            self.window == 0.0 || (r < 1.0 && self.window * r / (1.0 - r) <= TAIL_TOL * self.total);
        (self.previous, self.window) = (self.window, 0.0);
        done
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper() -> LinearSystem {
        LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
    }

    fn walk(lam: f64, z0: u64, mu: f64, gamma: f64) -> Walk {
        Walk::new(lam, OnlineDesign::new(z0, mu).unwrap(), gamma).unwrap()
    }

    fn run(sys: &LinearSystem, w: &Walk, beta: f64) -> Cycle {
        cycle(Some(&mut ScaledTraces::new(sys, w)), w, beta).unwrap()
    }

    /// The (τ, z) chain of the protocol with forging, built state by state and iterated to
    /// its stationary law; truncated at τ = 400, whose mass is far below 1e-18 here.
    fn chain(lam: f64, z0: usize, mu: f64, beta: f64, gamma: f64, tr: &[f64]) -> (f64, f64) {
        let (n, a) = (tr.len(), 1.0 - lam);
        let idx = |tau: usize, z: usize| tau * (z0 + 2) + z;
        let mut pi = vec![0.0; n * (z0 + 2)];
        pi[0] = 1.0;
        let mut sent = 0.0;
        for _ in 0..3000 {
            let mut next = vec![0.0; pi.len()];
            sent = 0.0;
            for tau in 0..n {
                for z in 0..z0 + 2 {
                    let x = pi[idx(tau, z)];
                    let f = if z == z0 + 1 {
                        1.0
                    } else if z == z0 {
                        mu
                    } else {
                        0.0
                    };
                    sent += x * f;
                    // A flag: delivered restarts; blocked goes on (loss) or restarts (arrival).
                    next[0] += x * f * ((1.0 - beta) + beta * lam);
                    if tau + 1 < n {
                        next[idx(tau + 1, 1)] += x * f * beta * a;
                        if f < 1.0 {
                            next[idx(tau + 1, z + 1)] += x * (1.0 - f) * (1.0 - gamma) * a;
                        }
                    }
                    // No flag: a forgery or an arrival restarts.
                    next[0] += x * (1.0 - f) * (gamma + (1.0 - gamma) * lam);
                }
            }
            let total: f64 = next.iter().sum();
            pi = next.iter().map(|x| x / total).collect();
        }
        let j = (0..pi.len()).map(|i| pi[i] * tr[i / (z0 + 2)]).sum();
        (j, sent)
    }

    #[test]
    fn matches_the_explicit_chain() {
        let sys = paper();
        let tr = sys.h_traces(399);
        for &(lam, z0, mu, beta, gamma) in &[
            (0.5, 2u64, 1.0, 0.3, 0.0),
            (0.5, 2, 1.0, 0.9, 0.0),
            (0.3, 3, 0.4, 0.5, 0.0),
            (0.8, 1, 1.0, 0.7, 0.0),
            (0.5, 2, 1.0, 0.0, 0.1),
            (0.5, 2, 0.6, 0.4, 0.05),
            (0.4, 1, 0.0, 1.0, 0.3),
        ] {
            let w = walk(lam, z0, mu, gamma);
            let c = run(&sys, &w, beta);
            let (j, sent) = chain(lam, z0 as usize, mu, beta, gamma, &tr);
            assert!(
                (c.j() - j).abs() < 1e-10 * j,
                "{lam} {z0} {mu} {beta} {gamma}: {} vs {j}",
                c.j()
            );
            assert!(
                (c.sent_rate() - sent).abs() < 1e-12,
                "{} vs {sent}",
                c.sent_rate()
            );
        }
    }

    #[test]
    fn ends_are_no_attack_and_all_blocked() {
        let sys = paper();
        let d = OnlineDesign::new(2, 0.6).unwrap();
        let w = Walk::new(0.5, d, 0.0).unwrap();
        let j_on = sys.j_online(0.5, d).unwrap();
        assert!((run(&sys, &w, 0.0).j() - j_on).abs() < 1e-14 * j_on);
        let rate = d.high_power_rate(0.5).unwrap();
        assert!((run(&sys, &w, 0.0).sent_rate() - rate).abs() < 1e-15);
        let j_max = sys.j_max(0.5).unwrap();
        assert!((run(&sys, &w, 1.0).j() - j_max).abs() < 1e-12 * j_max);
    }

    #[test]
    fn infinite_exactly_past_the_growth_condition() {
        // λ = 0.2: a ρ² = 1.152; z0 = 1, μ = 1: q = 1.152 β, finite iff β < 1/1.152.
        let sys = paper();
        let w = walk(0.2, 1, 1.0, 0.0);
        let edge = 1.0 / 1.152;
        assert!((growth_ratio(&w, edge, 1.2) - 1.0).abs() < 1e-14);
        let below = run(&sys, &w, edge * 0.999);
        assert!(below.j().is_finite() && below.j() > 0.0);
        assert_eq!(run(&sys, &w, edge * 1.001).j(), f64::INFINITY);
        // Near the edge J is large and keeps growing towards it.
        assert!(run(&sys, &w, edge * 0.99).j() < below.j());
    }
}
