//! For `fakeack.attacks` under a Markov channel: periodic and mask blocking by the renewal form
//! with the channel state as a phase (`engine::markov`), with the GIL released and Ctrl-C
//! checked.

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;

use super::engine::run;
use super::model::PySystem;
use crate::engine::markov;
use crate::engine::Channel;
use crate::OnlineDesign;

/// A channel as (P, low, high).
type ChannelParts = (Vec<Vec<f64>>, Vec<f64>, Vec<f64>);

type SweepArrays<'py> = (
    Bound<'py, PyArray1<u32>>,
    Bound<'py, PyArray1<u32>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

fn channel_of((p, low, high): ChannelParts) -> PyResult<Channel> {
    Ok(Channel::markov(p, low, high)?)
}

/// Work of a renewal set-up with runs up to `b` under a K-state channel (O(b² K³)).
fn work(b: u64, k: usize) -> u128 {
    u128::from(b).pow(2) * (k as u128).pow(3)
}

/// (r, t, beta, j) for every reduced r/t with t <= t_max under a Markov channel.
#[pyfunction]
pub(crate) fn markov_beta_sweep<'py>(
    py: Python<'py>,
    system: &Bound<'py, PySystem>,
    channel: ChannelParts,
    z0: u64,
    mu: f64,
    t_max: u64,
) -> PyResult<SweepArrays<'py>> {
    let ch = channel_of(channel)?;
    let d = OnlineDesign::new(z0, mu)?;
    let sys = &system.get().inner;
    let sw = run(py, work(t_max, ch.n_states()), |c| {
        markov::beta_sweep(sys, &ch, d, t_max, Some(c))
    })?;
    Ok((
        sw.r.into_pyarray(py),
        sw.t.into_pyarray(py),
        sw.beta.into_pyarray(py),
        sw.j.into_pyarray(py),
    ))
}

/// J of a blocking mask (true = blocked) under a Markov channel.
#[pyfunction]
pub(crate) fn markov_mask_j(
    py: Python<'_>,
    system: &Bound<'_, PySystem>,
    channel: ChannelParts,
    z0: u64,
    mu: f64,
    mask: Vec<bool>,
) -> PyResult<f64> {
    let ch = channel_of(channel)?;
    let d = OnlineDesign::new(z0, mu)?;
    let sys = &system.get().inner;
    run(py, work(mask.len() as u64, ch.n_states()), |_| {
        markov::mask_j(sys, &ch, d, &mask)
    })
}

/// (mask, J, J of the consecutive mask) of the most damaging mask under a Markov channel.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub(crate) fn markov_worst_mask(
    py: Python<'_>,
    system: &Bound<'_, PySystem>,
    channel: ChannelParts,
    z0: u64,
    mu: f64,
    t: usize,
    blocked: usize,
) -> PyResult<(Vec<bool>, f64, f64)> {
    let ch = channel_of(channel)?;
    let d = OnlineDesign::new(z0, mu)?;
    let sys = &system.get().inner;
    // Up to C(23, 11) masks: always on the watched thread.
    run(py, u128::MAX, |c| {
        markov::worst_mask(sys, &ch, d, t, blocked, Some(c))
    })
}
