//! For `fakeack.attacks` (and the chains of `fakeack.attack`): the attack class, the explicit
//! chains and their stationary laws.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use super::design;
use crate::chain::{general, stationary, AttackChain, Csr};
use crate::Attack;

/// An attack on the flag-ACKs (wrapped by `fakeack.PeriodicBlocking` and friends).
#[pyclass(frozen, name = "Attack", module = "fakeack._fakeack")]
pub(crate) struct PyAttack {
    pub(crate) inner: Attack,
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

    #[staticmethod]
    fn random(beta: f64) -> PyResult<Self> {
        Ok(PyAttack {
            inner: Attack::random(beta)?,
        })
    }

    #[staticmethod]
    #[pyo3(signature = (gamma, block))]
    fn injection(gamma: f64, block: Option<&Bound<'_, PyAttack>>) -> PyResult<Self> {
        Ok(PyAttack {
            inner: Attack::injection(gamma, attack_of(block))?,
        })
    }

    fn __str__(&self) -> String {
        self.inner.to_string()
    }
}

pub(crate) fn attack_of(a: Option<&Bound<'_, PyAttack>>) -> Option<Attack> {
    a.map(|a| a.get().inner.clone())
}

#[pyfunction]
pub(crate) fn num_states(z0: u64, r: u64, t: u64) -> u128 {
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
pub(crate) fn attack_chain<'py>(
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
pub(crate) fn general_attack_chain<'py>(
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
pub(crate) fn stationary_structured<'py>(
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
pub(crate) fn stationary_gth<'py>(
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
pub(crate) fn balance_residual(
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
