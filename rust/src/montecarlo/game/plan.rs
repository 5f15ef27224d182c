//! The validated, precomputed form of a [`GameConfig`]: exact Bernoulli draws from 16-bit
//! slices, the attacker's blocking rule (or its automaton's alias tables), the trace table, the
//! interval test's bins, the support check's gap and the CUSUM's fall-back length.

use super::channel::ChannelPlan;
use super::*;
use crate::montecarlo::automaton::tables::{automaton_aliases, Aliases};

pub(super) const RULE_NONE: u8 = 0;
pub(super) const RULE_FIRST_R: u8 = 1;
pub(super) const RULE_MASK: u8 = 2;
pub(super) const RULE_RANDOM: u8 = 3;
pub(super) const RULE_AUTOMATON: u8 = 4;

/// The lane kernel's per-step detection: none, the interval test's histogram, the CUSUM, or the
/// likelihood-ratio window test's sum.
pub(super) const DET_NONE: u8 = 0;
pub(super) const DET_BINS: u8 = 1;
pub(super) const DET_CUSUM: u8 = 2;
pub(super) const DET_LR: u8 = 3;

/// A Bernoulli draw from a 16-bit slice, exact to 2^-64 (see the module docs).
#[derive(Debug, Clone, Copy)]
pub(super) struct Bern {
    pub(super) hi: u64,
    pub(super) lo: u64,
    pub(super) always: bool,
}

pub(super) const MASK48: u64 = (1 << 48) - 1;

impl Bern {
    pub(super) fn new(p: f64) -> Self {
        let t = bernoulli_threshold(p);
        Bern {
            hi: t >> 48,
            lo: t & MASK48,
            always: p >= 1.0,
        }
    }

    #[inline(always)]
    pub(super) fn draw(&self, slice: u64, rng: &mut Xoshiro256pp) -> bool {
        if slice != self.hi {
            (slice < self.hi) | self.always
        } else {
            self.always || (rng.next_u64() >> 16) < self.lo
        }
    }
}

/// The attacker's rule for genuine flags.
#[derive(Debug, Clone)]
pub(super) enum Block {
    None,
    /// Blocked iff the counter is < r; counter modulo t.
    FirstR {
        r: u64,
        t: u64,
    },
    Mask(Vec<bool>),
    Random(Bern),
    /// An attacker automaton: its moves' alias tables (distribution `2 s + flag`, outcomes
    /// `next << 1 | deliver`) and its start state. It forges too: the plan's γ is 0.
    Automaton {
        moves: Aliases,
        start: u64,
    },
}

impl Block {
    pub(super) fn of(attack: Option<&Attack>) -> Result<Block> {
        Ok(match attack.and_then(Attack::genuine_blocking) {
            None => Block::None,
            Some(Attack::Random { beta }) => Block::Random(Bern::new(*beta)),
            Some(a) => match a.as_first_r() {
                Some((r, t)) => Block::FirstR { r, t },
                None => Block::Mask(a.blocking_mask()?.into_owned()),
            },
        })
    }
}

/// Validated, precomputed form of a [`GameConfig`].
pub(super) struct Plan<'a> {
    pub(super) cfg: &'a GameConfig,
    pub(super) traces: Vec<f64>,
    pub(super) lam: Bern,
    /// The Markov channel's draws (`None`: the i.i.d. channel of λ).
    pub(super) channel: Option<ChannelPlan>,
    pub(super) mu: Bern,
    pub(super) gamma: Bern,
    pub(super) forging: bool,
    pub(super) block: Block,
    pub(super) z0: u64,
    /// Bin of each gap (gaps beyond the table read its last entry); empty without bins.
    pub(super) bin_of: Vec<u16>,
    pub(super) bins: usize,
    /// The support check's shortest allowed gap, > 1; 0 without the check.
    pub(super) min_gap: u64,
    /// The CUSUM policy's steps offline after an alarm (`fallback` * `window`); 0 for the others.
    pub(super) fall_steps: u64,
}

impl<'a> Plan<'a> {
    /// The policy is the likelihood-ratio window test.
    pub(super) fn likelihood(&self) -> bool {
        matches!(
            self.cfg.policy,
            Policy::Test {
                detector: Detector::Likelihood { .. },
                ..
            }
        )
    }

    pub(super) fn new(sys: &LinearSystem, cfg: &'a GameConfig) -> Result<Self> {
        cfg.validate()?;
        let channel = match &cfg.channel {
            Some(ch) => Some(ChannelPlan::new(ch, &cfg.stationary()?)),
            None => None,
        };
        let steps = cfg.burn_in + cfg.horizon;
        let len = (steps.min(MAX_TRACE_TABLE as u64 - 1) + 1) as usize;
        let traces = sys.h_traces(len - 1);
        let gamma = cfg.attack.as_ref().map_or(0.0, Attack::forging);
        let (bin_of, bins) = match &cfg.policy {
            Policy::Test {
                detector: Detector::Interval { edges, .. },
                ..
            } => {
                let last = *edges.last().unwrap() as usize;
                let mut table = vec![0u16; last + 1];
                let mut b = 0usize;
                for (g, slot) in table.iter_mut().enumerate().skip(1) {
                    while b + 1 < edges.len() && g as u64 >= edges[b + 1] {
                        b += 1;
                    }
                    *slot = b as u16;
                }
                (table, edges.len())
            }
            _ => (Vec::new(), 0),
        };
        let min_gap = match cfg.policy {
            Policy::Test { min_gap, .. } if min_gap > 1 => min_gap,
            _ => 0,
        };
        let fall_steps = match cfg.policy {
            // Validated not to overflow.
            Policy::Cusum { fallback, .. } => fallback * cfg.window,
            _ => 0,
        };
        Ok(Plan {
            cfg,
            traces,
            lam: Bern::new(cfg.lam),
            channel,
            mu: Bern::new(cfg.design.mu),
            gamma: Bern::new(gamma),
            forging: gamma > 0.0,
            block: match &cfg.automaton {
                Some(a) => Block::Automaton {
                    moves: automaton_aliases(a)?,
                    start: a.start() as u64,
                },
                None => Block::of(cfg.attack.as_ref())?,
            },
            z0: cfg.design.z0,
            bin_of,
            bins,
            min_gap,
            fall_steps,
        })
    }
}
