//! The PyO3 module `fakeack._fakeack`: converts types and maps [`Error`] to Python exceptions.
//! No numerics here; long calls run with the GIL released on owned data.

use nalgebra::DMatrix;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use crate::chain::{AttackChain, Csr};
use crate::error::Error;
use crate::montecarlo::{self, McConfig, McSchedule, Mode, Protocol};
use crate::pattern::{self, Segments};
use crate::riccati::LinearSystem;
use crate::{general, schedules, stationary, sweep, transient};

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

/// A validated system with its steady-state covariance P̄ (wrapped by `fakeack.LinearSystem`).
#[pyclass(frozen, name = "System", module = "fakeack._fakeack")]
struct PySystem {
    inner: LinearSystem,
}

#[pymethods]
impl PySystem {
    #[new]
    #[pyo3(signature = (a, c, q, r, tol = crate::riccati::DEFAULT_TOL, max_iter = crate::riccati::DEFAULT_MAX_ITER))]
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
    fn rho(&self) -> f64 {
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
        let (s0, _, _) = schedules::offline_blocks(p, q)?;
        py.detach(|| {
            let w = self
                .inner
                .checked_weighted_traces(1.0 - lam, s0 as u128 + 1, "ratio")?;
            schedules::j_offline(&w, lam, p, q)
        })
        .map_err(Into::into)
    }

    fn j_online(&self, lam: f64, z0: u64, mu: f64) -> PyResult<f64> {
        let w = self
            .inner
            .checked_weighted_traces(1.0 - lam, z0 as u128 + 1, "z0")?;
        Ok(schedules::j_online(&w, lam, z0, mu)?)
    }

    fn j_max(&self, py: Python<'_>, lam: f64) -> PyResult<f64> {
        Ok(py.detach(|| schedules::j_max(&self.inner, lam))?)
    }

    fn j_attack(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        r: u64,
        t: u64,
        mu: f64,
    ) -> PyResult<f64> {
        let chain = AttackChain::new(lam, z0, r, t)?;
        py.detach(|| {
            if mu == 1.0 {
                // The structured stationary law of the (τ, σ) chain, summed per segment.
                let n = pattern::tau_needed(z0, r);
                let w = self
                    .inner
                    .checked_weighted_traces(1.0 - lam, n, "(z0, r)")?;
                stationary::j_attack(&chain, &w)
            } else {
                let seg = Segments::for_system(&self.inner, lam, z0, mu, r)?;
                Ok(seg.j_first_r(r as usize, t as usize))
            }
        })
        .map_err(Into::into)
    }

    fn j_attack_pattern(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        mu: f64,
        mask: Vec<bool>,
    ) -> PyResult<f64> {
        py.detach(|| {
            let seg = Segments::for_mask(&self.inner, lam, z0, mu, &mask)?;
            seg.j_mask(&mask)
        })
        .map_err(Into::into)
    }

    /// (flag-ACKs sent, delivered) per step under a blocking mask.
    fn flag_rates(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        mu: f64,
        mask: Vec<bool>,
    ) -> PyResult<(f64, f64)> {
        py.detach(|| {
            let seg = Segments::for_mask(&self.inner, lam, z0, mu, &mask)?;
            seg.flag_rates(&mask)
        })
        .map_err(Into::into)
    }

    fn j_attack_limit(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        mu: f64,
        beta: f64,
    ) -> PyResult<f64> {
        py.detach(|| {
            let seg = Segments::for_system(&self.inner, lam, z0, mu, 0)?;
            let jmax = schedules::j_max(&self.inner, lam)?;
            pattern::j_limit(&seg, lam, jmax, beta)
        })
        .map_err(Into::into)
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
        let sw = py.detach(|| {
            let seg = Segments::for_system(&self.inner, lam, z0, mu, t_max.saturating_sub(1))?;
            sweep::sweep(&seg, t_max)
        })?;
        Ok((
            sw.r.into_pyarray(py),
            sw.t.into_pyarray(py),
            sw.beta.into_pyarray(py),
            sw.j.into_pyarray(py),
        ))
    }

    /// (first (r, t) with J >= j_ref or None, the large-period threshold, J_max).
    #[allow(clippy::type_complexity)]
    fn beta_bar(
        &self,
        py: Python<'_>,
        lam: f64,
        z0: u64,
        mu: f64,
        t_max: u64,
        j_ref: f64,
    ) -> PyResult<(Option<(u32, u32)>, f64, f64)> {
        py.detach(|| {
            let seg = Segments::for_system(&self.inner, lam, z0, mu, t_max.saturating_sub(1))?;
            let jmax = schedules::j_max(&self.inner, lam)?;
            let first = sweep::first_crossing(&seg, t_max, j_ref)?;
            Ok::<_, Error>((
                first,
                pattern::beta_limit_threshold(&seg, lam, jmax, j_ref),
                jmax,
            ))
        })
        .map_err(Into::into)
    }

    /// Exact E[Tr P_k], k = 1..horizon, under a periodic offline pattern.
    fn curve_offline<'py>(
        &self,
        py: Python<'py>,
        lam: f64,
        pattern: Vec<u8>,
        horizon: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let out = py.detach(|| {
            crate::error::check_lam(lam)?;
            let gap = pattern.iter().filter(|&&g| g == 0).count();
            let tr = self
                .inner
                .checked_weighted_traces(1.0, gap as u128, "pattern")?;
            transient::offline(&tr, lam, &pattern, horizon)
        })?;
        Ok(out.into_pyarray(py))
    }

    /// Exact E[Tr P_k], k = 1..horizon, under the online schedule and a blocking mask.
    fn curve_online<'py>(
        &self,
        py: Python<'py>,
        lam: f64,
        z0: u64,
        mu: f64,
        mask: Vec<bool>,
        horizon: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let out = py.detach(|| {
            let (states, csr) = general::build(lam, z0, mu, &mask)?;
            let taus: Vec<u64> = states.iter().map(|s| s.0).collect();
            let top = taus.iter().copied().max().unwrap_or(0);
            let tr = self
                .inner
                .checked_weighted_traces(1.0, top as u128, "mask")?;
            transient::chain(&csr, &taus, &tr, horizon)
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
        py.detach(|| {
            let seg = Segments::for_system(&self.inner, lam, z0, mu, t.saturating_sub(1) as u64)?;
            pattern::worst_mask(&seg, t, blocked)
        })
        .map_err(Into::into)
    }
}

#[pyfunction]
fn offline_schedule<'py>(py: Python<'py>, p: u64, q: u64) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let s = schedules::offline_schedule(p, q)?;
    Ok(s.into_iter()
        .map(i64::from)
        .collect::<Vec<_>>()
        .into_pyarray(py))
}

#[pyfunction]
fn online_high_power_rate(lam: f64, z0: u64, mu: f64) -> PyResult<f64> {
    Ok(schedules::online_high_power_rate(lam, z0, mu)?)
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
    let n = states.len();
    let flat: Vec<i64> = states
        .iter()
        .flat_map(|&(tau, sigma)| [tau as i64, sigma as i64])
        .collect();
    let states = Array2::from_shape_vec((n, 2), flat)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py);
    Ok(csr_out(py, states, csr))
}

/// (states (n, 3) of [tau, zeros, sigma], indptr, indices, data): the general chain.
#[pyfunction]
fn general_chain<'py>(
    py: Python<'py>,
    lam: f64,
    z0: u64,
    mu: f64,
    mask: Vec<bool>,
) -> PyResult<CsrArrays<'py>> {
    let (states, csr) = py.detach(|| general::build(lam, z0, mu, &mask))?;
    let n = states.len();
    let flat: Vec<i64> = states
        .iter()
        .flat_map(|&(tau, z, sigma)| [tau as i64, z as i64, sigma as i64])
        .collect();
    let states = Array2::from_shape_vec((n, 3), flat)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py);
    Ok(csr_out(py, states, csr))
}

fn csr_out<'py>(py: Python<'py>, states: Bound<'py, PyArray2<i64>>, csr: Csr) -> CsrArrays<'py> {
    let to_i64 = |v: Vec<usize>| v.into_iter().map(|x| x as i64).collect::<Vec<_>>();
    (
        states,
        to_i64(csr.indptr).into_pyarray(py),
        to_i64(csr.indices).into_pyarray(py),
        csr.data.into_pyarray(py),
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

#[pyfunction]
fn stationary_gth<'py>(
    py: Python<'py>,
    indptr: PyReadonlyArray1<'_, i64>,
    indices: PyReadonlyArray1<'_, i64>,
    data: PyReadonlyArray1<'_, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let to_usize = |name: &str, v: &PyReadonlyArray1<'_, i64>| -> PyResult<Vec<usize>> {
        v.as_array()
            .iter()
            .map(|&x| {
                usize::try_from(x)
                    .map_err(|_| PyValueError::new_err(format!("{name}: negative entry {x}")))
            })
            .collect()
    };
    let indptr = to_usize("indptr", &indptr)?;
    let indices = to_usize("indices", &indices)?;
    let data: Vec<f64> = data.as_array().iter().copied().collect();
    let n = indptr.len().saturating_sub(1);
    if indptr.first() != Some(&0)
        || indptr.windows(2).any(|w| w[0] > w[1])
        || indptr.last() != Some(&indices.len())
        || indices.len() != data.len()
    {
        return Err(PyValueError::new_err("T: malformed CSR arrays"));
    }
    let csr = Csr {
        n,
        indptr,
        indices,
        data,
    };
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

/// Monte Carlo of the protocol. The kernel runs on a worker thread (rayon inside) with the GIL
/// released; this thread wakes every 50 ms to check for Ctrl-C (cancelling the kernel) and to
/// report progress to `progress(done_runs)`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    system: &Bound<'py, PySystem>,
    lam: f64,
    kind: &str,
    pattern: Vec<u8>,
    z0: u64,
    mu: f64,
    mask: Option<Vec<bool>>,
    mode: &str,
    protocol: &str,
    horizon: usize,
    runs: u64,
    seed: u64,
    progress: Bound<'py, PyAny>,
    record_runs: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let schedule = match kind {
        "offline" => McSchedule::Offline { pattern },
        "online" => McSchedule::Online { z0, mu },
        _ => {
            return Err(PyValueError::new_err(format!(
                "kind: unknown schedule {kind:?}"
            )))
        }
    };
    let mode = match mode {
        "covariance" => Mode::Covariance,
        "state" => Mode::State,
        _ => {
            return Err(PyValueError::new_err(format!(
                "mode: unknown mode {mode:?}"
            )))
        }
    };
    let protocol = match protocol {
        "A" => Protocol::A,
        "B" => Protocol::B,
        _ => {
            return Err(PyValueError::new_err(format!(
                "protocol: unknown protocol {protocol:?}"
            )))
        }
    };
    let cfg = McConfig {
        lam,
        schedule,
        attack: mask,
        mode,
        protocol,
        horizon,
        runs,
        seed,
        record_runs,
    };
    let sys = system.get().inner.clone();
    let cancel = AtomicBool::new(false);
    let done = AtomicU64::new(0);
    let res = std::thread::scope(|scope| -> PyResult<montecarlo::McResult> {
        // The worker says when it is done, so a short run returns at once; otherwise the
        // GIL is retaken every 50 ms to check signals and report progress.
        let (tx, mut rx) = std::sync::mpsc::channel::<()>();
        let worker = scope.spawn(|| {
            let r = montecarlo::simulate(&sys, &cfg, &cancel, &done);
            drop(tx);
            r
        });
        loop {
            // Disconnected: the worker ended (its sender is gone), normally or by a panic.
            // (The receiver is not Sync: it moves into the GIL-free closure and back.)
            let (finished, back) = py.detach(move || {
                let wait = rx.recv_timeout(Duration::from_millis(50));
                let timeout = matches!(wait, Err(std::sync::mpsc::RecvTimeoutError::Timeout));
                (!timeout, rx)
            });
            rx = back;
            let polled = py
                .check_signals()
                .and_then(|_| progress.call1((done.load(Ordering::Relaxed),)).map(|_| ()));
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
    })?;
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

#[pymodule]
#[pyo3(name = "_fakeack")]
fn fakeack_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySystem>()?;
    m.add("ConvergenceError", m.py().get_type::<ConvergenceError>())?;
    m.add_function(wrap_pyfunction!(offline_schedule, m)?)?;
    m.add_function(wrap_pyfunction!(online_high_power_rate, m)?)?;
    m.add_function(wrap_pyfunction!(num_states, m)?)?;
    m.add_function(wrap_pyfunction!(attack_chain, m)?)?;
    m.add_function(wrap_pyfunction!(stationary_structured, m)?)?;
    m.add_function(wrap_pyfunction!(general_chain, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(stationary_gth, m)?)?;
    m.add_function(wrap_pyfunction!(balance_residual, m)?)?;
    m.add("MAX_BUILD_STATES", crate::chain::MAX_BUILD_STATES as u64)?;
    m.add(
        "MAX_VECTOR_STATES",
        crate::stationary::MAX_VECTOR_STATES as u64,
    )?;
    Ok(())
}
