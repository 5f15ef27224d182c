//! For `fakeack.game`: the closed-loop game Monte Carlo ([`crate::montecarlo::game`]): converts
//! the policy, runs with the GIL released, Ctrl-C and progress, returns per-run arrays.

use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use super::attacks::{attack_of, PyAttack};
use super::design;
use super::model::PySystem;
use super::montecarlo::run_interruptible;
use crate::montecarlo::game::{Detector, GameConfig, Policy};
use crate::schedule::{offline_schedule, Ratio};

/// The policy named `kind`: "online" (never tested), "offline", "count" (alarm iff N <= lo or
/// N >= hi) or "interval" (alarm iff Pearson's X² over `edges`/`expected` exceeds `critical`).
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
) -> PyResult<Policy> {
    let detector = match kind {
        "online" => return Ok(Policy::Online),
        "offline" => return Ok(Policy::Offline),
        "count" => Detector::Count { lo, hi },
        "interval" => Detector::Interval {
            edges,
            expected,
            critical,
        },
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
    })
}

/// Closed-loop Monte Carlo of the game, with the GIL released, Ctrl-C and `progress(done_runs)`.
#[pyfunction]
#[pyo3(signature = (system, lam, p, q, z0, mu, attack, kind, lo, hi, edges, expected, critical, harmful_at_most, fallback, window, horizon, burn_in, runs, seed, progress))]
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
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = GameConfig {
        lam,
        design: design(z0, mu)?,
        offline: offline_schedule(Ratio::new(p, q)?)?,
        attack: attack_of(attack),
        policy: policy_of(
            kind,
            lo,
            hi,
            edges,
            expected,
            critical,
            harmful_at_most,
            fallback,
        )?,
        window,
        horizon,
        burn_in,
        runs,
        seed,
    };
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
    Ok(out)
}
