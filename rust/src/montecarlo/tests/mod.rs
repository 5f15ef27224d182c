use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use nalgebra::DMatrix;

use super::driver::{simulate_with, Kernels};
use super::kernel::{detect_isa, Isa};
use super::plan::{max_tau, Plan};
use super::*;
use crate::attack::Attack;
use crate::error::{Error, Result};
use crate::system::LinearSystem;

mod channel;
mod exact;
mod inputs;
mod kernels;
mod other_attacks;
mod per_run;
mod perf;

fn scalar_sys() -> LinearSystem {
    let m = |x: f64| DMatrix::from_element(1, 1, x);
    LinearSystem::new(m(1.2), m(0.7), m(0.8), m(0.8)).unwrap()
}

/// An online experiment, attacked by the blocking mask `mask` if given.
fn online(lam: f64, z0: u64, mu: f64, mask: Option<Vec<bool>>) -> McConfig {
    McConfig {
        channel: None,
        lam,
        schedule: McSchedule::Online { z0, mu },
        attack: mask.map(Attack::Mask),
        mode: Mode::Covariance,
        protocol: Protocol::B,
        horizon: 1000,
        runs: 100,
        seed: 1,
        record_runs: false,
    }
}

fn run(sys: &LinearSystem, cfg: &McConfig) -> Result<McResult> {
    simulate(sys, cfg, &AtomicBool::new(false), &AtomicU64::new(0))
}

/// The bit-sliced kernel (where the plan fits it) and the lane kernels, for the statistical
/// checks that each must pass on its own.
fn run_both(sys: &LinearSystem, cfg: &McConfig) -> [(&'static str, McResult); 2] {
    let go = |bitslice| {
        let kernels = Kernels {
            isa: detect_isa(),
            bitslice,
        };
        simulate_with(
            sys,
            cfg,
            &AtomicBool::new(false),
            &AtomicU64::new(0),
            kernels,
        )
        .unwrap()
    };
    [("bit-sliced", go(true)), ("lanes", go(false))]
}

fn two_state_sys() -> LinearSystem {
    // Unstable mode 1.1 seen by C; Q is singular (rank 1).
    let a = DMatrix::from_row_slice(2, 2, &[1.1, 0.3, 0.0, 0.7]);
    let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.5]);
    let q = DMatrix::from_row_slice(2, 2, &[0.5, 0.5, 0.5, 0.5]);
    let r = DMatrix::from_element(1, 1, 0.3);
    LinearSystem::new(a, c, q, r).unwrap()
}

fn three_state_sys() -> LinearSystem {
    // Two outputs, so the gain involves a 2x2 innovation covariance.
    let a = DMatrix::from_row_slice(3, 3, &[1.05, 0.2, 0.0, 0.0, 0.9, 0.3, 0.1, 0.0, 0.6]);
    let c = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.5, 0.0, 1.0, 0.0]);
    let q = DMatrix::from_row_slice(3, 3, &[0.4, 0.1, 0.0, 0.1, 0.3, 0.05, 0.0, 0.05, 0.2]);
    let r = DMatrix::from_row_slice(2, 2, &[0.5, 0.1, 0.1, 0.4]);
    LinearSystem::new(a, c, q, r).unwrap()
}

/// Statistical tests use fewer runs in unoptimised builds (`cargo test`), where the kernels
/// are ~50 times slower; their tolerances scale with the standard error, so they stay valid.
fn scaled(runs: u64) -> u64 {
    if cfg!(debug_assertions) {
        (runs / 16).max(64)
    } else {
        runs
    }
}

/// Tolerance for a fraction of steps: 5 binomial standard errors (conservative: the
/// high-power indicators are negatively correlated) plus the initial step's 1/horizon.
fn binomial_tol(p: f64, cfg: &McConfig) -> f64 {
    let n = cfg.runs as f64 * cfg.horizon as f64;
    5.0 * (p * (1.0 - p) / n).sqrt() + 1.0 / cfg.horizon as f64
}

/// |x - y| <= k·se, with a readable failure.
fn assert_close(what: &str, x: f64, y: f64, se: f64, k: f64) {
    assert!(
        se.is_finite() && se > 0.0,
        "{what}: bad standard error {se}"
    );
    assert!(
        (x - y).abs() <= k * se,
        "{what}: {x} vs {y}, {:.2} standard errors",
        (x - y).abs() / se
    );
}

/// Cases that reach the rarer kernel paths: a table too long for the in-register lookup
/// (gathered), and a mask over 64 entries.
fn edge_kernel_cases() -> Vec<McConfig> {
    let mut long = vec![false; 70];
    long[66] = true;
    long[67] = true;
    vec![
        online(0.3, 4, 0.5, Some(vec![true, true, false, false])),
        online(0.3, 2, 1.0, Some(long)),
    ]
}

/// A rayon pool of `n` threads.
fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
}

/// The AVX2 lane kernel, or `None` after printing a SKIPPED line when this CPU lacks AVX2 (so
/// a test comparing the AVX2 and the portable kernels says so rather than passing unchecked).
fn avx2_or_skip(test: &str) -> Option<Isa> {
    let isa = detect_isa();
    if isa.avx2().is_some() {
        return Some(isa);
    }
    eprintln!("SKIPPED: {test}: this CPU has no AVX2, so the AVX2 kernels were not checked");
    None
}
