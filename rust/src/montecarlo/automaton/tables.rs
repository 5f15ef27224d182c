//! Validation of an [`AutomatonConfig`] and the tables the kernel steps through ([`Plan`]):
//! arrival thresholds, alias tables of the channel rows, of c_1's law and of every attacker
//! (state, event), and the trace table.

use nalgebra::{DMatrix, DVector};

use super::{Attacker, AutomatonConfig, Sensor, Transition};
use crate::engine::AttackerAutomaton;
use crate::error::{Error, Result};
use crate::montecarlo::state::StateModel;
use crate::montecarlo::{Mode, MAX_HORIZON, MAX_RECORDED_RUNS};
use crate::schedule::OnlineDesign;
use crate::system::LinearSystem;

/// Largest deviation from 1 of a channel row or of an event's probabilities.
const SUM_TOL: f64 = 1e-9;
/// Most attacker states, channel states and transitions per event (the tables use u32 indices).
const MAX_ENTRIES: usize = 1 << 26;
/// Longest offline pattern.
const MAX_PATTERN: usize = 1 << 30;
/// 2^63 as a float.
const TWO63: f64 = 9_223_372_036_854_775_808.0;

/// The 63-bit threshold T = ⌊p 2^63⌋ (p clamped to [0, 1]): `(u >> 1) < T` is Bernoulli(T / 2^63)
/// for uniform u, exact at p = 0 and p = 1.
pub(super) fn threshold63(p: f64) -> u64 {
    if p.is_nan() || p <= 0.0 {
        0
    } else if p >= 1.0 {
        1 << 63
    } else {
        (p * TWO63) as u64
    }
}

/// One column of an alias table: below `thr` the draw keeps the column's own value, else it
/// takes its alias's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Entry {
    /// The 63-bit threshold.
    pub(super) thr: u64,
    /// The value of this column (an attacker's outcome, a channel state).
    pub(super) own: u64,
    /// The value of its alias.
    pub(super) alt: u64,
}

/// Alias tables of several distributions over values, stored one after another.
#[derive(Debug, Clone, Default)]
pub(in crate::montecarlo) struct Aliases {
    /// Per distribution, its first column and its number of columns.
    pub(super) index: Vec<(u32, u32)>,
    /// The columns.
    pub(super) entries: Vec<Entry>,
}

impl Aliases {
    /// Appends the alias table of the distribution `p` over `values` (non-negative, summing to
    /// about 1), by Vose's construction; returns its number.
    pub(super) fn push(&mut self, p: &[f64], values: &[u64]) -> usize {
        let n = p.len();
        let total: f64 = p.iter().sum();
        let mut q: Vec<f64> = p.iter().map(|x| x / total * n as f64).collect();
        let mut thr = vec![1u64 << 63; n];
        let mut alias: Vec<usize> = (0..n).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| q[i] < 1.0);
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            thr[s] = threshold63(q[s]);
            alias[s] = l;
            q[l] = (q[l] + q[s]) - 1.0;
            if q[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // What is left has q = 1 up to rounding: it keeps itself (threshold 2^63).
        let off = self.entries.len();
        self.entries.extend((0..n).map(|i| Entry {
            thr: thr[i],
            own: values[i],
            alt: values[alias[i]],
        }));
        self.index.push((off as u32, n as u32));
        self.index.len() - 1
    }

    /// The value distribution `dist` gives for the random word `u`: the high part of `u · n`
    /// chooses a column, the top 63 bits of the low part keep it or take its alias.
    #[inline(always)]
    pub(in crate::montecarlo) fn draw(&self, dist: usize, u: u64) -> u64 {
        let (off, n) = self.index[dist];
        let m = u128::from(u) * u128::from(n);
        let e = &self.entries[off as usize + (m >> 64) as usize];
        if ((m as u64) >> 1) < e.thr {
            e.own
        } else {
            e.alt
        }
    }
}

/// What the attacker table holds per (state, event) after its draw: `next << 1 | deliver`.
pub(super) fn outcome(t: &Transition) -> u64 {
    ((t.next as u64) << 1) | u64::from(t.deliver)
}

/// The validated, precomputed experiment.
pub(super) struct Plan {
    /// Steps per run.
    pub(super) horizon: usize,
    /// Runs.
    pub(super) runs: u64,
    /// The seed.
    pub(super) seed: u64,
    /// Keep each run's delivered flag-ACK count.
    pub(super) record_runs: bool,
    /// Channel states K.
    pub(super) k: usize,
    /// Arrival thresholds, entry `2 c + high`.
    pub(super) arrive: Vec<u64>,
    /// The channel rows (distributions 0..K) and the law of c_1 (distribution K).
    pub(super) channel: Aliases,
    /// Whether the sensor follows the online schedule (else the offline pattern).
    pub(super) online: bool,
    /// z0.
    pub(super) z0: u64,
    /// Whether the memory length is drawn each step (0 < μ < 1).
    pub(super) mu_draw: bool,
    /// ⌊μ 2^63⌋.
    pub(super) mu_thr: u64,
    /// The memory length when it is not drawn: z0 for μ = 1, z0 + 1 for μ = 0.
    pub(super) fixed_memory: u64,
    /// The offline pattern (1 = high), empty online.
    pub(super) pattern: Vec<u64>,
    /// High-power steps of the offline pattern within the horizon.
    pub(super) offline_high: u64,
    /// The attacker's events, distribution `2 s + flag`, over the outcomes
    /// `next << 1 | deliver`.
    pub(super) attacker: Aliases,
    /// The attacker's start state.
    pub(super) start: u64,
    /// `tr[τ]`, up to where it settles.
    pub(super) tr: Vec<f64>,
    /// The error recursions (state mode), `None` in covariance mode.
    pub(super) state: Option<StateModel>,
}

/// Checks a probability named `arg`.
fn probability(arg: &str, where_: String, p: f64) -> Result<()> {
    if p.is_finite() && (0.0..=1.0).contains(&p) {
        Ok(())
    } else {
        Err(Error::invalid(
            arg,
            format!("{where_} must lie in [0, 1], got {p}"),
        ))
    }
}

/// The stationary law of the row-stochastic `p` (one closed class): the solution of
/// π (I - P) = 0, Σ π = 1, with the last equation replaced by the normalisation (non-singular
/// when the closed class is unique).
fn stationary(p: &[Vec<f64>]) -> Result<Vec<f64>> {
    let k = p.len();
    // M' π = e_k with M = (I - P) whose last column is replaced by ones.
    let mut mt = DMatrix::<f64>::zeros(k, k);
    for i in 0..k {
        for j in 0..k {
            let m = if j == k - 1 {
                1.0
            } else {
                f64::from(u8::from(i == j)) - p[i][j]
            };
            mt[(j, i)] = m;
        }
    }
    let mut rhs = DVector::<f64>::zeros(k);
    rhs[k - 1] = 1.0;
    let bad = || {
        Error::invalid(
            "P",
            "must have exactly one closed class (a unique stationary law)",
        )
    };
    let pi = mt.lu().solve(&rhs).ok_or_else(bad)?;
    if pi.iter().any(|x| !x.is_finite() || *x < -1e-9) {
        return Err(bad());
    }
    let pi: Vec<f64> = pi.iter().map(|x| x.max(0.0)).collect();
    let total: f64 = pi.iter().sum();
    Ok(pi.iter().map(|x| x / total).collect())
}

/// Checks the channel and builds its tables: arrival thresholds, row aliases, c_1's law.
fn channel_tables(cfg: &AutomatonConfig) -> Result<(Vec<u64>, Aliases)> {
    let ch = &cfg.channel;
    let k = ch.p.len();
    if k == 0 {
        return Err(Error::invalid("P", "must have at least one state"));
    }
    if k > 4096 {
        return Err(Error::TooLarge {
            arg: "P".into(),
            requested: k as u128,
            limit: 4096,
        });
    }
    for (i, row) in ch.p.iter().enumerate() {
        if row.len() != k {
            return Err(Error::invalid(
                "P",
                format!("must be square: row {i} has {} entries, not {k}", row.len()),
            ));
        }
        for (j, &x) in row.iter().enumerate() {
            probability("P", format!("P[{i}][{j}]"), x)?;
        }
        let s: f64 = row.iter().sum();
        if (s - 1.0).abs() > SUM_TOL {
            return Err(Error::invalid(
                "P",
                format!("must be row-stochastic: row {i} sums to {s}"),
            ));
        }
    }
    for (arg, v) in [("low", &ch.low), ("high", &ch.high)] {
        if v.len() != k {
            return Err(Error::invalid(
                arg,
                format!(
                    "must have one entry per channel state ({k}), got {}",
                    v.len()
                ),
            ));
        }
        for (i, &x) in v.iter().enumerate() {
            probability(arg, format!("{arg}[{i}]"), x)?;
        }
    }
    let pi = stationary(&ch.p)?;
    let mut arrive = Vec::with_capacity(2 * k);
    for c in 0..k {
        arrive.push(threshold63(ch.low[c]));
        arrive.push(threshold63(ch.high[c]));
    }
    let mut aliases = Aliases::default();
    let states: Vec<u64> = (0..k as u64).collect();
    for row in &ch.p {
        aliases.push(row, &states);
    }
    aliases.push(&pi, &states);
    Ok((arrive, aliases))
}

/// Checks the attacker and builds its tables (distribution `2 s + flag`).
fn attacker_tables(att: &Attacker) -> Result<(Aliases, u64)> {
    let n = att.flag.len();
    if n == 0 {
        return Err(Error::invalid("flag", "must list at least one state"));
    }
    if att.quiet.len() != n {
        return Err(Error::invalid(
            "quiet",
            format!(
                "must list as many states as flag ({n}), got {}",
                att.quiet.len()
            ),
        ));
    }
    if n > MAX_ENTRIES {
        return Err(Error::TooLarge {
            arg: "flag".into(),
            requested: n as u128,
            limit: MAX_ENTRIES as u128,
        });
    }
    if att.start >= n {
        return Err(Error::invalid(
            "start",
            format!("must be a state (0..{}), got {}", n - 1, att.start),
        ));
    }
    let mut aliases = Aliases::default();
    for s in 0..n {
        for (arg, events) in [("quiet", &att.quiet), ("flag", &att.flag)] {
            let ev = &events[s];
            if ev.is_empty() {
                return Err(Error::invalid(
                    arg,
                    format!("state {s} lists no transition"),
                ));
            }
            if aliases.entries.len() + ev.len() > MAX_ENTRIES {
                return Err(Error::TooLarge {
                    arg: arg.into(),
                    requested: (aliases.entries.len() + ev.len()) as u128,
                    limit: MAX_ENTRIES as u128,
                });
            }
            for (i, t) in ev.iter().enumerate() {
                probability(
                    arg,
                    format!("state {s}, transition {i}: the probability"),
                    t.p,
                )?;
                if t.next >= n {
                    return Err(Error::invalid(
                        arg,
                        format!(
                            "state {s}, transition {i}: next state {} is not a state (0..{})",
                            t.next,
                            n - 1
                        ),
                    ));
                }
            }
            let total: f64 = ev.iter().map(|t| t.p).sum();
            if (total - 1.0).abs() > SUM_TOL {
                return Err(Error::invalid(
                    arg,
                    format!("state {s}: the probabilities must sum to 1, got {total}"),
                ));
            }
            let p: Vec<f64> = ev.iter().map(|t| t.p).collect();
            let values: Vec<u64> = ev.iter().map(outcome).collect();
            aliases.push(&p, &values);
        }
    }
    Ok((aliases, att.start as u64))
}

/// The alias tables of an attacker automaton of the exact engine (validated by its constructor),
/// in the layout of [`attacker_tables`]: distribution `2 s + flag` over the outcomes
/// `next << 1 | deliver`. For the closed-loop game kernel, which draws its attacker as this
/// kernel does. Refused, naming `automaton`, beyond [`MAX_ENTRIES`] states or moves.
pub(in crate::montecarlo) fn automaton_aliases(att: &AttackerAutomaton) -> Result<Aliases> {
    let n = att.n_states();
    let moves: usize = (0..n)
        .map(|s| att.moves(s, false).len() + att.moves(s, true).len())
        .sum();
    if n.max(moves) > MAX_ENTRIES {
        return Err(Error::TooLarge {
            arg: "automaton".into(),
            requested: n.max(moves) as u128,
            limit: MAX_ENTRIES as u128,
        });
    }
    let mut aliases = Aliases::default();
    for s in 0..n {
        for flag in [false, true] {
            let ev = att.moves(s, flag);
            let p: Vec<f64> = ev.iter().map(|m| m.p).collect();
            // The outcomes of `outcome`.
            let values: Vec<u64> = ev
                .iter()
                .map(|m| ((m.next as u64) << 1) | u64::from(m.deliver))
                .collect();
            aliases.push(&p, &values);
        }
    }
    Ok(aliases)
}

/// `tr[τ]` = Tr h^τ(P̄) for τ = 0..=`max` or up to where the table settles (an increasing
/// sequence: once an entry is +inf, or equals its predecessor in f64, so are all later ones),
/// computed in doubling stretches so that a long horizon does not build a long table.
fn trace_table(sys: &LinearSystem, max: usize) -> Result<Vec<f64>> {
    let mut n = max.min(1024);
    loop {
        let tr = sys.h_traces(n);
        if tr.len() != n + 1 || tr.iter().any(|t| t.is_nan()) {
            return Err(Error::invalid("system", "Tr h^i(P̄) is not a number"));
        }
        let settled = (1..tr.len()).find(|&i| tr[i].is_infinite() || tr[i] == tr[i - 1]);
        if let Some(i) = settled {
            return Ok(tr[..=i].to_vec());
        }
        if n == max {
            return Ok(tr);
        }
        n = n.saturating_mul(2).min(max);
    }
}

impl Plan {
    /// Validates `cfg` (errors name the argument) and precomputes the tables.
    pub(super) fn new(sys: &LinearSystem, cfg: &AutomatonConfig) -> Result<Self> {
        if cfg.horizon == 0 {
            return Err(Error::invalid("horizon", "must be at least 1"));
        }
        if cfg.horizon > MAX_HORIZON {
            return Err(Error::TooLarge {
                arg: "horizon".into(),
                requested: cfg.horizon as u128,
                limit: MAX_HORIZON as u128,
            });
        }
        if cfg.runs == 0 {
            return Err(Error::invalid("runs", "must be at least 1"));
        }
        if cfg.record_runs && cfg.runs > MAX_RECORDED_RUNS {
            return Err(Error::TooLarge {
                arg: "runs".into(),
                requested: u128::from(cfg.runs),
                limit: u128::from(MAX_RECORDED_RUNS),
            });
        }
        let (arrive, channel) = channel_tables(cfg)?;
        let mut plan = Plan {
            horizon: cfg.horizon,
            runs: cfg.runs,
            seed: cfg.seed,
            record_runs: cfg.record_runs,
            k: cfg.channel.p.len(),
            arrive,
            channel,
            online: false,
            z0: 0,
            mu_draw: false,
            mu_thr: 0,
            fixed_memory: 0,
            pattern: Vec::new(),
            offline_high: 0,
            attacker: Aliases::default(),
            start: 0,
            tr: Vec::new(),
            state: None,
        };
        match &cfg.sensor {
            Sensor::Online { z0, mu } => {
                OnlineDesign::new(*z0, *mu)?;
                plan.online = true;
                // Zero counts never exceed the horizon: longer memories are all alike.
                plan.z0 = (*z0).min(cfg.horizon as u64 + 1);
                plan.mu_draw = *mu > 0.0 && *mu < 1.0;
                plan.mu_thr = threshold63(*mu);
                plan.fixed_memory = if *mu >= 1.0 { plan.z0 } else { plan.z0 + 1 };
                let att = cfg.attacker.clone().unwrap_or_else(Attacker::none);
                (plan.attacker, plan.start) = attacker_tables(&att)?;
            }
            Sensor::Offline { pattern } => {
                if pattern.is_empty() {
                    return Err(Error::invalid("offline", "the pattern must not be empty"));
                }
                if pattern.len() > MAX_PATTERN {
                    return Err(Error::TooLarge {
                        arg: "offline".into(),
                        requested: pattern.len() as u128,
                        limit: MAX_PATTERN as u128,
                    });
                }
                if let Some(att) = &cfg.attacker {
                    // Validated all the same, though an offline sensor ignores it.
                    attacker_tables(att)?;
                }
                plan.pattern = pattern.iter().map(|&g| u64::from(g)).collect();
                let (len, h) = (pattern.len(), cfg.horizon);
                let ones = |p: &[u64]| p.iter().sum::<u64>();
                plan.offline_high =
                    (h / len) as u64 * ones(&plan.pattern) + ones(&plan.pattern[..h % len]);
            }
        }
        plan.tr = trace_table(sys, cfg.horizon)?;
        if cfg.mode == Mode::State {
            plan.state = Some(StateModel::new(sys)?);
        }
        Ok(plan)
    }
}
