//! For `fakeack.montecarlo`: the Monte Carlo, its arguments, the GIL-free run with Ctrl-C and
//! progress, its results.

use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::Duration;

use super::attacks::{attack_of, PyAttack};
use super::design;
use super::model::PySystem;
use crate::montecarlo::{self, TwoStateChannel};
use crate::{McConfig, McResult, McSchedule, Mode, Protocol, Ratio, Schedule};

fn parse_mode(mode: &str) -> PyResult<Mode> {
    match mode {
        "covariance" => Ok(Mode::Covariance),
        "state" => Ok(Mode::State),
        _ => Err(PyValueError::new_err(format!(
            "mode: unknown mode {mode:?}"
        ))),
    }
}

fn parse_protocol(protocol: &str) -> PyResult<Protocol> {
    match protocol {
        "A" => Ok(Protocol::A),
        "B" => Ok(Protocol::B),
        _ => Err(PyValueError::new_err(format!(
            "protocol: unknown protocol {protocol:?}"
        ))),
    }
}

/// The schedule named `kind`: "offline" with the energy ratio p/q, or "online" with (z0, mu).
fn schedule_of(kind: &str, p: u64, q: u64, z0: u64, mu: f64) -> PyResult<Schedule> {
    match kind {
        "offline" => Ok(Schedule::Offline(Ratio::new(p, q)?)),
        "online" => Ok(Schedule::Online(design(z0, mu)?)),
        _ => Err(PyValueError::new_err(format!(
            "schedule: unknown kind {kind:?} (expected 'offline' or 'online')"
        ))),
    }
}

/// Runs `work` on a scoped thread while this thread, every 50 ms, retakes the GIL to check for
/// Ctrl-C and to report progress; either failing cancels the work and returns its error. The
/// last check runs after the worker has ended, so a Ctrl-C that arrives before the result is
/// complete is raised and the result dropped, never returned as if nothing had happened.
pub(crate) fn run_interruptible<T: Send>(
    py: Python<'_>,
    cancel: &AtomicBool,
    report: impl Fn() -> PyResult<()>,
    work: impl FnOnce() -> crate::Result<T> + Send,
) -> PyResult<T> {
    std::thread::scope(|scope| {
        let (tx, mut rx) = channel::<()>();
        let worker = scope.spawn(move || {
            let out = work();
            drop(tx);
            out
        });
        loop {
            let (finished, back) = py.detach(move || wait_for(rx));
            rx = back;
            let polled = py.check_signals().and_then(|_| report());
            if let Err(e) = polled {
                cancel.store(true, Ordering::Relaxed);
                let _ = worker.join();
                return Err(e);
            }
            if finished {
                return match worker.join() {
                    Ok(r) => r.map_err(Into::into),
                    Err(_) => Err(PyValueError::new_err(
                        "internal error: the simulation thread panicked",
                    )),
                };
            }
        }
    })
}

/// Waits up to 50 ms for the worker's channel to close; true once it has (the worker ended,
/// normally or by a panic). The receiver is not `Sync`: it moves into the GIL-free closure and
/// back out.
fn wait_for(rx: Receiver<()>) -> (bool, Receiver<()>) {
    let wait = rx.recv_timeout(Duration::from_millis(50));
    (!matches!(wait, Err(RecvTimeoutError::Timeout)), rx)
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

/// Monte Carlo of the protocol, with the GIL released, Ctrl-C and `progress(done_runs)`. On a
/// two-state Markov `channel` = (p, q, low_0, low_1) (`lam` is then not read) it returns `None`
/// without running when the plan is outside the one kernel that simulates such a channel.
#[pyfunction]
#[pyo3(signature = (system, lam, kind, p, q, z0, mu, attack, mode, protocol, horizon, runs, seed, progress, record_runs, channel=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn simulate<'py>(
    py: Python<'py>,
    system: &Bound<'py, PySystem>,
    lam: f64,
    kind: &str,
    p: u64,
    q: u64,
    z0: u64,
    mu: f64,
    attack: Option<&Bound<'py, PyAttack>>,
    mode: &str,
    protocol: &str,
    horizon: usize,
    runs: u64,
    seed: u64,
    progress: Bound<'py, PyAny>,
    record_runs: bool,
    channel: Option<(f64, f64, f64, f64)>,
) -> PyResult<Option<Bound<'py, PyDict>>> {
    let cfg = McConfig {
        lam,
        channel: channel.map(|(p, q, low0, low1)| TwoStateChannel {
            p,
            q,
            low: [low0, low1],
        }),
        schedule: schedule_of(kind, p, q, z0, mu)?.to_monte_carlo()?,
        attack: attack_of(attack),
        mode: parse_mode(mode)?,
        protocol: parse_protocol(protocol)?,
        horizon,
        runs,
        seed,
        record_runs,
    };
    let sys = &system.get().inner;
    let (cancel, done) = (AtomicBool::new(false), AtomicU64::new(0));
    let report = || progress.call1((done.load(Ordering::Relaxed),)).map(|_| ());
    if matches!(cfg.schedule, McSchedule::Offline { .. }) && cfg.attack.is_some() {
        return Err(PyValueError::new_err(
            "attack: an offline schedule ignores ACKs, so an attack has no effect",
        ));
    }
    let res = run_interruptible(py, &cancel, report, || {
        montecarlo::simulate_if_supported(sys, &cfg, &cancel, &done)
    })?;
    res.map(|r| result_dict(py, r)).transpose()
}
