//! For `fakeack.game`: the closed-loop game Monte Carlo ([`crate::montecarlo::game`]): converts
//! the policy, runs with the GIL released, Ctrl-C and progress, returns per-run arrays.

use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use super::attacks::{attack_of, PyAttack};
use super::design;
use super::engine::{moves, Moves};
use super::model::PySystem;
use super::montecarlo::run_interruptible;
use crate::engine::AttackerAutomaton;
use crate::error::Error;
use crate::montecarlo::game::{Detector, GameConfig, MarkovChannel, Policy};
use crate::schedule::{offline_schedule, Ratio};

/// The policy named `kind`: "online" (never tested), "offline", "count" (alarm iff N <= lo or
/// N >= hi), "interval" (alarm iff Pearson's X² over `edges`/`expected` exceeds `critical`) or
/// "cusum" (the statistic of `cusum` = (inc_flag, inc_quiet, threshold), given with it and only
/// with it) or "lr" (the likelihood-ratio test of `lr` = (inc_flag, inc_quiet, opening), alarm
/// iff Λ >= `critical`; given with it and only with it); a count or interval test with the
/// support check when `min_gap` > 1 (the others refuse one: the CUSUM's and the likelihood-ratio
/// test's +inf increments are their own).
#[allow(clippy::too_many_arguments)]
fn policy_of(
    kind: &str,
    lo: i64,
    hi: i64,
    edges: Vec<u64>,
    expected: Vec<f64>,
    critical: f64,
    harmful_at_most: Option<i64>,
    fallback: u64,
    min_gap: i64,
    cusum: Option<(Vec<f64>, Vec<f64>, f64)>,
    lr: Option<(Vec<f64>, Vec<f64>, Vec<f64>)>,
) -> PyResult<Policy> {
    // A negative value as a ValueError naming the argument, not pyo3's OverflowError.
    let min_gap = u64::try_from(min_gap)
        .map_err(|_| Error::invalid("min_gap", format!("must be non-negative, got {min_gap}")))?;
    if min_gap > 1 && matches!(kind, "online" | "offline") {
        return Err(Error::invalid(
            "min_gap",
            format!("the policy {kind:?} tests nothing, so it takes no support check"),
        )
        .into());
    }
    if kind == "cusum" {
        let Some((inc_flag, inc_quiet, threshold)) = cusum else {
            return Err(Error::invalid("cusum", "the policy \"cusum\" needs its statistic").into());
        };
        if min_gap > 1 {
            return Err(Error::invalid(
                "min_gap",
                "the CUSUM checks the support by its +inf increments",
            )
            .into());
        }
        return Ok(Policy::Cusum {
            inc_flag,
            inc_quiet,
            threshold,
            fallback,
        });
    }
    if cusum.is_some() {
        return Err(Error::invalid("cusum", format!("given with the policy {kind:?}")).into());
    }
    if (kind == "lr") != lr.is_some() {
        let why = if lr.is_some() {
            format!("given with the policy {kind:?}")
        } else {
            "the policy \"lr\" needs its statistic".to_string()
        };
        return Err(Error::invalid("lr", why).into());
    }
    if kind == "lr" && min_gap > 1 {
        return Err(Error::invalid(
            "min_gap",
            "the likelihood-ratio test checks the support by its +inf increments",
        )
        .into());
    }
    let detector = match kind {
        "online" => return Ok(Policy::Online),
        "offline" => return Ok(Policy::Offline),
        "count" => Detector::Count { lo, hi },
        "interval" => Detector::Interval {
            edges,
            expected,
            critical,
        },
        "lr" => {
            let (inc_flag, inc_quiet, opening) = lr.unwrap_or_default();
            Detector::Likelihood {
                inc_flag,
                inc_quiet,
                opening,
                critical,
            }
        }
        _ => {
            return Err(PyValueError::new_err(format!(
                "policy: unknown kind {kind:?}"
            )))
        }
    };
    Ok(Policy::Test {
        detector,
        harmful_at_most,
        fallback,
        min_gap,
    })
}

/// The channel of `channel_p`, `channel_low` and `channel_high` (all or none).
fn channel_of(
    p: Option<Vec<Vec<f64>>>,
    low: Option<Vec<f64>>,
    high: Option<Vec<f64>>,
) -> PyResult<Option<MarkovChannel>> {
    match (p, low, high) {
        (None, None, None) => Ok(None),
        (Some(p), Some(low), Some(high)) => Ok(Some(MarkovChannel { p, low, high })),
        (p, low, _) => {
            let missing = if p.is_none() {
                "channel_p"
            } else if low.is_none() {
                "channel_low"
            } else {
                "channel_high"
            };
            Err(PyValueError::new_err(format!(
                "{missing}: channel_p, channel_low and channel_high are given together or not at all"
            )))
        }
    }
}

/// `e` naming the Python argument: the channel's fields and, when given, the offline pattern.
fn rename(e: Error, pattern_given: bool) -> Error {
    let name = |arg: &str| -> Option<&'static str> {
        match arg {
            "P" => Some("channel_p"),
            "low" => Some("channel_low"),
            "high" => Some("channel_high"),
            "offline" if pattern_given => Some("offline_pattern"),
            _ => None,
        }
    };
    match e {
        Error::InvalidArgument { arg, reason } => match name(&arg) {
            Some(n) => Error::invalid(n, reason),
            None => Error::InvalidArgument { arg, reason },
        },
        Error::TooLarge {
            arg,
            requested,
            limit,
        } => Error::TooLarge {
            arg: name(&arg).map_or(arg, String::from),
            requested,
            limit,
        },
        other => other,
    }
}

/// Closed-loop Monte Carlo of the game, with the GIL released, Ctrl-C and `progress(done_runs)`.
/// `channel_p`, `channel_low`, `channel_high`: a Markov channel (all three, or none for the
/// i.i.d. channel of `lam`; `lam` is then ignored). `offline_pattern`: the offline schedule's
/// period (first symbol = the first step of an offline stretch) instead of the pattern of p/q.
/// `min_gap`: the support check of a testing policy (0 or 1: none), an alarm at any gap between
/// flag-ACKs that reach the sensor shorter than it. `automaton`: an attacker automaton
/// `(flag, quiet, start)` (each state's moves (probability, deliver, next state)) instead of
/// `attack`, run on the lane kernel. `cusum`: the statistic `(inc_flag, inc_quiet, threshold)`
/// of the policy "cusum" (whose fall-back is `fallback` windows), run on the lane kernel. `lr`:
/// the likelihood-ratio test's `(inc_flag, inc_quiet, opening)` (policy "lr", with `critical`),
/// run on the lane kernel.
#[pyfunction]
#[pyo3(signature = (system, lam, p, q, z0, mu, attack, kind, lo, hi, edges, expected, critical, harmful_at_most, fallback, window, horizon, burn_in, runs, seed, progress, channel_p=None, channel_low=None, channel_high=None, offline_pattern=None, min_gap=0, automaton=None, cusum=None, lr=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn simulate_game<'py>(
    py: Python<'py>,
    system: &Bound<'py, PySystem>,
    lam: f64,
    p: u64,
    q: u64,
    z0: u64,
    mu: f64,
    attack: Option<&Bound<'py, PyAttack>>,
    kind: &str,
    lo: i64,
    hi: i64,
    edges: Vec<u64>,
    expected: Vec<f64>,
    critical: f64,
    harmful_at_most: Option<i64>,
    fallback: u64,
    window: u64,
    horizon: u64,
    burn_in: u64,
    runs: u64,
    seed: u64,
    progress: Bound<'py, PyAny>,
    channel_p: Option<Vec<Vec<f64>>>,
    channel_low: Option<Vec<f64>>,
    channel_high: Option<Vec<f64>>,
    offline_pattern: Option<Vec<bool>>,
    min_gap: i64,
    automaton: Option<(Moves, Moves, usize)>,
    cusum: Option<(Vec<f64>, Vec<f64>, f64)>,
    lr: Option<(Vec<f64>, Vec<f64>, Vec<f64>)>,
) -> PyResult<Bound<'py, PyDict>> {
    if attack.is_some() && automaton.is_some() {
        return Err(PyValueError::new_err(
            "automaton: give either attack or automaton, not both",
        ));
    }
    let automaton = automaton
        .map(|(flag, quiet, start)| AttackerAutomaton::new(moves(flag), moves(quiet), start))
        .transpose()?;
    let ratio = Ratio::new(p, q)?;
    let given = offline_pattern.is_some();
    let offline = match offline_pattern {
        Some(pattern) => pattern.into_iter().map(u8::from).collect(),
        None => offline_schedule(ratio)?,
    };
    let cfg = GameConfig {
        lam,
        channel: channel_of(channel_p, channel_low, channel_high)?,
        design: design(z0, mu)?,
        offline,
        attack: attack_of(attack),
        automaton,
        policy: policy_of(
            kind,
            lo,
            hi,
            edges,
            expected,
            critical,
            harmful_at_most,
            fallback,
            min_gap,
            cusum,
            lr,
        )?,
        window,
        horizon,
        burn_in,
        runs,
        seed,
    };
    // Checked here, before the run, so that the errors name this function's arguments.
    cfg.validate().map_err(|e| rename(e, given))?;
    let sys = &system.get().inner;
    let (cancel, done) = (AtomicBool::new(false), AtomicU64::new(0));
    let report = || progress.call1((done.load(Ordering::Relaxed),)).map(|_| ());
    let res = run_interruptible(py, &cancel, report, || {
        sys.simulate_game_with(&cfg, &cancel, &done)
    })?;
    let out = PyDict::new(py);
    out.set_item("cost", res.cost.into_pyarray(py))?;
    out.set_item("high_power", res.high_power.into_pyarray(py))?;
    out.set_item("online", res.online.into_pyarray(py))?;
    out.set_item("tested", res.tested.into_pyarray(py))?;
    out.set_item("alarms", res.alarms.into_pyarray(py))?;
    out.set_item("fallbacks", res.fallbacks.into_pyarray(py))?;
    out.set_item("delivered", res.delivered.into_pyarray(py))?;
    out.set_item("online_steps", res.online_steps.into_pyarray(py))?;
    Ok(out)
}
