use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use nalgebra::DMatrix;

use super::driver::{simulate_with, Kernels};
use super::kernel::{detect_isa, Isa};
use super::plan::{max_tau, Plan};
use super::*;
use crate::attack::Attack;
use crate::error::{Error, Result};
use crate::riccati::LinearSystem;

mod per_run;
mod perf;

fn scalar_sys() -> LinearSystem {
    let m = |x: f64| DMatrix::from_element(1, 1, x);
    LinearSystem::new(m(1.2), m(0.7), m(0.8), m(0.8)).unwrap()
}

/// An online experiment, attacked by the blocking mask `mask` if given.
fn online(lam: f64, z0: u64, mu: f64, mask: Option<Vec<bool>>) -> McConfig {
    McConfig {
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

/// (1) Offline 1/7 against the exact period average, derived here by propagating the law of
/// τ over one period (the run starts on the pattern's 1, so E Tr P_k is exactly periodic).
#[test]
fn offline_matches_exact_period_average() {
    let sys = scalar_sys();
    let lam = 0.5;
    let pattern = vec![1u8, 0, 0, 0, 0, 0, 0];
    let tr = sys.h_traces(8);
    let mut law = vec![0.0; 8];
    let mut total = 0.0;
    for &g in &pattern {
        let mut next = vec![0.0; 8];
        if g == 1 {
            next[0] = 1.0;
        } else {
            for t in 0..7 {
                next[0] += lam * law[t];
                next[t + 1] += (1.0 - lam) * law[t];
            }
        }
        law = next;
        total += law.iter().zip(&tr).map(|(p, t)| p * t).sum::<f64>();
    }
    let j_off = total / pattern.len() as f64;
    let cfg = McConfig {
        lam,
        schedule: McSchedule::Offline { pattern },
        attack: None,
        mode: Mode::Covariance,
        protocol: Protocol::B,
        horizon: 7_000,
        runs: scaled(2_048),
        seed: 11,
        record_runs: false,
    };
    for (kernel, r) in run_both(&sys, &cfg) {
        assert_close(&format!("J_off ({kernel})"), r.j, j_off, r.stderr, 4.0);
        assert_eq!(r.high_power_rate, 1.0 / 7.0);
        assert_eq!((r.flags_sent, r.flags_blocked), (0.0, 0.0));
        assert_eq!(r.j, r.j_k[r.j_k.len() - 1]);
        // Per step: k = 1 (mod 7) is always an arrival.
        assert_eq!(r.mean_trace[0], tr[0]);
        assert_eq!(r.mean_trace[7], tr[0]);
    }
}

/// The corrected online formulas (ERRATA item 2), written out independently of `schedules`.
fn j_online_closed(tr: &[f64], lam: f64, z0: usize, mu: f64) -> (f64, f64) {
    let a: f64 = 1.0 - lam;
    let den = 1.0 - mu * a.powi(z0 as i32 + 1) - (1.0 - mu) * a.powi(z0 as i32 + 2);
    let head: f64 = (0..=z0).map(|i| a.powi(i as i32) * tr[i]).sum();
    let tail = (1.0 - mu) * a.powi(z0 as i32 + 1) * tr[z0 + 1];
    let j = lam / den * (head + tail);
    let rate = lam * a.powi(z0 as i32) * (mu + (1.0 - mu) * a) / den;
    (j, rate)
}

/// (2) Online z0 = 2 with μ = 1 and μ = 0.4 against J_on and the high-power rate.
#[test]
fn online_matches_corrected_formula() {
    let sys = scalar_sys();
    let tr = sys.h_traces(4);
    for (mu, seed) in [(1.0, 21u64), (0.4, 22)] {
        let cfg = McConfig {
            horizon: scaled(100_000) as usize,
            runs: scaled(512),
            seed,
            ..online(0.5, 2, mu, None)
        };
        let (j, rate) = j_online_closed(&tr, 0.5, 2, mu);
        for (kernel, r) in run_both(&sys, &cfg) {
            assert_close(&format!("J_on(mu = {mu}, {kernel})"), r.j, j, r.stderr, 4.0);
            assert!(
                (r.high_power_rate - rate).abs() < binomial_tol(rate, &cfg),
                "mu = {mu}, {kernel}: {} vs {rate}",
                r.high_power_rate
            );
            // No attacker: every flag is delivered, and all high-power steps but the first
            // follow one.
            assert_eq!(r.flags_blocked, 0.0);
            let steps = (cfg.runs * cfg.horizon as u64) as f64;
            let diff = (r.high_power_rate - r.flags_sent) * steps;
            assert!(diff.abs() <= cfg.runs as f64, "{diff}");
        }
    }
    // μ = 1: the paper's example uses high power 1/7 of the time.
    assert!((j_online_closed(&tr, 0.5, 2, 1.0).1 - 1.0 / 7.0).abs() < 1e-15);
}

/// (3) Attack r = 1, t = 3 against the stationary law of the attack chain.
#[test]
fn attack_matches_chain() {
    let sys = scalar_sys();
    let lam = 0.5;
    let chain = crate::chain::AttackChain::new(lam, 2, 1, 3).unwrap();
    let exact = crate::stationary::j_attack(&chain, &sys.weighted_traces(1.0 - lam, 10)).unwrap();
    let cfg = McConfig {
        horizon: scaled(100_000) as usize,
        runs: scaled(512),
        seed: 31,
        ..online(lam, 2, 1.0, Some(vec![true, false, false]))
    };
    for (kernel, r) in run_both(&sys, &cfg) {
        assert_close(&format!("J_attack ({kernel})"), r.j, exact, r.stderr, 4.0);
        // The counter runs over all flags: exactly one in three is blocked (up to the last
        // cycle).
        let steps = (cfg.runs * cfg.horizon as u64) as f64;
        let (sent, blocked) = (r.flags_sent * steps, r.flags_blocked * steps);
        assert!(
            (sent / 3.0 - blocked).abs() <= cfg.runs as f64,
            "{kernel}: {sent} {blocked}"
        );
        // Blocked flags do not raise the power.
        let high = r.high_power_rate * steps;
        assert!((high - (sent - blocked)).abs() <= cfg.runs as f64);
    }
}

/// (4) Protocols A and B are separate code paths with identical statistics, draw for draw.
#[test]
fn protocols_agree() {
    let sys = scalar_sys();
    for mode in [Mode::Covariance, Mode::State] {
        for mu in [1.0, 0.4] {
            let b = McConfig {
                mode,
                horizon: 3_000,
                runs: scaled(300),
                seed: 41,
                ..online(0.4, 2, mu, Some(vec![true, false, true, true, false]))
            };
            let a = McConfig {
                protocol: Protocol::A,
                ..b.clone()
            };
            for ((kernel, ra), (_, rb)) in run_both(&sys, &a).into_iter().zip(run_both(&sys, &b)) {
                assert_eq!(ra, rb, "{mode:?}, mu = {mu}, {kernel}");
                assert!(rb.flags_blocked > 0.0);
            }
        }
    }
}

/// (5) State mode (real Gaussian errors) against covariance mode, scalar and vector systems.
#[test]
fn state_mode_matches_covariance_mode() {
    let offline = McSchedule::Offline {
        pattern: vec![1, 0, 0, 1, 0],
    };
    let cases = [
        ("scalar, online", scalar_sys(), online(0.5, 2, 1.0, None)),
        (
            "scalar, attack",
            scalar_sys(),
            online(0.5, 2, 0.4, Some(vec![true, false, false])),
        ),
        (
            "two-state, offline",
            two_state_sys(),
            McConfig {
                schedule: offline,
                ..online(0.4, 2, 1.0, None)
            },
        ),
        (
            "two-state, online",
            two_state_sys(),
            online(0.4, 3, 0.5, None),
        ),
        (
            "three-state, online",
            three_state_sys(),
            online(0.3, 2, 1.0, None),
        ),
    ];
    for (name, sys, cfg) in cases {
        let cov = McConfig {
            horizon: 1_000,
            runs: scaled(1_024),
            seed: 51,
            ..cfg
        };
        let state = McConfig {
            mode: Mode::State,
            ..cov.clone()
        };
        let (rc, rs) = (run(&sys, &cov).unwrap(), run(&sys, &state).unwrap());
        let se = rc.stderr.hypot(rs.stderr);
        assert_close(name, rs.j, rc.j, se, 4.0);
        // Same seed, same protocol randomness as the lane kernels: the power decisions coincide.
        let lanes = Kernels {
            isa: detect_isa(),
            bitslice: false,
        };
        let rl = simulate_with(
            &sys,
            &cov,
            &AtomicBool::new(false),
            &AtomicU64::new(0),
            lanes,
        );
        let rl = rl.unwrap();
        assert_eq!(rs.high_power_rate, rl.high_power_rate, "{name}");
        assert_eq!(rs.flags_sent, rl.flags_sent, "{name}");
    }
    // k = 1 is an arrival: E||e_1||² = Tr P̄ checks the stationary start and the gain.
    for sys in [two_state_sys(), three_state_sys()] {
        let cfg = McConfig {
            mode: Mode::State,
            horizon: 1,
            runs: scaled(40_000),
            seed: 52,
            ..online(0.5, 2, 1.0, None)
        };
        let r = run(&sys, &cfg).unwrap();
        assert_close("E||e_1||²", r.j, sys.pbar().trace(), r.stderr, 4.0);
    }
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

/// (6) Results depend on the seed only: 1 or 2 threads, portable or vector kernel.
#[test]
fn independent_of_threads_and_kernel() {
    let sys = scalar_sys();
    let offline = McSchedule::Offline {
        pattern: vec![1, 0, 0, 1, 0, 0, 0],
    };
    let attack = || Some(vec![true, false, true, false, false]);
    let mut cases = Vec::new();
    for mu in [1.0, 0.4, 0.0] {
        cases.push(online(0.45, 2, mu, None));
        for protocol in [Protocol::A, Protocol::B] {
            cases.push(McConfig {
                protocol,
                ..online(0.45, 2, mu, attack())
            });
        }
    }
    cases.push(McConfig {
        schedule: offline,
        ..online(0.45, 2, 1.0, None)
    });
    cases.extend(edge_kernel_cases());
    let (one, two) = (pool(1), pool(2));
    for base in cases {
        let cfg = McConfig {
            horizon: if cfg!(debug_assertions) { 300 } else { 777 },
            runs: 2 * BLOCK_RUNS + 37, // several blocks and a partial tile
            seed: 61,
            ..base
        };
        let go = |isa, bitslice| {
            let kernels = Kernels { isa, bitslice };
            simulate_with(
                &sys,
                &cfg,
                &AtomicBool::new(false),
                &AtomicU64::new(0),
                kernels,
            )
            .unwrap()
        };
        // The lane kernels.
        let reference = one.install(|| go(Isa::Reference, false));
        assert_eq!(
            two.install(|| go(Isa::Portable, false)),
            reference,
            "{cfg:?}"
        );
        assert_eq!(
            one.install(|| go(detect_isa(), false)),
            reference,
            "{cfg:?}"
        );
        assert_eq!(
            two.install(|| go(detect_isa(), false)),
            reference,
            "{cfg:?}"
        );
        // The bit-sliced kernel (every plan here fits it).
        assert!(Plan::new(&sys, &cfg).unwrap().bitslice.is_some(), "{cfg:?}");
        let sliced = one.install(|| go(Isa::Portable, true));
        assert_eq!(two.install(|| go(detect_isa(), true)), sliced, "{cfg:?}");
        assert_eq!(one.install(|| go(detect_isa(), true)), sliced, "{cfg:?}");
    }
    let state = McConfig {
        mode: Mode::State,
        horizon: 200,
        runs: BLOCK_RUNS + 5,
        ..online(0.45, 2, 0.4, attack())
    };
    assert_eq!(
        one.install(|| run(&sys, &state)),
        two.install(|| run(&sys, &state))
    );
}

/// (7) Cancellation: before the start, and from another thread while running.
#[test]
fn cancel_interrupts() {
    let sys = scalar_sys();
    let cfg = online(0.5, 2, 1.0, None);
    let cancel = AtomicBool::new(true);
    let progress = AtomicU64::new(0);
    assert_eq!(
        simulate(&sys, &cfg, &cancel, &progress),
        Err(Error::Interrupted)
    );
    assert_eq!(progress.load(Ordering::Relaxed), 0);
    // Too long to finish (2·10^10 steps): must stop on the flag.
    let long = McConfig {
        horizon: 2_000_000,
        runs: 10_000,
        ..cfg
    };
    let cancel = AtomicBool::new(false);
    let res = std::thread::scope(|s| {
        let h = s.spawn(|| simulate(&sys, &long, &cancel, &progress));
        std::thread::sleep(std::time::Duration::from_millis(50));
        cancel.store(true, Ordering::Relaxed);
        h.join().unwrap()
    });
    assert_eq!(res, Err(Error::Interrupted));
    let state = McConfig {
        mode: Mode::State,
        ..long
    };
    let cancel = AtomicBool::new(false);
    let res = std::thread::scope(|s| {
        let h = s.spawn(|| simulate(&sys, &state, &cancel, &progress));
        std::thread::sleep(std::time::Duration::from_millis(50));
        cancel.store(true, Ordering::Relaxed);
        h.join().unwrap()
    });
    assert_eq!(res, Err(Error::Interrupted));
}

/// (8) Bad inputs give errors that name the argument.
#[test]
fn bad_inputs_are_named() {
    let sys = scalar_sys();
    let base = online(0.5, 2, 1.0, None);
    let off = |pattern: Vec<u8>| McConfig {
        schedule: McSchedule::Offline { pattern },
        ..base.clone()
    };
    let cases: Vec<(McConfig, &str)> = vec![
        (
            McConfig {
                lam: 0.0,
                ..base.clone()
            },
            "lam",
        ),
        (
            McConfig {
                lam: 1.0,
                ..base.clone()
            },
            "lam",
        ),
        (
            McConfig {
                lam: f64::NAN,
                ..base.clone()
            },
            "lam",
        ),
        (online(0.5, 2, 1.5, None), "mu"),
        (online(0.5, 2, f64::NAN, None), "mu"),
        (online(0.5, 0, 1.0, None), "z0"),
        (online(0.5, 2, 1.0, Some(vec![])), "mask"),
        (
            McConfig {
                attack: Some(Attack::Periodic { r: 3, t: 3 }),
                ..base.clone()
            },
            "r",
        ),
        (off(vec![]), "pattern"),
        (off(vec![0, 1]), "pattern"),
        (off(vec![1, 2]), "pattern"),
        (
            McConfig {
                attack: Some(Attack::Mask(vec![true])),
                ..off(vec![1, 0])
            },
            "attack",
        ),
        (
            McConfig {
                horizon: 0,
                ..base.clone()
            },
            "horizon",
        ),
        (
            McConfig {
                runs: 0,
                ..base.clone()
            },
            "runs",
        ),
        (
            McConfig {
                horizon: MAX_HORIZON + 1,
                ..base.clone()
            },
            "horizon",
        ),
    ];
    for (cfg, arg) in cases {
        let e = run(&sys, &cfg).unwrap_err();
        assert!(
            e.to_string().starts_with(&format!("{arg}:")),
            "{e} (expected {arg})"
        );
    }
    let e = run(
        &sys,
        &McConfig {
            horizon: usize::MAX,
            ..base
        },
    )
    .unwrap_err();
    assert!(matches!(e, Error::TooLarge { .. }), "{e}");
}

#[test]
fn edge_cases() {
    let sys = scalar_sys();
    // One run: no spread can be estimated.
    let r = run(
        &sys,
        &McConfig {
            runs: 1,
            ..online(0.5, 2, 1.0, None)
        },
    )
    .unwrap();
    assert_eq!(r.stderr, f64::INFINITY);
    assert!(r.j.is_finite());
    // Always high power: P_k = P̄ every step, no spread at all.
    let cfg = McConfig {
        schedule: McSchedule::Offline { pattern: vec![1] },
        horizon: 50,
        runs: 40,
        ..online(0.5, 2, 1.0, None)
    };
    let progress = AtomicU64::new(0);
    let r = simulate(&sys, &cfg, &AtomicBool::new(false), &progress).unwrap();
    assert_eq!(progress.load(Ordering::Relaxed), 40);
    let pbar = sys.pbar()[(0, 0)];
    assert!(r.mean_trace.iter().all(|&x| x == pbar));
    assert_eq!((r.j, r.stderr, r.high_power_rate), (pbar, 0.0, 1.0));
    assert_eq!((r.runs, r.steps), (40, 50));
    // Horizon 1: only the initial high-power step.
    let r = run(
        &sys,
        &McConfig {
            horizon: 1,
            ..online(0.5, 2, 0.3, None)
        },
    )
    .unwrap();
    assert_eq!(r.mean_trace, vec![pbar]);
    assert_eq!(r.high_power_rate, 1.0);
    // Every flag blocked: τ is unbounded but the run stays finite (a ρ² = 0.72 < 1).
    let r = run(&sys, &online(0.5, 2, 1.0, Some(vec![true]))).unwrap();
    assert_eq!(r.high_power_rate, 1.0 / 1000.0);
    assert!(r.j.is_finite() && r.stderr.is_finite());
    // z0 beyond the horizon: no flag is ever due.
    let r = run(&sys, &online(0.5, u64::MAX, 0.5, None)).unwrap();
    assert_eq!(r.flags_sent, 0.0);
}

#[test]
fn reachable_tau() {
    let off = McSchedule::Offline {
        pattern: vec![1, 0, 1, 0, 0, 0],
    };
    assert_eq!(max_tau(&off, None), Some(3));
    let on = |mu| McSchedule::Online { z0: 2, mu };
    assert_eq!(max_tau(&on(1.0), None), Some(2));
    assert_eq!(max_tau(&on(0.5), None), Some(3));
    assert_eq!(max_tau(&on(1.0), Some(&[true, false, false])), Some(4));
    assert_eq!(max_tau(&on(0.0), Some(&[true, false, true])), Some(9));
    assert_eq!(max_tau(&on(1.0), Some(&[true, true])), None);
}

/// An attack given as (r, t) is the mask 1^r 0^(t-r): the same experiment, draw for draw, on
/// every kernel family and in both modes.
#[test]
fn periodic_attack_is_its_mask() {
    let sys = scalar_sys();
    for mode in [Mode::Covariance, Mode::State] {
        let mask = McConfig {
            mode,
            horizon: 500,
            runs: BLOCK_RUNS + 9,
            seed: 91,
            ..online(0.45, 2, 0.4, Some(vec![true, true, false, false, false]))
        };
        let periodic = McConfig {
            attack: Some(Attack::periodic(2, 5).unwrap()),
            ..mask.clone()
        };
        for ((kernel, rm), (_, rp)) in run_both(&sys, &mask)
            .into_iter()
            .zip(run_both(&sys, &periodic))
        {
            assert_eq!(rm, rp, "{mode:?}, {kernel}");
            assert!(rp.flags_blocked > 0.0);
        }
    }
}

/// Plans the bit-sliced kernel does not take run on the lane kernels, through the same entry.
#[test]
fn deep_plans_use_the_lane_kernels() {
    let sys = scalar_sys();
    let mut gap = vec![0u8; 41];
    gap[0] = 1;
    let five_runs: Vec<bool> = (0..10).map(|i| i % 2 == 0).collect();
    let cases = [
        // τ bound 40 > MAX_DEPTH.
        McConfig {
            schedule: McSchedule::Offline { pattern: gap },
            ..online(0.5, 2, 1.0, None)
        },
        // Five runs of ones in the mask.
        online(0.5, 2, 1.0, Some(five_runs)),
        // A 40-bit memory under attack.
        online(0.5, 40, 1.0, Some(vec![true, false])),
        McConfig {
            mode: Mode::State,
            ..online(0.5, 2, 1.0, None)
        },
    ];
    for base in cases {
        let cfg = McConfig {
            horizon: 200,
            runs: BLOCK_RUNS + 3,
            ..base
        };
        assert!(Plan::new(&sys, &cfg).unwrap().bitslice.is_none(), "{cfg:?}");
        let [(_, auto), (_, lanes)] = run_both(&sys, &cfg);
        assert_eq!(auto, lanes, "{cfg:?}");
    }
}
