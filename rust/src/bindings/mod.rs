//! The PyO3 module `fakeack._fakeack`: converts types, calls the crate's API ([`crate::analysis`]
//! and the types the crate root re-exports) and maps [`Error`] to Python exceptions. No
//! numerics here; long calls run with the GIL released on owned data.
//!
//! One file per Python subpackage that calls it: `model` (the system class and its costs, the
//! schedules), `attacks` (the attack class, chains and stationary laws), `detection` (flag-ACK
//! rates), `engine` (the general exact engine), `montecarlo` (the Monte Carlo), `game` (the
//! closed-loop game) and `studies` (parameter grids). All of them register in the one module
//! `fakeack._fakeack` below.

use nalgebra::DMatrix;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;

use crate::error::Error;
use crate::OnlineDesign;

mod attacks;
mod automaton;
mod channels;
mod detection;
mod engine;
mod game;
mod model;
mod montecarlo;
mod studies;

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

pub(crate) fn to_dmatrix(x: &PyReadonlyArray2<'_, f64>) -> DMatrix<f64> {
    let v = x.as_array();
    DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[[i, j]])
}

pub(crate) fn to_numpy<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]).into_pyarray(py)
}

pub(crate) fn design(z0: u64, mu: f64) -> PyResult<OnlineDesign> {
    Ok(OnlineDesign::new(z0, mu)?)
}

/// Raises the exception that the [`Error`] variant named `kind` maps to, so that the mapping of
/// every variant is tested from Python ("invalid", "too_large", "not_converged", "interrupted").
#[pyfunction]
fn raise_core_error(kind: &str) -> PyResult<()> {
    let e = match kind {
        "invalid" => Error::invalid("arg", "is wrong"),
        "too_large" => Error::TooLarge {
            arg: "arg".into(),
            requested: 2,
            limit: 1,
        },
        "not_converged" => Error::NotConverged {
            what: "a solver",
            iterations: 3,
            residual: 0.5,
        },
        "interrupted" => Error::Interrupted,
        _ => {
            return Err(PyValueError::new_err(format!(
                "kind: unknown error kind {kind:?}"
            )))
        }
    };
    Err(e.into())
}

#[pymodule]
#[pyo3(name = "_fakeack")]
fn fakeack_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // The package version has one source, Cargo.toml; `fakeack.__version__` reads it from here.
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<model::PySystem>()?;
    m.add_class::<attacks::PyAttack>()?;
    m.add_class::<engine::PyEngine>()?;
    m.add_function(wrap_pyfunction!(channels::markov_beta_sweep, m)?)?;
    m.add_function(wrap_pyfunction!(channels::markov_mask_j, m)?)?;
    m.add_function(wrap_pyfunction!(channels::markov_worst_mask, m)?)?;
    m.add("ConvergenceError", m.py().get_type::<ConvergenceError>())?;
    m.add_function(wrap_pyfunction!(model::offline_schedule, m)?)?;
    m.add_function(wrap_pyfunction!(model::high_power_rate, m)?)?;
    m.add_function(wrap_pyfunction!(detection::flag_rates, m)?)?;
    m.add_function(wrap_pyfunction!(attacks::num_states, m)?)?;
    m.add_function(wrap_pyfunction!(attacks::attack_chain, m)?)?;
    m.add_function(wrap_pyfunction!(attacks::stationary_structured, m)?)?;
    m.add_function(wrap_pyfunction!(attacks::general_attack_chain, m)?)?;
    m.add_function(wrap_pyfunction!(montecarlo::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(automaton::simulate_automaton, m)?)?;
    m.add_function(wrap_pyfunction!(raise_core_error, m)?)?;
    m.add_function(wrap_pyfunction!(studies::grid_cells, m)?)?;
    m.add_function(wrap_pyfunction!(studies::grid_designs, m)?)?;
    m.add_function(wrap_pyfunction!(game::simulate_game, m)?)?;
    m.add_function(wrap_pyfunction!(attacks::stationary_gth, m)?)?;
    m.add_function(wrap_pyfunction!(attacks::balance_residual, m)?)?;
    m.add("MAX_BUILD_STATES", crate::chain::MAX_BUILD_STATES as u64)?;
    m.add(
        "MAX_VECTOR_STATES",
        crate::chain::stationary::MAX_VECTOR_STATES as u64,
    )?;
    m.add("DEFAULT_TOL", crate::system::DEFAULT_TOL)?;
    m.add("DEFAULT_MAX_ITER", crate::system::DEFAULT_MAX_ITER)?;
    Ok(())
}
