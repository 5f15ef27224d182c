//! The PyO3 module `fakeack._fakeack`: converts types, calls the crate's facade
//! ([`crate::analysis`] and the types it re-exports) and maps [`Error`] to Python exceptions.
//! No numerics here; long calls run with the GIL released on owned data.

use nalgebra::DMatrix;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::Duration;

use crate::chain::{AttackChain, Csr};
use crate::error::Error;
use crate::{
    analysis, general, riccati, stationary, Attack, LinearSystem, McConfig, McResult, Mode,
    OnlineDesign, Protocol, Ratio, Schedule,
};

create_exception!(
    _fakeack,
    ConvergenceError,
    PyValueError,
    "An iterative solver stopped without meeting its tolerance."
);

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::InvalidArgument { .. } | Error::TooLarge { .. } => {
                PyValueError::new_err(e.to_string())
            }
            Error::NotConverged { .. } => ConvergenceError::new_err(e.to_string()),
            Error::Interrupted => PyKeyboardInterrupt::new_err(e.to_string()),
        }
    }
}

fn to_dmatrix(x: &PyReadonlyArray2<'_, f64>) -> DMatrix<f64> {
    let v = x.as_array();
    DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[[i, j]])
}

fn to_numpy<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]).into_pyarray(py)
}

fn design(z0: u64, mu: f64) -> PyResult<OnlineDesign> {
    Ok(OnlineDesign::new(z0, mu)?)
}

/// An attack on the flag-ACKs (wrapped by `fakeack.PeriodicBlocking` and friends).
#[pyclass(frozen, name = "Attack", module = "fakeack._fakeack")]
struct PyAttack {
    inner: Attack,
}

#[pymethods]
impl PyAttack {
    #[staticmethod]
    fn periodic(r: u64, t: u64) -> PyResult<Self> {
        Ok(PyAttack {
            inner: Attack::periodic(r, t)?,
        })
    }

    #[staticmethod]
    fn mask(mask: Vec<bool>) -> PyResult<Self> {
        Ok(PyAttack {
            inner: Attack::mask(mask)?,
        })
    }

    fn __str__(&self) -> String {
        self.inner.to_string()
    }
}

fn attack_of(a: Option<&Bound<'_, PyAttack>>) -> Option<Attack> {
    a.map(|a| a.get().inner.clone())
}

/// A validated system with its steady-state covariance P̄ (wrapped by `fakeack.LinearSystem`).
#[pyclass(frozen, name = "System", module = "fakeack._fakeack")]
struct PySystem {
    inner: LinearSystem,
}

#[pymethods]
impl PySystem {
    #[new]
    #[pyo3(signature = (a, c, q, r, tol = riccati::DEFAULT_TOL, max_iter = riccati::DEFAULT_MAX_ITER))]
    fn new(
        py: Python<'_>,
        a: PyReadonlyArray2<'_, f64>,
        c: PyReadonlyArray2<'_, f64>,
        q: PyReadonlyArray2<'_, f64>,
        r: PyReadonlyArray2<'_, f64>,
        tol: f64,
        max_iter: usize,
    ) -> PyResult<Self> {
        let (a, c, q, r) = (
            to_dmatrix(&a),
            to_dmatrix(&c),
            to_dmatrix(&q),
            to_dmatrix(&r),
        );
        let inner = py.detach(|| LinearSystem::with_tolerance(a, c, q, r, tol, max_iter))?;
        Ok(PySystem { inner })
    }

    fn pbar<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        to_numpy(py, self.inner.pbar())
    }

    #[getter]
    fn residual(&self) -> f64 {
        self.inner.residual()
    }

    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations()
    }

    #[getter]
    fn spectral_radius(&self) -> f64 {
        self.inner.rho()
    }

    fn weighted_traces<'py>(
        &self,
        py: Python<'py>,
        weight: f64,
        n: u64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let w = py.detach(|| self.inner.checked_weighted_traces(weight, n as u128, "n"))?;
        Ok(w.into_pyarray(py))
    }

    fn j_offline(&self, py: Python<'_>, lam: f64, p: u64, q: u64) -> PyResult<f64> {
        let ratio = Ratio::new(p, q)?;
        Ok(py.detach(|| self.inner.j_offline(lam, ratio))?)
    }

    fn j_online(&self, lam: f64, z0: u64, mu: f64) -> PyResult<f64> {
        Ok(self.inner.j_online(lam, design(z0, mu)?)?)
    }

    fn j_max(&self, py: Python<'_>, lam: f64) -> PyResult<f64> {
        Ok(py.detach(|| self.inner.j_max(lam))?)
    }

    fn j_attack(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        mu: f64,
        attack: &Bound<'_, PyAttack>,
    ) -> PyResult<f64> {
        let (d, attack) = (design(z0, mu)?, &attack.get().inner);
        Ok(py.detach(|| self.inner.j_attack(lam, d, attack))?)
    }

    fn j_attack_limit(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        mu: f64,
        beta: f64,
    ) -> PyResult<f64> {
        let d = design(z0, mu)?;
        Ok(py.detach(|| self.inner.j_attack_limit(lam, d, beta))?)
    }

    /// (r, t, beta, j) for every reduced r/t with t <= t_max, sorted by beta.
    #[allow(clippy::type_complexity)]
    fn beta_sweep<'py>(
        &self,
        py: Python<'py>,
        lam: f64,
        z0: u64,
        mu: f64,
        t_max: u64,
    ) -> PyResult<(
        Bound<'py, PyArray1<u32>>,
        Bound<'py, PyArray1<u32>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<f64>>,
    )> {
        let d = design(z0, mu)?;
        let sw = py.detach(|| self.inner.beta_sweep(lam, d, t_max))?;
        Ok((
            sw.r.into_pyarray(py),
            sw.t.into_pyarray(py),
            sw.beta.into_pyarray(py),
            sw.j.into_pyarray(py),
        ))
    }

    /// (finite (r, t) or None, limit, J_offline, J_online, J_max).
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    fn beta_bar(
        &self,
        py: Python<'_>,
        lam: f64,
        p: u64,
        q: u64,
        z0: u64,
        mu: f64,
        t_max: u64,
    ) -> PyResult<(Option<(u32, u32)>, f64, f64, f64, f64)> {
        let (ratio, d) = (Ratio::new(p, q)?, design(z0, mu)?);
        let b = py.detach(|| self.inner.beta_bar(lam, ratio, d, t_max))?;
        Ok((b.finite, b.limit, b.j_offline, b.j_online, b.j_max))
    }

    /// (keep online, beta_bar, J_online under attack, J_offline, J_online).
    #[allow(clippy::too_many_arguments)]
    fn choose_schedule(
        &self,
        py: Python<'_>,
        lam: f64,
        p: u64,
        q: u64,
        z0: u64,
        mu: f64,
        beta: f64,
    ) -> PyResult<(bool, f64, f64, f64, f64)> {
        let (ratio, d) = (Ratio::new(p, q)?, design(z0, mu)?);
        let c = py.detach(|| self.inner.choose_schedule(lam, ratio, d, beta))?;
        Ok((
            c.online,
            c.beta_bar,
            c.j_online_attacked,
            c.j_offline,
            c.j_online,
        ))
    }

    /// Exact E[Tr P_k], k = 1..horizon, under the optimal offline schedule.
    fn curve_offline<'py>(
        &self,
        py: Python<'py>,
        lam: f64,
        p: u64,
        q: u64,
        horizon: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let sched = Schedule::Offline(Ratio::new(p, q)?);
        let out = py.detach(|| self.inner.expected_trace_curve(lam, sched, None, horizon))?;
        Ok(out.into_pyarray(py))
    }

    /// Exact E[Tr P_k], k = 1..horizon, under the online schedule and an attack.
    #[pyo3(signature = (lam, z0, mu, attack, horizon))]
    fn curve_online<'py>(
        &self,
        py: Python<'py>,
        lam: f64,
        z0: u64,
        mu: f64,
        attack: Option<&Bound<'py, PyAttack>>,
        horizon: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (sched, attack) = (Schedule::Online(design(z0, mu)?), attack_of(attack));
        let out = py.detach(|| {
            self.inner
                .expected_trace_curve(lam, sched, attack.as_ref(), horizon)
        })?;
        Ok(out.into_pyarray(py))
    }

    /// (worst mask, its J, J of the consecutive mask).
    fn worst_mask(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        mu: f64,
        t: usize,
        blocked: usize,
    ) -> PyResult<(Vec<bool>, f64, f64)> {
        let d = design(z0, mu)?;
        let m = py.detach(|| self.inner.worst_mask(lam, d, t, blocked))?;
        Ok((m.mask, m.j, m.j_consecutive))
    }
}

#[pyfunction]
fn offline_schedule<'py>(py: Python<'py>, p: u64, q: u64) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let s = crate::schedules::offline_schedule(Ratio::new(p, q)?)?;
    Ok(s.into_iter()
        .map(i64::from)
        .collect::<Vec<_>>()
        .into_pyarray(py))
}

#[pyfunction]
fn high_power_rate(lam: f64, z0: u64, mu: f64) -> PyResult<f64> {
    Ok(design(z0, mu)?.high_power_rate(lam)?)
}

/// (flag-ACKs sent, delivered) per step.
#[pyfunction]
#[pyo3(signature = (lam, z0, mu, attack))]
fn flag_rates(
    lam: f64,
    z0: u64,
    mu: f64,
    attack: Option<&Bound<'_, PyAttack>>,
) -> PyResult<(f64, f64)> {
    let rates = analysis::flag_rates(lam, design(z0, mu)?, attack_of(attack).as_ref())?;
    Ok((rates.sent, rates.delivered))
}

#[pyfunction]
fn num_states(z0: u64, r: u64, t: u64) -> u128 {
    crate::chain::num_states(z0, r, t)
}

type CsrArrays<'py> = (
    Bound<'py, PyArray2<i64>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<f64>>,
);

/// (states (n, k) int64, indptr, indices, data) from one row of k integers per state.
fn csr_out<'py, const K: usize>(
    py: Python<'py>,
    states: impl ExactSizeIterator<Item = [u64; K]>,
    csr: Csr,
) -> PyResult<CsrArrays<'py>> {
    let n = states.len();
    let flat: Vec<i64> = states.flatten().map(|x| x as i64).collect();
    let states = Array2::from_shape_vec((n, K), flat)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py);
    let to_i64 = |v: Vec<usize>| v.into_iter().map(|x| x as i64).collect::<Vec<_>>();
    Ok((
        states,
        to_i64(csr.indptr).into_pyarray(py),
        to_i64(csr.indices).into_pyarray(py),
        csr.data.into_pyarray(py),
    ))
}

/// (states (n, 2) of [tau, sigma], indptr, indices, data) of the row-stochastic chain.
#[pyfunction]
fn attack_chain<'py>(
    py: Python<'py>,
    lam: f64,
    z0: u64,
    r: u64,
    t: u64,
) -> PyResult<CsrArrays<'py>> {
    let chain = AttackChain::new(lam, z0, r, t)?;
    let (states, csr) =
        py.detach(|| -> crate::Result<_> { Ok((chain.states()?, chain.build_csr()?)) })?;
    csr_out(py, states.into_iter().map(|(tau, s)| [tau, s]), csr)
}

/// (states (n, 3) of [tau, zeros, sigma], indptr, indices, data): the general chain.
#[pyfunction]
fn general_attack_chain<'py>(
    py: Python<'py>,
    lam: f64,
    z0: u64,
    mu: f64,
    attack: &Bound<'py, PyAttack>,
) -> PyResult<CsrArrays<'py>> {
    let (d, attack) = (design(z0, mu)?, &attack.get().inner);
    let (states, csr) = py.detach(|| general::general_attack_chain(lam, d, attack))?;
    csr_out(
        py,
        states.into_iter().map(|s| [s.tau, s.zeros, s.sigma]),
        csr,
    )
}

#[pyfunction]
fn stationary_structured<'py>(
    py: Python<'py>,
    lam: f64,
    z0: u64,
    r: u64,
    t: u64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let chain = AttackChain::new(lam, z0, r, t)?;
    Ok(py
        .detach(|| stationary::structured(&chain))?
        .into_pyarray(py))
}

fn to_usize(name: &str, v: &PyReadonlyArray1<'_, i64>) -> PyResult<Vec<usize>> {
    v.as_array()
        .iter()
        .map(|&x| {
            usize::try_from(x)
                .map_err(|_| PyValueError::new_err(format!("{name}: negative entry {x}")))
        })
        .collect()
}

#[pyfunction]
fn stationary_gth<'py>(
    py: Python<'py>,
    indptr: PyReadonlyArray1<'_, i64>,
    indices: PyReadonlyArray1<'_, i64>,
    data: PyReadonlyArray1<'_, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let indptr = to_usize("indptr", &indptr)?;
    let csr = Csr {
        n: indptr.len().saturating_sub(1),
        indptr,
        indices: to_usize("indices", &indices)?,
        data: data.as_array().iter().copied().collect(),
    };
    csr.validate()?;
    Ok(py.detach(|| stationary::gth(&csr))?.into_pyarray(py))
}

#[pyfunction]
fn balance_residual(
    lam: f64,
    z0: u64,
    r: u64,
    t: u64,
    pi: PyReadonlyArray1<'_, f64>,
) -> PyResult<f64> {
    let chain = AttackChain::new(lam, z0, r, t)?;
    let pi = pi
        .as_slice()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    if pi.len() as u128 != chain.num_states() {
        return Err(PyValueError::new_err(format!(
            "pi: expected {} entries, found {}",
            chain.num_states(),
            pi.len()
        )));
    }
    Ok(stationary::balance_residual(&chain, pi))
}

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
fn run_interruptible<T: Send>(
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
    out.set_item("steps", res.steps)?;
    out.set_item("delivered_per_run", res.delivered_per_run.into_pyarray(py))?;
    Ok(out)
}

/// Monte Carlo of the protocol, with the GIL released, Ctrl-C and `progress(done_runs)`.
#[pyfunction]
#[pyo3(signature = (system, lam, kind, p, q, z0, mu, attack, mode, protocol, horizon, runs, seed, progress, record_runs))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
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
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = McConfig {
        lam,
        schedule: schedule_of(kind, p, q, z0, mu)?.to_monte_carlo()?,
        attack: attack_of(attack)
            .map(|a| a.blocking_mask().map(|m| m.into_owned()))
            .transpose()?,
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
    let res = run_interruptible(py, &cancel, report, || {
        sys.simulate_with(&cfg, &cancel, &done)
    })?;
    result_dict(py, res)
}

#[pymodule]
#[pyo3(name = "_fakeack")]
fn fakeack_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySystem>()?;
    m.add_class::<PyAttack>()?;
    m.add("ConvergenceError", m.py().get_type::<ConvergenceError>())?;
    m.add_function(wrap_pyfunction!(offline_schedule, m)?)?;
    m.add_function(wrap_pyfunction!(high_power_rate, m)?)?;
    m.add_function(wrap_pyfunction!(flag_rates, m)?)?;
    m.add_function(wrap_pyfunction!(num_states, m)?)?;
    m.add_function(wrap_pyfunction!(attack_chain, m)?)?;
    m.add_function(wrap_pyfunction!(stationary_structured, m)?)?;
    m.add_function(wrap_pyfunction!(general_attack_chain, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(stationary_gth, m)?)?;
    m.add_function(wrap_pyfunction!(balance_residual, m)?)?;
    m.add("MAX_BUILD_STATES", crate::chain::MAX_BUILD_STATES as u64)?;
    m.add(
        "MAX_VECTOR_STATES",
        crate::stationary::MAX_VECTOR_STATES as u64,
    )?;
    m.add("DEFAULT_TOL", riccati::DEFAULT_TOL)?;
    m.add("DEFAULT_MAX_ITER", riccati::DEFAULT_MAX_ITER)?;
    Ok(())
}
