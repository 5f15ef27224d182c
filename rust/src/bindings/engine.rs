//! For `fakeack.engine` (the scenario): the general exact engine. Converts the channel, the
//! schedule and the attacker, builds the automaton and runs its solves with the GIL released and
//! Ctrl-C checked.

use std::sync::atomic::AtomicBool;

use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use super::attacks::PyAttack;
use super::model::PySystem;
use super::montecarlo::run_interruptible;
use crate::engine::{Attacker, AttackerAutomaton, Channel, Engine, Move, PowerSchedule};
use crate::{Attack, OnlineDesign};

/// One state's moves: (probability, deliver, next state).
pub(super) type Moves = Vec<Vec<(f64, bool, usize)>>;

/// The virtual system of the mimicry attacker: (P, low, high, z0, mu).
type Virtual = (Vec<Vec<f64>>, Vec<f64>, Vec<f64>, u64, f64);

/// K0 or K1 as (rows, cols, vals) arrays.
type CooIn<'py> = (
    PyReadonlyArray1<'py, i64>,
    PyReadonlyArray1<'py, i64>,
    PyReadonlyArray1<'py, f64>,
);

/// Owned copies of (rows, cols, vals), to cross into the solve without the GIL.
fn owned(m: &CooIn<'_>) -> (Vec<i64>, Vec<i64>, Vec<f64>) {
    (
        m.0.as_array().to_vec(),
        m.1.as_array().to_vec(),
        m.2.as_array().to_vec(),
    )
}

type Coo<'py> = (
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<f64>>,
);

/// The product automaton of a scenario and its solves (wrapped by `fakeack.Scenario`).
#[pyclass(frozen, name = "Engine", module = "fakeack._fakeack")]
pub(crate) struct PyEngine {
    inner: Engine,
}

pub(super) fn moves(lists: Moves) -> Vec<Vec<Move>> {
    lists
        .into_iter()
        .map(|l| {
            l.into_iter()
                .map(|(p, deliver, next)| Move { p, deliver, next })
                .collect()
        })
        .collect()
}

/// Work below this size (automaton states, times the system's dimension squared for the Stein
/// solves) takes well under a millisecond: it runs on the calling thread with the GIL released,
/// because the watcher thread that lets Ctrl-C through costs more than the work itself (about
/// 80 us a call, measured on the paper's scenario).
const SMALL: u128 = 20_000;

pub(crate) fn run<T: Send>(
    py: Python<'_>,
    size: u128,
    work: impl FnOnce(&AtomicBool) -> crate::Result<T> + Send,
) -> PyResult<T> {
    let cancel = AtomicBool::new(false);
    if size <= SMALL {
        return py.detach(|| work(&cancel)).map_err(Into::into);
    }
    let flag = &cancel;
    run_interruptible(py, &cancel, || Ok(()), move || work(flag))
}

impl PyEngine {
    /// The size of a solve on this automaton for a system of dimension `n`.
    fn work(&self, n: usize) -> u128 {
        self.inner.n_states() as u128 * (n as u128).pow(2)
    }
}

#[pymethods]
impl PyEngine {
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (P, low, high, z0, mu, offline, attack, min_gap, mimicry, automaton, max_states))]
    fn new(
        py: Python<'_>,
        #[allow(non_snake_case)] P: Vec<Vec<f64>>,
        low: Vec<f64>,
        high: Vec<f64>,
        z0: u64,
        mu: f64,
        offline: Option<Vec<bool>>,
        attack: Option<&Bound<'_, PyAttack>>,
        min_gap: u64,
        mimicry: Option<Virtual>,
        automaton: Option<(Moves, Moves, usize)>,
        max_states: usize,
    ) -> PyResult<Self> {
        let given = [attack.is_some(), mimicry.is_some(), automaton.is_some()];
        if given.iter().filter(|&&g| g).count() > 1 {
            return Err(PyValueError::new_err(
                "attack: at most one of attack, mimicry and automaton may be given",
            ));
        }
        let attack: Option<Attack> = attack.map(|a| a.get().inner.clone());
        if min_gap != 1 && !matches!(attack, Some(Attack::Injection { .. })) {
            return Err(PyValueError::new_err(format!(
                "min_gap: applies to flag injection only, got {min_gap}"
            )));
        }
        let channel = Channel::markov(P, low, high)?;
        let schedule = match offline {
            Some(p) => PowerSchedule::Offline(p),
            None => PowerSchedule::Online(OnlineDesign::new(z0, mu)?),
        };
        let attacker = match (attack, mimicry, automaton) {
            (Some(attack), _, _) => Attacker::Attack { attack, min_gap },
            (_, Some((vp, vlow, vhigh, vz0, vmu)), _) => Attacker::Mimicry {
                channel: Channel::markov(vp, vlow, vhigh).map_err(|e| match e {
                    crate::Error::InvalidArgument { arg, reason } => {
                        crate::Error::invalid(format!("mimicry: {arg}"), reason)
                    }
                    other => other,
                })?,
                design: OnlineDesign::new(vz0, vmu)?,
            },
            (_, _, Some((flag, quiet, start))) => {
                Attacker::Automaton(AttackerAutomaton::new(moves(flag), moves(quiet), start)?)
            }
            _ => Attacker::None,
        };
        let bound = crate::engine::product::size_bound(
            channel.n_states(),
            &schedule,
            usize::try_from(attacker.size_bound()).unwrap_or(usize::MAX),
        );
        let inner = run(py, bound, |_| {
            Engine::new(&channel, &schedule, &attacker, max_states)
        })?;
        Ok(PyEngine { inner })
    }

    /// An automaton given as K0 and K1 (`Engine::from_automaton`).
    #[staticmethod]
    #[pyo3(signature = (n, k0, k1, init, labels, max_states))]
    fn from_automaton(
        py: Python<'_>,
        n: usize,
        k0: CooIn<'_>,
        k1: CooIn<'_>,
        init: Option<PyReadonlyArray1<'_, f64>>,
        labels: Option<Vec<String>>,
        max_states: usize,
    ) -> PyResult<Self> {
        let (k0, k1) = (owned(&k0), owned(&k1));
        let init = init.map(|a| a.as_array().to_vec());
        let size = (k0.0.len() + k1.0.len() + n) as u128;
        let inner = run(py, size, |_| {
            Engine::from_automaton(
                n,
                (&k0.0, &k0.1, &k0.2),
                (&k1.0, &k1.1, &k1.2),
                init.as_deref(),
                labels,
                max_states,
            )
        })?;
        Ok(PyEngine { inner })
    }

    #[getter]
    fn n_states(&self) -> usize {
        self.inner.n_states()
    }

    fn cost(&self, py: Python<'_>, system: &Bound<'_, PySystem>) -> PyResult<f64> {
        let sys = &system.get().inner;
        run(py, self.work(sys.n()), |c| {
            self.inner.cost_cancellable(sys, Some(c))
        })
    }

    fn stability_index(&self, py: Python<'_>, system: &Bound<'_, PySystem>) -> PyResult<f64> {
        let sys = &system.get().inner;
        run(py, self.work(sys.n()), |c| {
            self.inner.stability_index_cancellable(sys, Some(c))
        })
    }

    fn high_power_rate(&self, py: Python<'_>) -> PyResult<f64> {
        run(py, self.work(1), |_| self.inner.high_power_rate())
    }

    fn flag_rates(&self, py: Python<'_>) -> PyResult<(f64, f64, f64)> {
        let r = run(py, self.work(1), |_| self.inner.flag_rates())?;
        Ok((r.sent, r.delivered, r.forged))
    }

    fn holding_time_law<'py>(
        &self,
        py: Python<'py>,
        n: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(run(py, self.work(1), |_| self.inner.holding_time_law(n))?.into_pyarray(py))
    }

    #[allow(clippy::type_complexity)]
    fn cost_curve<'py>(
        &self,
        py: Python<'py>,
        system: &Bound<'py, PySystem>,
        horizon: usize,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
        let sys = &system.get().inner;
        let (tr, j) = run(py, self.work(sys.n()) * horizon as u128, |c| {
            self.inner.cost_curve_cancellable(sys, horizon, Some(c))
        })?;
        Ok((tr.into_pyarray(py), j.into_pyarray(py)))
    }

    fn automaton<'py>(&self, py: Python<'py>) -> (Vec<String>, Coo<'py>, Coo<'py>) {
        let ex = py.detach(|| self.inner.automaton());
        let coo = |(r, c, v): (Vec<i64>, Vec<i64>, Vec<f64>)| {
            (r.into_pyarray(py), c.into_pyarray(py), v.into_pyarray(py))
        };
        (ex.labels, coo(ex.k0), coo(ex.k1))
    }

    fn __repr__(&self) -> String {
        format!("Engine(n_states={})", self.inner.n_states())
    }
}
