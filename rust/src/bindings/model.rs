//! For `fakeack.system` and `fakeack.schedules` (the model): `LinearSystem` (the system, P̄ and
//! every cost), the offline schedule and the online schedule's high-power rate.

use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;

use super::attacks::{attack_of, PyAttack};
use super::{design, to_dmatrix, to_numpy};
use crate::{system, LinearSystem, Ratio, Schedule};

/// A validated system with its steady-state covariance P̄ (wrapped by `fakeack.LinearSystem`).
#[pyclass(frozen, name = "LinearSystem", module = "fakeack._fakeack")]
pub(crate) struct PySystem {
    pub(crate) inner: LinearSystem,
}

#[pymethods]
impl PySystem {
    #[new]
    #[pyo3(signature = (a, c, q, r, tol = system::DEFAULT_TOL, max_iter = system::DEFAULT_MAX_ITER))]
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
        self.inner.spectral_radius()
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

    /// J under independent blocking at each beta (forging with probability gamma).
    #[allow(clippy::too_many_arguments)]
    fn j_random_sweep<'py>(
        &self,
        py: Python<'py>,
        lam: f64,
        z0: u64,
        mu: f64,
        gamma: f64,
        betas: Vec<f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let d = design(z0, mu)?;
        let j = py.detach(|| self.inner.j_random_sweep(lam, d, gamma, &betas))?;
        Ok(j.into_pyarray(py))
    }

    /// The root of J(independent blocking at beta) = J_offline.
    fn beta_bar_random(
        &self,
        py: Python<'_>,
        lam: f64,
        p: u64,
        q: u64,
        z0: u64,
        mu: f64,
    ) -> PyResult<f64> {
        let (ratio, d) = (Ratio::new(p, q)?, design(z0, mu)?);
        Ok(py.detach(|| self.inner.beta_bar_random(lam, ratio, d))?)
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
pub(crate) fn offline_schedule<'py>(
    py: Python<'py>,
    p: u64,
    q: u64,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let s = crate::schedule::offline_schedule(Ratio::new(p, q)?)?;
    Ok(s.into_iter()
        .map(i64::from)
        .collect::<Vec<_>>()
        .into_pyarray(py))
}

#[pyfunction]
pub(crate) fn high_power_rate(lam: f64, z0: u64, mu: f64) -> PyResult<f64> {
    Ok(design(z0, mu)?.high_power_rate(lam)?)
}
