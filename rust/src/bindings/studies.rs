//! For `fakeack.study` and `fakeack.grid` (the studies): one block of cells of
//! `fakeack.study_grid` ([`crate::grid`]), and the exact online designs of the cells.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::attacks::PyAttack;
use super::model::PySystem;
use crate::grid::{self, Cell, CellResult, Family, Study};
use crate::schedule::exact_design::{design_exact, Lam};
use crate::{LinearSystem, OnlineDesign, Ratio};

fn family_of(name: &str) -> PyResult<Family> {
    match name {
        "periodic" => Ok(Family::Periodic),
        "random" => Ok(Family::Random),
        _ => Err(PyValueError::new_err(format!(
            "family: unknown family {name:?} (expected 'periodic' or 'random')"
        ))),
    }
}

/// The cells from flat arrays; `z0 == 0` means no online design.
fn cells_of(
    system: &[u64],
    lam: &[f64],
    p: &[u64],
    q: &[u64],
    z0: &[u64],
    mu: &[f64],
) -> PyResult<Vec<Cell>> {
    let n = system.len();
    if [lam.len(), p.len(), q.len(), z0.len(), mu.len()]
        .iter()
        .any(|&l| l != n)
    {
        return Err(PyValueError::new_err(
            "cells: system, lam, p, q, z0 and mu must have the same length",
        ));
    }
    (0..n)
        .map(|i| {
            Ok(Cell {
                system: system[i] as usize,
                lam: lam[i],
                ratio: Ratio::new(p[i], q[i])?,
                design: match z0[i] {
                    0 => None,
                    z => Some(OnlineDesign::new(z, mu[i])?),
                },
            })
        })
        .collect()
}

fn column(out: &[CellResult], f: impl Fn(&CellResult) -> f64) -> Vec<f64> {
    out.iter().map(f).collect()
}

fn matrix(out: &[CellResult], width: usize, f: impl Fn(&CellResult) -> &Vec<f64>) -> Array2<f64> {
    Array2::from_shape_fn((out.len(), width), |(i, j)| f(&out[i])[j])
}

/// Every quantity of `fakeack.study_grid` for a block of cells, as a dict of arrays.
#[pyfunction]
#[pyo3(signature = (systems, system, lam, p, q, z0, mu, betas, family, t_max, attacks))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn grid_cells<'py>(
    py: Python<'py>,
    systems: Vec<Bound<'py, PySystem>>,
    system: PyReadonlyArray1<'py, u64>,
    lam: PyReadonlyArray1<'py, f64>,
    p: PyReadonlyArray1<'py, u64>,
    q: PyReadonlyArray1<'py, u64>,
    z0: PyReadonlyArray1<'py, u64>,
    mu: PyReadonlyArray1<'py, f64>,
    betas: Vec<f64>,
    family: &str,
    t_max: u64,
    attacks: Vec<Bound<'py, PyAttack>>,
) -> PyResult<Bound<'py, PyDict>> {
    let cells = cells_of(
        &system.as_array().to_vec(),
        &lam.as_array().to_vec(),
        &p.as_array().to_vec(),
        &q.as_array().to_vec(),
        &z0.as_array().to_vec(),
        &mu.as_array().to_vec(),
    )?;
    let study = Study {
        betas,
        family: family_of(family)?,
        t_max,
        attacks: attacks.iter().map(|a| a.get().inner.clone()).collect(),
    };
    let refs: Vec<&LinearSystem> = systems.iter().map(|s| &s.get().inner).collect();
    let out = py.detach(|| grid::evaluate(&refs, &cells, &study))?;
    let d = PyDict::new(py);
    d.set_item("j_offline", column(&out, |r| r.j_offline).into_pyarray(py))?;
    d.set_item("j_online", column(&out, |r| r.j_online).into_pyarray(py))?;
    d.set_item("j_max", column(&out, |r| r.j_max).into_pyarray(py))?;
    let limit = column(&out, |r| r.beta_bar_limit);
    d.set_item("beta_bar_limit", limit.into_pyarray(py))?;
    let random = column(&out, |r| r.beta_bar_random);
    d.set_item("beta_bar_random", random.into_pyarray(py))?;
    let (fr, ft): (Vec<u32>, Vec<u32>) = out
        .iter()
        .map(|r| r.beta_bar_finite.unwrap_or((0, 0)))
        .unzip();
    d.set_item("finite_r", fr.into_pyarray(py))?;
    d.set_item("finite_t", ft.into_pyarray(py))?;
    let nb = study.betas.len();
    d.set_item(
        "j_attack",
        matrix(&out, nb, |r| &r.j_attack).into_pyarray(py),
    )?;
    let na = study.attacks.len();
    d.set_item(
        "j_listed",
        matrix(&out, na, |r| &r.j_listed).into_pyarray(py),
    )?;
    let errors: Vec<String> = out
        .iter()
        .map(|r| r.error.as_ref().map(|e| e.to_string()).unwrap_or_default())
        .collect();
    d.set_item("error", errors)?;
    Ok(d)
}

/// The memories and mixes of [`grid_designs`].
type Designs<'py> = (Bound<'py, PyArray1<u64>>, Bound<'py, PyArray1<f64>>);

/// The exact online design of each (λ, p/q) ([`crate::schedule::exact_design::design_exact`]), in
/// parallel with the GIL released. λ is read as the fraction `lam_num / lam_den` (or, where
/// `lam_den` is 0, as the float's exact binary value), as the Python package reads it. Returns
/// `(z0, mu)` arrays, `z0 == 0` where the Python package's exact path must decide.
#[pyfunction]
pub(crate) fn grid_designs<'py>(
    py: Python<'py>,
    lam: PyReadonlyArray1<'py, f64>,
    lam_num: PyReadonlyArray1<'py, u64>,
    lam_den: PyReadonlyArray1<'py, u64>,
    p: PyReadonlyArray1<'py, u64>,
    q: PyReadonlyArray1<'py, u64>,
) -> PyResult<Designs<'py>> {
    let [lam_num, lam_den, p, q] = [lam_num, lam_den, p, q].map(|a| a.as_array().to_vec());
    let lam = lam.as_array().to_vec();
    if [lam_num.len(), lam_den.len(), p.len(), q.len()]
        .iter()
        .any(|&l| l != lam.len())
    {
        return Err(PyValueError::new_err(
            "cells: lam, lam_num, lam_den, p and q must have the same length",
        ));
    }
    let out: Vec<(u64, f64)> = py.detach(|| {
        use rayon::prelude::*;
        (0..lam.len())
            .into_par_iter()
            .with_min_len(64)
            .map(|i| {
                let l = Lam {
                    value: lam[i],
                    fraction: (lam_den[i] > 0).then_some((lam_num[i], lam_den[i])),
                };
                design_exact(l, p[i], q[i]).unwrap_or((0, f64::NAN))
            })
            .collect()
    });
    let (z0, mu): (Vec<u64>, Vec<f64>) = out.into_iter().unzip();
    Ok((z0.into_pyarray(py), mu.into_pyarray(py)))
}
