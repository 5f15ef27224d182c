//! For `fakeack.detection`: the flag-ACK rates the remote detector sends, delivers and has
//! forged under an attack.

use pyo3::prelude::*;

use super::attacks::{attack_of, PyAttack};
use super::design;
use crate::analysis;

/// (flag-ACKs sent, reaching the sensor, forged) per step.
#[pyfunction]
#[pyo3(signature = (lam, z0, mu, attack))]
pub(crate) fn flag_rates(
    lam: f64,
    z0: u64,
    mu: f64,
    attack: Option<&Bound<'_, PyAttack>>,
) -> PyResult<(f64, f64, f64)> {
    let rates = analysis::flag_rates(lam, design(z0, mu)?, attack_of(attack).as_ref())?;
    Ok((rates.sent, rates.delivered, rates.forged))
}
