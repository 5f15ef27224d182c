//! Parameter studies: the analysis of many (system, λ, energy ratio) cells in one call.
//!
//! A [`Cell`] is a system of a list, a λ, an energy ratio and the online design for them (from
//! [`crate::design_online`], or the exact design of the Python package); a [`Study`] adds the
//! attacker budgets β, the attack [`Family`] and t_max. [`evaluate`] returns for every cell what
//! the single calls return: [`LinearSystem::j_offline`], [`LinearSystem::j_online`],
//! [`LinearSystem::j_max`], [`LinearSystem::beta_bar`], the attacked cost at each β
//! ([`LinearSystem::j_attack_limit`] for [`Family::Periodic`], [`LinearSystem::j_attack`] with
//! [`Attack::random`] for [`Family::Random`], with [`LinearSystem::beta_bar_random`]) and
//! optionally J under listed attacks ([`LinearSystem::j_attack`], J_max for an attack that
//! blocks every flag-ACK) — bit for bit, with the first error of a cell in place of an exception.
//!
//! Speed: the weighted traces a^τ Tr h^τ(P̄) and J_max depend on (system, λ) only, so cells
//! are grouped by (system, λ) and share them; groups and cells run in parallel (rayon). Every
//! quantity is then computed by the functions the single calls use, on the same inputs (the
//! traces' recursion gives the same prefix whatever its length), so the values are identical. A
//! cell whose shared computation meets any error, or that would need more shared traces than
//! [`MAX_SHARED_TRACES`], is computed by the single calls themselves, so its values and errors
//! are theirs.
//!
//! ```
//! use fakeack::grid::{evaluate, Cell, Family, Study};
//! use fakeack::{design_online, LinearSystem, Ratio};
//!
//! let sys = LinearSystem::scalar(1.2, 0.7, 0.8, 0.8)?;
//! let ratio = Ratio::new(1, 7)?;
//! let cells: Vec<Cell> = [0.4, 0.5, 0.6]
//!     .iter()
//!     .map(|&lam| Cell { system: 0, lam, ratio, design: design_online(lam, ratio).ok() })
//!     .collect();
//! let study = Study { betas: vec![0.2, 0.5], family: Family::Periodic, t_max: 60, attacks: vec![] };
//! let out = evaluate(&[&sys], &cells, &study)?;
//! let bar = sys.beta_bar(0.5, ratio, cells[1].design.unwrap(), 60)?;
//! assert_eq!(out[1].beta_bar_limit, bar.limit);
//! assert_eq!(out[1].beta_bar_finite, bar.finite);
//! # Ok::<(), fakeack::Error>(())
//! ```

use std::collections::HashMap;

use rayon::prelude::*;

use crate::attack::Attack;
use crate::error::{Error, Result};
use crate::renewal::periodic::{self, tau_needed, Segments, MAX_SEGMENTS_MIXED};
use crate::renewal::sweep;
use crate::schedule::{self, Ratio};
use crate::schedule::{OnlineDesign, Walk};
use crate::system::LinearSystem;

/// Most weighted traces a (system, λ) group shares; a cell that needs more is computed alone.
pub const MAX_SHARED_TRACES: u128 = 1 << 22;

/// What the attacked cost at each β means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// The large-period worst case of blocking a fraction β of the flag-ACKs in runs,
    /// J_∞(β) ([`LinearSystem::j_attack_limit`]); the decision is [`LinearSystem::choose_schedule`]'s.
    Periodic,
    /// Each flag-ACK blocked independently with probability β ([`Attack::random`]).
    Random,
}

/// One cell of a study.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// Index of the cell's system in the list passed to [`evaluate`].
    pub system: usize,
    /// Low-power arrival probability λ.
    pub lam: f64,
    /// Energy ratio p/q.
    pub ratio: Ratio,
    /// The online schedule; `None` when no online schedule meets the budget at this λ (the
    /// cell's online quantities are then NaN).
    pub design: Option<OnlineDesign>,
}

/// What to compute in every cell besides the costs and thresholds.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// Attacker budgets, each in [0, 1].
    pub betas: Vec<f64>,
    /// How an attacker of budget β attacks.
    pub family: Family,
    /// Largest attack period of the finite threshold (>= 2).
    pub t_max: u64,
    /// Attacks whose stationary J each cell also reports (e.g. the ones a Monte Carlo simulates);
    /// J_max for one that blocks every flag-ACK.
    pub attacks: Vec<Attack>,
}

/// Everything computed for one cell; a quantity whose single call fails is NaN (`None` for
/// the finite threshold) and `error` holds the cell's first error.
#[derive(Debug, Clone, PartialEq)]
pub struct CellResult {
    /// [`LinearSystem::j_offline`].
    pub j_offline: f64,
    /// [`LinearSystem::j_online`] of the cell's design.
    pub j_online: f64,
    /// [`LinearSystem::j_max`] (`inf` when (1-λ) ρ(A)² >= 1).
    pub j_max: f64,
    /// [`crate::BetaBar::limit`].
    pub beta_bar_limit: f64,
    /// [`crate::BetaBar::finite`].
    pub beta_bar_finite: Option<(u32, u32)>,
    /// [`LinearSystem::beta_bar_random`] ([`Family::Random`] only; NaN otherwise).
    pub beta_bar_random: f64,
    /// The attacked cost at each β of the study.
    pub j_attack: Vec<f64>,
    /// J under each of [`Study::attacks`].
    pub j_listed: Vec<f64>,
    /// The first error met, if any.
    pub error: Option<Error>,
}

impl CellResult {
    fn empty(study: &Study) -> Self {
        CellResult {
            j_offline: f64::NAN,
            j_online: f64::NAN,
            j_max: f64::NAN,
            beta_bar_limit: f64::NAN,
            beta_bar_finite: None,
            beta_bar_random: f64::NAN,
            j_attack: vec![f64::NAN; study.betas.len()],
            j_listed: vec![f64::NAN; study.attacks.len()],
            error: None,
        }
    }
}

/// Every cell's quantities, in the order of `cells`. Errors only for a malformed study (a
/// system index out of range, t_max < 2, a β outside [0, 1]); a cell's own failures go into
/// its [`CellResult::error`].
pub fn evaluate(
    systems: &[&LinearSystem],
    cells: &[Cell],
    study: &Study,
) -> Result<Vec<CellResult>> {
    check_study(systems, cells, study)?;
    // Group the cells by (system, λ): they share the traces and J_max.
    let mut groups: HashMap<(usize, u64), Vec<usize>> = HashMap::new();
    for (i, c) in cells.iter().enumerate() {
        groups
            .entry((c.system, c.lam.to_bits()))
            .or_default()
            .push(i);
    }
    let groups: Vec<Vec<usize>> = groups.into_values().collect();
    let per_group: Vec<Vec<(usize, CellResult)>> = groups
        .par_iter()
        .map(|members| {
            let first = &cells[members[0]];
            let sys = systems[first.system];
            let shared = Shared::new(sys, first.lam, members.iter().map(|&i| &cells[i]), study);
            members
                .par_iter()
                .map(|&i| (i, evaluate_cell(sys, &cells[i], study, shared.as_ref())))
                .collect()
        })
        .collect();
    let mut out: Vec<Option<CellResult>> = vec![None; cells.len()];
    for (i, r) in per_group.into_iter().flatten() {
        out[i] = Some(r);
    }
    Ok(out.into_iter().map(|r| r.expect("every cell")).collect())
}

fn check_study(systems: &[&LinearSystem], cells: &[Cell], study: &Study) -> Result<()> {
    if study.t_max < 2 {
        return Err(Error::invalid(
            "t_max",
            format!("must be at least 2, got {}", study.t_max),
        ));
    }
    if let Some(b) = study
        .betas
        .iter()
        .find(|b| !(b.is_finite() && (0.0..=1.0).contains(*b)))
    {
        return Err(Error::invalid(
            "beta",
            format!("must lie in [0, 1], got {b}"),
        ));
    }
    if let Some(c) = cells.iter().find(|c| c.system >= systems.len()) {
        return Err(Error::invalid(
            "system",
            format!(
                "index {} out of range for {} systems",
                c.system,
                systems.len()
            ),
        ));
    }
    for a in &study.attacks {
        a.validate()?;
    }
    Ok(())
}

/// What the cells of one (system, λ) group share.
struct Shared {
    /// a^τ Tr h^τ(P̄) with a = 1 - λ, as [`LinearSystem::j_offline`] and
    /// [`LinearSystem::j_online`] compute them.
    w_cost: Vec<f64>,
    /// c^τ Tr h^τ(P̄) with the walk's c, as [`Segments::for_system`] computes them (`None`
    /// when c is bit for bit 1 - λ: then `w_cost` serves).
    w_walk: Option<Vec<f64>>,
    /// The walk's masses c^τ ([`periodic::masses`]), as [`Segments::of_walk`] computes them.
    masses: Vec<f64>,
    j_max: f64,
}

impl Shared {
    /// `None` when J_max fails (every cell then takes the single calls).
    fn new<'a>(
        sys: &LinearSystem,
        lam: f64,
        cells: impl Iterator<Item = &'a Cell>,
        study: &Study,
    ) -> Option<Self> {
        let j_max = sys.j_max(lam).ok()?;
        let walk = Walk::new(lam, OnlineDesign::fixed(1).ok()?, 0.0).ok()?;
        let c = walk.continuation();
        let same = c.to_bits() == (1.0 - lam).to_bits();
        let (mut n_cost, mut n_walk) = (0u128, 0u128);
        for cell in cells {
            if let Some(need) = shared_needs(cell, study) {
                n_cost = n_cost.max(need.cost);
                n_walk = n_walk.max(need.walk);
            }
        }
        if same {
            n_cost = n_cost.max(n_walk);
        }
        let w_cost = sys.weighted_traces(1.0 - lam, n_cost as usize);
        let w_walk = (!same).then(|| sys.weighted_traces(c, n_walk as usize));
        Some(Shared {
            w_cost,
            w_walk,
            masses: periodic::masses(&walk, n_walk as usize + 1),
            j_max,
        })
    }

    fn walk_traces(&self) -> &[f64] {
        self.w_walk.as_deref().unwrap_or(&self.w_cost)
    }
}

/// Highest τ of the shared traces a cell needs: for the costs (weight 1 - λ) and for the walk's
/// segments; `None` if the cell is computed alone.
struct Needs {
    cost: u128,
    walk: u128,
}

fn shared_needs(cell: &Cell, study: &Study) -> Option<Needs> {
    let s0 = cell.ratio.offline_blocks().s0 as u128;
    let (cost, walk) = match cell.design {
        None => (s0 + 1, 0),
        Some(d) => {
            let kmax = study.t_max - 1;
            if d.mu < 1.0 && kmax > MAX_SEGMENTS_MIXED {
                return None;
            }
            (s0.max(d.z0 as u128) + 1, tau_needed(d.z0, kmax))
        }
    };
    (cost < MAX_SHARED_TRACES && walk < MAX_SHARED_TRACES).then_some(Needs { cost, walk })
}

fn evaluate_cell(
    sys: &LinearSystem,
    cell: &Cell,
    study: &Study,
    shared: Option<&Shared>,
) -> CellResult {
    if let Some(sh) = shared {
        if shared_needs(cell, study).is_some() {
            if let Ok(r) = shared_cell(sys, cell, study, sh) {
                return r;
            }
        }
    }
    single_calls(sys, cell, study)
}

/// The cell from the group's traces and J_max, by the functions the single calls use.
fn shared_cell(sys: &LinearSystem, cell: &Cell, study: &Study, sh: &Shared) -> Result<CellResult> {
    let (lam, ratio) = (cell.lam, cell.ratio);
    let mut out = CellResult::empty(study);
    let s0 = ratio.offline_blocks().s0 as usize;
    out.j_offline = schedule::j_offline(&sh.w_cost[..s0 + 2], lam, ratio)?;
    out.j_max = sh.j_max;
    let Some(design) = cell.design else {
        return Ok(out);
    };
    let z0 = design.z0 as usize;
    out.j_online = schedule::j_online(&sh.w_cost[..z0 + 2], lam, design)?;
    // LinearSystem::beta_bar: segments 0..t_max-1 of the walk.
    let walk = Walk::new(lam, design, 0.0)?;
    let build = |k| Segments::of_walk_with_masses(sh.walk_traces(), &sh.masses, &walk, k);
    let seg = build(0)?;
    out.beta_bar_limit = periodic::beta_limit_threshold(&seg, lam, sh.j_max, out.j_offline);
    // The segments up to the crossing only (the same answer as the full sweep): the finite
    // threshold is usually a little above the limit's, so the visit starts at that depth.
    let start = (out.beta_bar_limit * study.t_max as f64).ceil() as u64; // NaN: 0
    let start = start.saturating_add(2);
    out.beta_bar_finite = sweep::first_crossing_by_depth(build, study.t_max, out.j_offline, start)?;
    // Segment 0 (all that j_attack_limit builds) is the same whatever the depth.
    match study.family {
        Family::Periodic => {
            for (j, &beta) in out.j_attack.iter_mut().zip(&study.betas) {
                *j = periodic::j_limit(&seg, lam, sh.j_max, beta)?;
            }
        }
        Family::Random => random_family(sys, cell, design, study, &mut out)?,
    }
    listed_attacks(sys, cell, design, study, &mut out)?;
    Ok(out)
}

fn random_family(
    sys: &LinearSystem,
    cell: &Cell,
    design: OnlineDesign,
    study: &Study,
    out: &mut CellResult,
) -> Result<()> {
    out.j_attack = sys.j_random_sweep(cell.lam, design, 0.0, &study.betas)?;
    out.beta_bar_random = sys.beta_bar_random(cell.lam, cell.ratio, design)?;
    Ok(())
}

fn listed_attacks(
    sys: &LinearSystem,
    cell: &Cell,
    design: OnlineDesign,
    study: &Study,
    out: &mut CellResult,
) -> Result<()> {
    for (j, attack) in out.j_listed.iter_mut().zip(&study.attacks) {
        *j = listed(sys, cell.lam, design, attack, out.j_max)?;
    }
    Ok(())
}

fn listed(
    sys: &LinearSystem,
    lam: f64,
    design: OnlineDesign,
    attack: &Attack,
    j_max: f64,
) -> Result<f64> {
    if attack.blocks_every_flag() {
        Ok(j_max)
    } else {
        sys.j_attack(lam, design, attack)
    }
}

/// The cell by the single calls, each quantity on its own: a failure leaves that quantity NaN
/// and the first one is the cell's error.
fn single_calls(sys: &LinearSystem, cell: &Cell, study: &Study) -> CellResult {
    let (lam, ratio) = (cell.lam, cell.ratio);
    let mut out = CellResult::empty(study);
    let mut first: Option<Error> = None;
    let mut keep = |r: Result<f64>| -> f64 {
        r.unwrap_or_else(|e| {
            first.get_or_insert(e);
            f64::NAN
        })
    };
    out.j_offline = keep(sys.j_offline(lam, ratio));
    out.j_max = keep(sys.j_max(lam));
    if let Some(d) = cell.design {
        out.j_online = keep(sys.j_online(lam, d));
        match sys.beta_bar(lam, ratio, d, study.t_max) {
            Ok(bar) => {
                out.beta_bar_limit = bar.limit;
                out.beta_bar_finite = bar.finite;
            }
            Err(e) => {
                keep(Err(e));
            }
        }
        for (j, &beta) in out.j_attack.iter_mut().zip(&study.betas) {
            *j = keep(match study.family {
                Family::Periodic => sys.j_attack_limit(lam, d, beta),
                Family::Random => Attack::random(beta).and_then(|a| sys.j_attack(lam, d, &a)),
            });
        }
        if study.family == Family::Random {
            out.beta_bar_random = keep(sys.beta_bar_random(lam, ratio, d));
        }
        let j_max = sys.j_max(lam);
        for (j, attack) in out.j_listed.iter_mut().zip(&study.attacks) {
            *j = keep(j_max.clone().and_then(|jm| listed(sys, lam, d, attack, jm)));
        }
    }
    out.error = first;
    out
}

#[cfg(test)]
mod tests;
