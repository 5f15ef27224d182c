//! For `fakeack.montecarlo`: the automaton Monte Carlo ([`crate::montecarlo::automaton`]), its
//! arguments, the GIL-free run with Ctrl-C and progress, and its results in the dict shape of
//! `simulate`.

use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use super::model::PySystem;
use super::montecarlo::run_interruptible;
use crate::montecarlo::automaton::{
    self, Attacker, AutomatonConfig, MarkovChannel, Sensor, Transition,
};
use crate::{McResult, Mode};

/// One event's transitions as Python gives them: (probability, deliver, next_state).
type Events = Vec<Vec<(f64, bool, usize)>>;

fn transitions(events: Events) -> Vec<Vec<Transition>> {
    events
        .into_iter()
        .map(|ev| {
            ev.into_iter()
                .map(|(p, deliver, next)| Transition { p, deliver, next })
                .collect()
        })
        .collect()
}

fn result_dict<'py>(py: Python<'py>, res: McResult) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("mean_trace", res.mean_trace.into_pyarray(py))?;
    out.set_item("j_k", res.j_k.into_pyarray(py))?;
    out.set_item("j", res.j)?;
    out.set_item("stderr", res.stderr)?;
    out.set_item("high_power_rate", res.high_power_rate)?;
    out.set_item("flags_sent", res.flags_sent)?;
    out.set_item("flags_blocked", res.flags_blocked)?;
    out.set_item("flags_forged", res.flags_forged)?;
    out.set_item("steps", res.steps)?;
    out.set_item("delivered_per_run", res.delivered_per_run.into_pyarray(py))?;
    Ok(out)
}

/// The mode by name ("covariance" or "state").
fn parse_mode(mode: &str) -> PyResult<Mode> {
    match mode {
        "covariance" => Ok(Mode::Covariance),
        "state" => Ok(Mode::State),
        _ => Err(pyo3::exceptions::PyValueError::new_err(format!(
            "mode must be 'covariance' or 'state', got {mode:?}"
        ))),
    }
}

/// Monte Carlo of the protocol on a Markov channel under an attacker automaton, in covariance or
/// state mode, with the GIL released, Ctrl-C and `progress(done_runs)`.
#[pyfunction]
#[pyo3(signature = (system, P, low, high, z0, mu, offline, flag, quiet, start, horizon, runs, seed, progress, record_runs=false, mode="covariance"))]
#[allow(clippy::too_many_arguments, non_snake_case)]
pub(crate) fn simulate_automaton<'py>(
    py: Python<'py>,
    system: &Bound<'py, PySystem>,
    P: Vec<Vec<f64>>,
    low: Vec<f64>,
    high: Vec<f64>,
    z0: u64,
    mu: f64,
    offline: Option<Vec<bool>>,
    flag: Events,
    quiet: Events,
    start: usize,
    horizon: usize,
    runs: u64,
    seed: u64,
    progress: Bound<'py, PyAny>,
    record_runs: bool,
    mode: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let mode = parse_mode(mode)?;
    let cfg = AutomatonConfig {
        channel: MarkovChannel { p: P, low, high },
        sensor: match offline {
            Some(pattern) => Sensor::Offline { pattern },
            None => Sensor::Online { z0, mu },
        },
        attacker: Some(Attacker {
            flag: transitions(flag),
            quiet: transitions(quiet),
            start,
        }),
        mode,
        horizon,
        runs,
        seed,
        record_runs,
    };
    let sys = &system.get().inner;
    let (cancel, done) = (AtomicBool::new(false), AtomicU64::new(0));
    let report = || progress.call1((done.load(Ordering::Relaxed),)).map(|_| ());
    let res = run_interruptible(py, &cancel, report, || {
        automaton::simulate(sys, &cfg, &cancel, &done)
    })?;
    result_dict(py, res)
}
