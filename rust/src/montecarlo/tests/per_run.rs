//! The per-run record of delivered flag-ACKs ([`McConfig::record_runs`],
//! [`McResult::delivered_per_run`]).

use super::*;

fn recorded(cfg: McConfig) -> McConfig {
    McConfig {
        record_runs: true,
        ..cfg
    }
}

/// (a) The mean of the per-run counts over the horizon is `flags_sent - flags_blocked`, for
/// both protocols, both modes and an offline schedule (all zeros).
#[test]
fn delivered_mean_matches_flag_rates() {
    let sys = scalar_sys();
    let offline = McSchedule::Offline {
        pattern: vec![1, 0, 0, 1, 0],
    };
    let cases = vec![
        online(0.5, 2, 1.0, None),
        online(0.5, 2, 0.4, Some(vec![true, false, false])),
        McConfig {
            protocol: Protocol::A,
            ..online(0.4, 3, 0.5, Some(vec![true, true, false]))
        },
        McConfig {
            mode: Mode::State,
            ..online(0.5, 2, 1.0, Some(vec![true, false]))
        },
        McConfig {
            schedule: offline,
            ..online(0.5, 2, 1.0, None)
        },
    ];
    for base in cases {
        let cfg = McConfig {
            horizon: 1_000,
            runs: 2 * BLOCK_RUNS + 37,
            seed: 71,
            ..recorded(base)
        };
        let r = run(&sys, &cfg).unwrap();
        let d = &r.delivered_per_run;
        assert_eq!(d.len() as u64, cfg.runs, "{cfg:?}");
        let total: u64 = d.iter().sum();
        let steps = (cfg.runs * cfg.horizon as u64) as f64;
        let want = r.flags_sent - r.flags_blocked;
        let mean = total as f64 / cfg.runs as f64 / cfg.horizon as f64;
        assert!(
            (mean - want).abs() <= 1e-12 * want,
            "{mean} vs {want} ({cfg:?})"
        );
        // The same as integers: the averaged fields are totals over runs × horizon.
        let (sent, blocked) = (r.flags_sent * steps, r.flags_blocked * steps);
        assert_eq!(total, sent.round() as u64 - blocked.round() as u64);
        if matches!(cfg.schedule, McSchedule::Offline { .. }) {
            assert!(d.iter().all(|&x| x == 0));
        } else {
            assert!(total > 0 && d.iter().all(|&x| x <= cfg.horizon as u64));
        }
    }
}

/// (b) The record depends on the seed only: 1 or 2 threads, any kernel, either mode and either
/// protocol; entry i is run i, whatever the number of runs after it. Checked here with the
/// portable kernels, and with the AVX2 ones in `avx2_delivered_matches_portable`.
#[test]
fn delivered_independent_of_threads_and_kernel() {
    check_delivered_record(Isa::Portable);
}

/// (b) with the AVX2 kernels.
#[test]
fn avx2_delivered_matches_portable() {
    if let Some(avx2) = avx2_or_skip("avx2_delivered_matches_portable") {
        check_delivered_record(avx2);
    }
}

/// The checks of (b), with `fast` (portable or AVX2) as the grouped lane kernel and the
/// bit-sliced kernel's build, against the reference and the portable bit-sliced kernel.
fn check_delivered_record(fast: Isa) {
    let sys = scalar_sys();
    let attack = || Some(vec![true, false, true, false, false]);
    let mut cases = Vec::new();
    for mu in [1.0, 0.4, 0.0] {
        cases.push(online(0.45, 2, mu, None));
        cases.push(online(0.45, 2, mu, attack()));
    }
    cases.extend(edge_kernel_cases());
    let (one, two) = (pool(1), pool(2));
    for base in cases {
        let cfg = McConfig {
            horizon: if cfg!(debug_assertions) { 300 } else { 777 },
            runs: 2 * BLOCK_RUNS + 37, // several blocks and a partial tile
            seed: 62,
            ..recorded(base)
        };
        // The lane kernels first (state mode shares their protocol randomness).
        let run_on = |cfg: &McConfig, isa, bitslice| {
            let kernels = Kernels { isa, bitslice };
            simulate_with(
                &sys,
                cfg,
                &AtomicBool::new(false),
                &AtomicU64::new(0),
                kernels,
            )
            .unwrap()
        };
        let go = |cfg: &McConfig, isa| run_on(cfg, isa, false);
        let reference = one.install(|| go(&cfg, Isa::Reference));
        let d = &reference.delivered_per_run;
        assert_eq!(d.len() as u64, cfg.runs);
        assert!(d.iter().any(|&x| x != d[0]), "{cfg:?}");
        assert_eq!(two.install(|| go(&cfg, Isa::Reference)), reference);
        assert_eq!(two.install(|| go(&cfg, Isa::Portable)), reference);
        assert_eq!(one.install(|| go(&cfg, fast)), reference);
        assert_eq!(two.install(|| go(&cfg, fast)), reference);
        let a = McConfig {
            protocol: Protocol::A,
            ..cfg.clone()
        };
        assert_eq!(two.install(|| go(&a, fast)).delivered_per_run, *d);
        // State mode draws the same protocol randomness.
        let state = McConfig {
            mode: Mode::State,
            ..cfg.clone()
        };
        assert_eq!(two.install(|| go(&state, fast)).delivered_per_run, *d);
        // Run order: the first runs of a smaller experiment are the same runs.
        let fewer = McConfig {
            runs: BLOCK_RUNS + 21,
            ..cfg.clone()
        };
        let r = two.install(|| go(&fewer, fast));
        assert_eq!(r.delivered_per_run[..], d[..fewer.runs as usize]);
        // The bit-sliced kernel: its own samples, with the same guarantees.
        let sliced = |cfg: &McConfig, isa| run_on(cfg, isa, true);
        let bs = one.install(|| sliced(&cfg, Isa::Portable));
        let d = &bs.delivered_per_run;
        assert_eq!(d.len() as u64, cfg.runs);
        assert_eq!(two.install(|| sliced(&cfg, fast)), bs);
        assert_eq!(two.install(|| sliced(&a, fast)).delivered_per_run, *d);
        let r = two.install(|| sliced(&fewer, fast));
        assert_eq!(r.delivered_per_run[..], d[..fewer.runs as usize]);
        // Its record agrees with its totals.
        let total: u64 = d.iter().sum();
        let per_step = total as f64 / (cfg.runs as f64 * cfg.horizon as f64);
        assert!((per_step - (bs.flags_sent - bs.flags_blocked)).abs() < 1e-12);
    }
}

/// (c) Without an attacker the mean count matches horizon × the analytic high-power rate
/// λ a^z0 (μ + (1-μ) a) / (1 - μ a^(z0+1) - (1-μ) a^(z0+2)), a = 1 - λ (every delivered flag
/// raises the next step's power; the initial high-power step is no flag). The start-up
/// transient shifts the mean by O(1) flags, far below the standard error at this horizon.
#[test]
fn delivered_count_matches_online_rate() {
    let sys = scalar_sys();
    for (lam, z0, mu, seed) in [
        (0.5, 2u64, 1.0, 81u64),
        (0.5, 2, 0.4, 82),
        (0.3, 3, 0.7, 83),
    ] {
        let cfg = McConfig {
            horizon: scaled(100_000) as usize,
            runs: scaled(512),
            seed,
            ..recorded(online(lam, z0, mu, None))
        };
        let r = run(&sys, &cfg).unwrap();
        let a: f64 = 1.0 - lam;
        let z = z0 as i32;
        let rate = lam * a.powi(z) * (mu + (1.0 - mu) * a)
            / (1.0 - mu * a.powi(z + 1) - (1.0 - mu) * a.powi(z + 2));
        let counts: Vec<f64> = r.delivered_per_run.iter().map(|&x| x as f64).collect();
        let n = counts.len() as f64;
        let mean = counts.iter().sum::<f64>() / n;
        let var = counts.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let want = cfg.horizon as f64 * rate;
        assert_close(
            &format!("delivered (lam = {lam}, z0 = {z0}, mu = {mu})"),
            mean,
            want,
            (var / n).sqrt(),
            4.0,
        );
    }
}

/// (d) Without `record_runs` the record is empty and unallocated, and the other outputs are
/// those of a recording run; recording refuses more than 2^28 runs before any work.
#[test]
fn delivered_only_on_request() {
    let sys = scalar_sys();
    let offline = McSchedule::Offline {
        pattern: vec![1, 0, 0],
    };
    let cases = vec![
        online(0.5, 2, 0.4, Some(vec![true, false, false])),
        McConfig {
            mode: Mode::State,
            ..online(0.5, 2, 1.0, None)
        },
        McConfig {
            schedule: offline,
            ..online(0.5, 2, 1.0, None)
        },
    ];
    for cfg in cases {
        let off = run(&sys, &cfg).unwrap();
        assert!(off.delivered_per_run.is_empty());
        assert_eq!(off.delivered_per_run.capacity(), 0);
        let on = run(&sys, &recorded(cfg.clone())).unwrap();
        assert_eq!(on.delivered_per_run.len() as u64, cfg.runs);
        let on = McResult {
            delivered_per_run: Vec::new(),
            ..on
        };
        assert_eq!(on, off);
    }
    let big = McConfig {
        runs: (1 << 28) + 1,
        ..recorded(online(0.5, 2, 1.0, None))
    };
    let progress = AtomicU64::new(0);
    let e = simulate(&sys, &big, &AtomicBool::new(false), &progress).unwrap_err();
    assert_eq!(
        e,
        Error::TooLarge {
            arg: "runs".into(),
            requested: (1 << 28) + 1,
            limit: 1 << 28,
        }
    );
    assert!(e.to_string().starts_with("runs:"), "{e}");
    assert_eq!(progress.load(Ordering::Relaxed), 0);
}
