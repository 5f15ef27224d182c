//! The attacker as a finite automaton: in each state, for the event "a genuine flag-ACK was sent
//! this step" (flag) or not (quiet), a list of moves (probability, deliver, next state). Every
//! built-in [`Attack`], flag injection with a minimum gap, and the mimicry attack compile to this
//! one form, so the product automaton of [`crate::engine`] needs no case per attack.

use std::collections::HashMap;

use crate::attack::Attack;
use crate::engine::channel::{Channel, ROW_SUM_TOL};
use crate::error::{Error, Result};
use crate::schedule::OnlineDesign;

/// One move of the attacker: with probability `p`, the sensor receives a flag-ACK this step
/// (`deliver`) and the attacker goes to state `next`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    /// Probability of the move, in [0, 1].
    pub p: f64,
    /// Whether the sensor receives a flag-ACK (high power at the next step).
    pub deliver: bool,
    /// The attacker's next state.
    pub next: usize,
}

/// A finite attacker: `flag[s]` and `quiet[s]` list the moves of state `s` after a step with and
/// without a genuine flag-ACK; each list sums to 1. `start` is the state at k = 0.
#[derive(Debug, Clone, PartialEq)]
pub struct AttackerAutomaton {
    flag: Vec<Vec<Move>>,
    quiet: Vec<Vec<Move>>,
    start: usize,
}

impl AttackerAutomaton {
    /// A validated automaton. Refused, naming `automaton`: no states, `flag` and `quiet` of
    /// different lengths, a probability outside [0, 1], a list that does not sum to 1 within
    /// [`ROW_SUM_TOL`], a next state or `start` that is not a state. Moves of zero probability
    /// are dropped, equal moves merged.
    pub fn new(flag: Vec<Vec<Move>>, quiet: Vec<Vec<Move>>, start: usize) -> Result<Self> {
        let n = flag.len();
        let bad = |reason: String| Error::invalid("automaton", reason);
        if n == 0 {
            return Err(bad("must have at least one state".into()));
        }
        if quiet.len() != n {
            return Err(bad(format!(
                "flag has {n} states but quiet has {}",
                quiet.len()
            )));
        }
        if start >= n {
            return Err(bad(format!("start {start} is not a state (0..{n})")));
        }
        for (event, lists) in [("flag", &flag), ("quiet", &quiet)] {
            for (s, moves) in lists.iter().enumerate() {
                for m in moves {
                    if !(m.p.is_finite() && (0.0..=1.0).contains(&m.p)) {
                        return Err(bad(format!(
                            "{event}[{s}]: probability must lie in [0, 1], got {}",
                            m.p
                        )));
                    }
                    if m.next >= n {
                        return Err(bad(format!(
                            "{event}[{s}]: next state {} is not a state (0..{n})",
                            m.next
                        )));
                    }
                }
                let total: f64 = moves.iter().map(|m| m.p).sum();
                if (total - 1.0).abs() > ROW_SUM_TOL {
                    return Err(bad(format!(
                        "{event}[{s}]: probabilities must sum to 1, sum to {total}"
                    )));
                }
            }
        }
        Ok(AttackerAutomaton {
            flag: flag.into_iter().map(merge).collect(),
            quiet: quiet.into_iter().map(merge).collect(),
            start,
        })
    }

    /// The automaton that delivers every genuine flag-ACK and forges none (no attack).
    pub fn none() -> Self {
        AttackerAutomaton {
            flag: vec![vec![pass(0)]],
            quiet: vec![vec![hold(0)]],
            start: 0,
        }
    }

    /// Number of states.
    pub fn n_states(&self) -> usize {
        self.flag.len()
    }

    /// The start state.
    pub fn start(&self) -> usize {
        self.start
    }

    /// The moves of state `s` after a step with (`flag`) or without a genuine flag-ACK.
    pub fn moves(&self, s: usize, flag: bool) -> &[Move] {
        if flag {
            &self.flag[s]
        } else {
            &self.quiet[s]
        }
    }

    /// A built-in attack. Periodic blocking and masks count genuine flag-ACKs modulo their period
    /// (state σ; flag σ is blocked while σ < r, or where the mask says so); random blocking has
    /// one state; flag injection forges on a quiet step with probability γ only if at least
    /// `min_gap` steps have passed since the last flag-ACK that reached the sensor (k_last = 0 at
    /// the start), and runs its blocking part on the genuine flags. `min_gap` must be 1 for an
    /// attack that forges nothing.
    pub fn from_attack(attack: &Attack, min_gap: u64) -> Result<Self> {
        attack.validate()?;
        if min_gap == 0 {
            return Err(Error::invalid("min_gap", "must be at least 1, got 0"));
        }
        match attack {
            Attack::Injection { gamma, block } => {
                let base = match block.as_deref() {
                    None => AttackerAutomaton::none(),
                    Some(b) => AttackerAutomaton::from_attack(b, 1)?,
                };
                Ok(injection(&base, *gamma, min_gap))
            }
            _ if min_gap != 1 => Err(Error::invalid(
                "min_gap",
                format!("applies to flag injection only, got {min_gap} for \"{attack}\""),
            )),
            Attack::Random { beta } => Ok(AttackerAutomaton {
                flag: vec![merge(vec![
                    Move {
                        p: *beta,
                        deliver: false,
                        next: 0,
                    },
                    Move {
                        p: 1.0 - beta,
                        deliver: true,
                        next: 0,
                    },
                ])],
                quiet: vec![vec![hold(0)]],
                start: 0,
            }),
            _ => {
                let mask = attack.blocking_mask()?;
                let t = mask.len();
                let flag = (0..t)
                    .map(|s| {
                        vec![Move {
                            p: 1.0,
                            deliver: !mask[s],
                            next: (s + 1) % t,
                        }]
                    })
                    .collect();
                let quiet = (0..t).map(|s| vec![hold(s)]).collect();
                Ok(AttackerAutomaton {
                    flag,
                    quiet,
                    start: 0,
                })
            }
        }
    }

    /// The mimicry attacker: it runs a virtual attack-free detector `design` over its own
    /// `channel` with its own coin flips, and the sensor receives a flag-ACK exactly when the
    /// virtual detector sends one (the genuine flag passed if there is one, forged otherwise;
    /// every other genuine flag blocked). The virtual packet uses the power the real sensor uses,
    /// high exactly after a delivered flag, which is a virtual flag: so the virtual system is an
    /// attack-free system from the paper's initial condition (high power at k = 1, memory all
    /// ones, the virtual channel stationary). State: (virtual channel, virtual zero count,
    /// virtual power), plus one start state that mixes the virtual channel's first state.
    pub fn mimicry(channel: &Channel, design: OnlineDesign) -> Result<Self> {
        design.validate()?;
        let (z0, mu) = (design.z0 as usize, design.mu);
        let k = channel.n_states();
        // Virtual state code (c, z, power) -> c + k (z + (z0 + 1) power).
        let code = |c: usize, z: usize, hi: bool| c + k * (z + (z0 + 1) * usize::from(hi));
        // Moves of a virtual state as (p, flag, next code).
        let step = |c: usize, z: usize, hi: bool| -> Vec<(f64, bool, usize)> {
            let pa = if hi {
                channel.high()[c]
            } else {
                channel.low()[c]
            };
            let mut out = Vec::new();
            for (arrived, pr) in [(true, pa), (false, 1.0 - pa)] {
                if pr == 0.0 {
                    continue;
                }
                for (pd, flag, z1) in detector(z, arrived, z0, mu) {
                    for (c1, &pc) in channel.row(c).iter().enumerate() {
                        if pc > 0.0 && pd > 0.0 {
                            out.push((pr * pd * pc, flag, code(c1, z1, flag)));
                        }
                    }
                }
            }
            out
        };
        // Breadth-first from the start state (index 0), whose moves mix the stationary c_1.
        let mut index: HashMap<usize, usize> = HashMap::new();
        let mut codes: Vec<usize> = vec![usize::MAX];
        let mut moves: Vec<Vec<Move>> = Vec::new();
        let mut i = 0;
        while i < codes.len() {
            let raw: Vec<(f64, bool, usize)> = if i == 0 {
                channel
                    .stationary()
                    .iter()
                    .enumerate()
                    .filter(|(_, &w)| w > 0.0)
                    .flat_map(|(c, &w)| {
                        step(c, 0, true)
                            .into_iter()
                            .map(move |(p, f, n)| (w * p, f, n))
                    })
                    .collect()
            } else {
                let x = codes[i];
                let (c, rest) = (x % k, x / k);
                step(c, rest % (z0 + 1), rest / (z0 + 1) == 1)
            };
            let mut list = Vec::with_capacity(raw.len());
            for (p, deliver, nc) in raw {
                let next = *index.entry(nc).or_insert_with(|| {
                    codes.push(nc);
                    codes.len() - 1
                });
                list.push(Move { p, deliver, next });
            }
            moves.push(merge(list));
            i += 1;
        }
        Ok(AttackerAutomaton {
            flag: moves.clone(),
            quiet: moves,
            start: 0,
        })
    }
}

/// The remote detector's step from zero count `z` (0..=z0; z0 only after the μ coin said "not
/// yet"): `(probability, flag sent, next count)`. An arrival restarts the count; a loss grows it,
/// and a flag-ACK goes out when it reaches z0 (with probability μ) or z0 + 1 (always), restarting
/// the memory.
pub(crate) fn detector(z: usize, arrived: bool, z0: usize, mu: f64) -> Vec<(f64, bool, usize)> {
    if arrived {
        return vec![(1.0, false, 0)];
    }
    let zz = z + 1;
    if zz > z0 {
        vec![(1.0, true, 0)]
    } else if zz == z0 {
        let mut v = Vec::with_capacity(2);
        if mu > 0.0 {
            v.push((mu, true, 0));
        }
        if mu < 1.0 {
            v.push((1.0 - mu, false, z0));
        }
        v
    } else {
        vec![(1.0, false, zz)]
    }
}

fn pass(next: usize) -> Move {
    Move {
        p: 1.0,
        deliver: true,
        next,
    }
}

fn hold(next: usize) -> Move {
    Move {
        p: 1.0,
        deliver: false,
        next,
    }
}

/// Drops moves of zero probability and merges equal (deliver, next) pairs, in first-seen order.
fn merge(moves: Vec<Move>) -> Vec<Move> {
    let mut out: Vec<Move> = Vec::with_capacity(moves.len());
    for m in moves {
        if m.p == 0.0 {
            continue;
        }
        match out
            .iter_mut()
            .find(|o| o.deliver == m.deliver && o.next == m.next)
        {
            Some(o) => o.p += m.p,
            None => out.push(m),
        }
    }
    out
}

/// Flag injection over the blocking automaton `base`: state (b, h), h = min(steps since the last
/// delivered flag-ACK, min_gap - 1) with h = 0 at k = 0, so forging at step k is allowed iff
/// h = min_gap - 1 (k - k_last >= min_gap). The min_gap states of the interface,
/// min(k - k_last, min_gap), collapse to these min_gap, which forge alike.
fn injection(base: &AttackerAutomaton, gamma: f64, min_gap: u64) -> AttackerAutomaton {
    let g = min_gap.min(u64::from(u32::MAX)) as usize;
    let id = |b: usize, h: usize| b * g + h;
    let later = |h: usize| (h + 1).min(g - 1);
    let nb = base.n_states();
    let mut flag = Vec::with_capacity(nb * g);
    let mut quiet = Vec::with_capacity(nb * g);
    for b in 0..nb {
        for h in 0..g {
            flag.push(merge(
                base.flag[b]
                    .iter()
                    .map(|m| Move {
                        p: m.p,
                        deliver: m.deliver,
                        next: id(m.next, if m.deliver { 0 } else { later(h) }),
                    })
                    .collect(),
            ));
            let forge = if h == g - 1 { gamma } else { 0.0 };
            quiet.push(merge(vec![
                Move {
                    p: forge,
                    deliver: true,
                    next: id(b, 0),
                },
                Move {
                    p: 1.0 - forge,
                    deliver: false,
                    next: id(b, later(h)),
                },
            ]));
        }
    }
    AttackerAutomaton {
        flag,
        quiet,
        start: id(base.start, 0),
    }
}
