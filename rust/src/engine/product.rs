//! The product automaton E = channel x detector x sensor x attacker, explored breadth-first from
//! the paper's initial condition, split into K0 (the next packet is lost) and K1 (it arrives).
//!
//! A state e_k is what holds after step k's events: the channel state of step k + 1, the
//! detector's zero count (0..=z0, z0 only after the μ coin said "not yet"), the power of step
//! k + 1 (online: high iff a flag-ACK reached the sensor at step k; offline: the pattern's phase
//! of step k + 1) and the attacker's state. An offline sensor ignores ACKs, so its product has
//! no detector and no attacker.

use std::collections::HashMap;

use crate::engine::attacker::{detector, AttackerAutomaton};
use crate::engine::channel::Channel;
use crate::error::{Error, Result};
use crate::schedule::OnlineDesign;

/// A sparse matrix in CSR form (row `i` is `indptr[i]..indptr[i + 1]`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SparseRows {
    /// Row pointers, one more than the rows.
    pub indptr: Vec<usize>,
    /// Column of each entry.
    pub indices: Vec<u32>,
    /// Value of each entry.
    pub data: Vec<f64>,
}

impl SparseRows {
    /// Number of rows.
    pub fn n(&self) -> usize {
        self.indptr.len() - 1
    }

    /// The entries of row `i` as (column, value).
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.indptr[i]..self.indptr[i + 1];
        self.indices[r.clone()]
            .iter()
            .zip(&self.data[r])
            .map(|(&j, &v)| (j as usize, v))
    }

    /// `x M` for a row vector x.
    pub fn left_mul(&self, x: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|o| *o = 0.0);
        for (i, &xi) in x.iter().enumerate() {
            if xi != 0.0 {
                for (j, v) in self.row(i) {
                    out[j] += xi * v;
                }
            }
        }
    }

    /// `M x` for a column vector x.
    pub fn right_mul(&self, x: &[f64], out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.row(i).map(|(j, v)| v * x[j]).sum();
        }
    }

    /// As (rows, cols, vals).
    pub fn coo(&self) -> (Vec<i64>, Vec<i64>, Vec<f64>) {
        let mut rows = Vec::with_capacity(self.data.len());
        for i in 0..self.n() {
            rows.extend(std::iter::repeat_n(
                i as i64,
                self.indptr[i + 1] - self.indptr[i],
            ));
        }
        let cols = self.indices.iter().map(|&j| i64::from(j)).collect();
        (rows, cols, self.data.clone())
    }
}

/// How the sensor chooses its power.
#[derive(Debug, Clone, PartialEq)]
pub enum PowerSchedule {
    /// The online (ACK-based) schedule: high power after a delivered flag-ACK.
    Online(OnlineDesign),
    /// An offline pattern, repeated: `true` is high power; the first entry is step 1.
    Offline(Vec<bool>),
}

/// What one state of the product is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StateParts {
    /// Channel state of the next step.
    pub channel: usize,
    /// Detector zero count (0 offline).
    pub zeros: usize,
    /// Online: 1 if the next step uses high power; offline: the next step's phase.
    pub power: usize,
    /// Attacker state (0 offline).
    pub attacker: usize,
}

/// What each state of an explored product is and does at the next step.
#[derive(Debug, Clone)]
pub struct Explored {
    /// Each state's parts, in breadth-first order (the initial states first).
    pub states: Vec<StateParts>,
    /// Per state: 1 if the next step uses high power.
    pub high_next: Vec<bool>,
    /// Per state: probability that the next step sends a genuine flag-ACK.
    pub sent: Vec<f64>,
    /// Per state: probability that a flag-ACK reaches the sensor at the next step.
    pub delivered: Vec<f64>,
    /// Per state: probability that a forged flag-ACK reaches the sensor at the next step.
    pub forged: Vec<f64>,
    /// Whether the schedule is online.
    pub online: bool,
}

/// Where a product's states come from.
#[derive(Debug, Clone)]
pub enum Origin {
    /// Explored from a channel, a schedule and an attacker: what each state is and does.
    Explored(Explored),
    /// Given as K0 and K1 ([`crate::engine::Engine::from_automaton`]), with a label per state
    /// if any (else its index): the states carry no power or flag-ACK information.
    Given(Option<Vec<String>>),
}

/// The product automaton: its initial law and K = K0 + K1.
#[derive(Debug, Clone)]
pub struct Product {
    /// Law of the state e_0 at k = 0 (before step 1).
    pub init: Vec<f64>,
    /// Transitions whose packet is lost.
    pub k0: SparseRows,
    /// Transitions whose packet arrives.
    pub k1: SparseRows,
    /// What the states are.
    pub origin: Origin,
}

/// An upper bound on the product's states: K (z0 + 1) 2 |attacker| online, K |pattern| offline.
pub fn size_bound(k: usize, schedule: &PowerSchedule, attacker_states: usize) -> u128 {
    match schedule {
        PowerSchedule::Online(d) => {
            k as u128 * (u128::from(d.z0) + 1) * 2 * attacker_states as u128
        }
        PowerSchedule::Offline(p) => k as u128 * p.len() as u128,
    }
}

/// Dense index table (u32 entries) the exploration always may allocate; it may grow to 4
/// `max_states`, at most 2^26 (256 MiB); past that, a hash map.
const DENSE_TABLE: u128 = 1 << 25;

/// Explores the product from the paper's initial condition, refusing (naming `max_states`) as
/// soon as more than `max_states` states are reachable.
pub fn explore(
    channel: &Channel,
    schedule: &PowerSchedule,
    attacker: &AttackerAutomaton,
    max_states: usize,
) -> Result<Product> {
    let k = channel.n_states();
    let (online, z0, mu, pattern) = match schedule {
        PowerSchedule::Online(d) => {
            d.validate()?;
            (true, d.z0 as usize, d.mu, &[][..])
        }
        PowerSchedule::Offline(p) => {
            if p.is_empty() {
                return Err(Error::invalid("offline", "the pattern must not be empty"));
            }
            (false, 0, 1.0, &p[..])
        }
    };
    let na = if online { attacker.n_states() } else { 1 };
    let bound = size_bound(k, schedule, na);
    let (nz, npw) = if online {
        (z0 + 1, 2)
    } else {
        (1, pattern.len())
    };
    let code = |s: &StateParts| -> u128 {
        ((s.attacker as u128 * npw as u128 + s.power as u128) * nz as u128 + s.zeros as u128)
            * k as u128
            + s.channel as u128
    };
    let dense = bound <= DENSE_TABLE.max(4 * max_states as u128).min(1 << 26);
    let mut table: Vec<u32> = if dense {
        vec![u32::MAX; bound as usize]
    } else {
        Vec::new()
    };
    let mut map: HashMap<u128, u32> = HashMap::new();
    let cap = bound.min(max_states as u128) as usize;
    let mut states: Vec<StateParts> = Vec::with_capacity(cap.min(1 << 20));
    let too_many = || Error::TooLarge {
        arg: "max_states".into(),
        requested: max_states as u128 + 1,
        limit: max_states as u128,
    };
    let mut lookup = |s: StateParts, states: &mut Vec<StateParts>| -> Result<u32> {
        let c = code(&s);
        let slot = if dense {
            &mut table[c as usize]
        } else {
            map.entry(c).or_insert(u32::MAX)
        };
        if *slot == u32::MAX {
            if states.len() >= max_states || states.len() >= u32::MAX as usize - 1 {
                return Err(too_many());
            }
            *slot = states.len() as u32;
            states.push(s);
        }
        Ok(*slot)
    };
    let mut init = Vec::new();
    for (c, &w) in channel.stationary().iter().enumerate() {
        if w > 0.0 {
            let s = StateParts {
                channel: c,
                zeros: 0,
                power: usize::from(online),
                attacker: if online { attacker.start() } else { 0 },
            };
            let i = lookup(s, &mut states)? as usize;
            if init.len() <= i {
                init.resize(i + 1, 0.0);
            }
            init[i] += w;
        }
    }
    let mut k0 = SparseRows {
        indptr: vec![0],
        ..Default::default()
    };
    let mut k1 = k0.clone();
    let (mut high_next, mut sent, mut delivered, mut forged) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut row0: Vec<(u32, f64)> = Vec::new();
    let mut row1: Vec<(u32, f64)> = Vec::new();
    let mut i = 0;
    while i < states.len() {
        let s = states[i];
        let hi = if online {
            s.power == 1
        } else {
            pattern[s.power]
        };
        let pa = if hi {
            channel.high()[s.channel]
        } else {
            channel.low()[s.channel]
        };
        let (mut fs, mut fd, mut ff) = (0.0, 0.0, 0.0);
        row0.clear();
        row1.clear();
        for (arrived, pr) in [(true, pa), (false, 1.0 - pa)] {
            if pr == 0.0 {
                continue;
            }
            let row = if arrived { &mut row1 } else { &mut row0 };
            if online {
                for (pd, flag, z1) in detector(s.zeros, arrived, z0, mu) {
                    for m in attacker.moves(s.attacker, flag) {
                        let p = pr * pd * m.p;
                        if flag {
                            fs += p;
                        }
                        if m.deliver {
                            fd += p;
                            if !flag {
                                ff += p;
                            }
                        }
                        for (c1, &pc) in channel.row(s.channel).iter().enumerate() {
                            if pc > 0.0 {
                                let t = StateParts {
                                    channel: c1,
                                    zeros: z1,
                                    power: usize::from(m.deliver),
                                    attacker: m.next,
                                };
                                row.push((lookup(t, &mut states)?, p * pc));
                            }
                        }
                    }
                }
            } else {
                for (c1, &pc) in channel.row(s.channel).iter().enumerate() {
                    if pc > 0.0 {
                        let t = StateParts {
                            channel: c1,
                            zeros: 0,
                            power: (s.power + 1) % pattern.len(),
                            attacker: 0,
                        };
                        row.push((lookup(t, &mut states)?, pr * pc));
                    }
                }
            }
        }
        push_row(&mut k0, &mut row0);
        push_row(&mut k1, &mut row1);
        high_next.push(hi);
        sent.push(fs);
        delivered.push(fd);
        forged.push(ff);
        i += 1;
    }
    init.resize(states.len(), 0.0);
    Ok(Product {
        init,
        k0,
        k1,
        origin: Origin::Explored(Explored {
            states,
            high_next,
            sent,
            delivered,
            forged,
            online,
        }),
    })
}

pub(crate) fn push_row(m: &mut SparseRows, row: &mut [(u32, f64)]) {
    row.sort_unstable_by_key(|e| e.0);
    let mut last = u32::MAX;
    for &(j, p) in row.iter() {
        if j == last {
            *m.data.last_mut().expect("an entry was pushed") += p;
        } else {
            m.indices.push(j);
            m.data.push(p);
            last = j;
        }
    }
    m.indptr.push(m.indices.len());
}

impl Product {
    /// Number of states.
    pub fn n(&self) -> usize {
        self.k0.n()
    }

    /// What each state is and does, for an explored product; an error naming the automaton
    /// for one given as K0 and K1, which carries no power or flag-ACK information.
    pub fn explored(&self) -> Result<&Explored> {
        match &self.origin {
            Origin::Explored(p) => Ok(p),
            Origin::Given(_) => Err(Error::invalid(
                "automaton",
                "an automaton given as K0 and K1 carries no power or flag-ACK information",
            )),
        }
    }

    /// A readable label per state.
    pub fn labels(&self) -> Vec<String> {
        let p = match &self.origin {
            Origin::Given(Some(labels)) => return labels.clone(),
            Origin::Given(None) => return (0..self.n()).map(|i| i.to_string()).collect(),
            Origin::Explored(p) => p,
        };
        p.states
            .iter()
            .map(|s| {
                if p.online {
                    format!(
                        "c={} z={} power={} attacker={}",
                        s.channel,
                        s.zeros,
                        if s.power == 1 { "high" } else { "low" },
                        s.attacker
                    )
                } else {
                    format!("c={} phase={}", s.channel, s.power)
                }
            })
            .collect()
    }
}
