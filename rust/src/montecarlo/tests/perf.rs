//! The ignored throughput and memory checks, run by hand with `--ignored --nocapture`.

use super::*;

/// 10^6 runs × 10^4 steps in bounded memory:
/// `cargo test --release montecarlo::tests::perf::big_run -- --ignored --nocapture`.
#[test]
#[ignore]
fn big_run() {
    let sys = scalar_sys();
    let cfg = McConfig {
        horizon: 10_000,
        runs: 1_000_000,
        seed: 3,
        ..online(0.5, 2, 1.0, None)
    };
    let (t, c) = (std::time::Instant::now(), cpu_seconds());
    let progress = AtomicU64::new(0);
    let r = simulate(&sys, &cfg, &AtomicBool::new(false), &progress).unwrap();
    let (dt, dc) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let peak = status
        .lines()
        .find(|l| l.starts_with("VmHWM"))
        .unwrap_or("");
    println!(
        "10^10 steps in {dt:.2} s wall ({:.3e} steps/s), {dc:.2} CPU-s; j = {} ± {:.1e}; {peak}",
        1e10 / dt,
        r.j,
        r.stderr
    );
    assert_eq!(progress.load(Ordering::Relaxed), cfg.runs);
    // At this precision the start-up transient shows (J_H = J + C/H, C ≈ -0.7 here), so
    // compare with the exact finite-horizon law of τ: from τ < z0 to 0 w.p. λ, else τ + 1;
    // from τ = z0 (a flag was delivered) to 0 surely; τ_1 = 0.
    let (lam, z0) = (0.5, 2usize);
    let tr = sys.h_traces(z0);
    let mut law = vec![0.0; z0 + 1];
    law[0] = 1.0;
    let mut total = 0.0;
    for k in 0..cfg.horizon {
        if k > 0 {
            let mut next = vec![0.0; z0 + 1];
            next[0] = law[z0];
            for t in 0..z0 {
                next[0] += lam * law[t];
                next[t + 1] += (1.0 - lam) * law[t];
            }
            law = next;
        }
        let mean: f64 = law.iter().zip(&tr).map(|(p, t)| p * t).sum();
        let var: f64 = law
            .iter()
            .zip(&tr)
            .map(|(p, t)| p * (t - mean).powi(2))
            .sum();
        let se = (var / cfg.runs as f64).sqrt();
        let tol = 6.0 * se + 1e-12 * mean; // rounding of the sums when the law is a point
        assert!((r.mean_trace[k] - mean).abs() <= tol, "k = {k}");
        total += mean;
    }
    assert_close("J_H", r.j, total / cfg.horizon as f64, r.stderr, 4.0);
}

/// CPU seconds used by this process so far (all threads), from /proc (Linux only).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = after
        .split_whitespace()
        .map(|x| x.parse().unwrap_or(0.0))
        .collect();
    // Fields 14 and 15 of the file (utime, stime) in clock ticks of 1/100 s.
    if f.len() > 13 {
        (f[11] + f[12]) / 100.0
    } else {
        f64::NAN
    }
}

fn env_or(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Throughput: `cargo test --release montecarlo::tests::perf::speed -- --ignored --nocapture`.
/// Prints wall-clock steps/s and steps per CPU-second (the latter times the core count is
/// what the machine does when nothing else runs). `MC_SPEED_FILTER` selects cases by name
/// ("lanes" for the lane kernels; a leading ^ anchors it); `MC_SPEED_THREADS`, `MC_SPEED_HORIZON`, `MC_SPEED_RUNS` and
/// `MC_SPEED_REPS` override 2 threads, 10^4 steps, 8192 runs per thread and 5 repetitions (small values suit `valgrind --tool=callgrind`).
#[test]
#[ignore]
fn speed() {
    let sys = scalar_sys();
    let big = ten_state_sys();
    let filter = std::env::var("MC_SPEED_FILTER").unwrap_or_default();
    let threads = env_or("MC_SPEED_THREADS", 2);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let families = [
        ("", detect_isa(), true),
        ("lanes ", detect_isa(), false),
        ("lanes ", Isa::Portable, false),
    ];
    for (family, isa, bitslice) in families {
        let kernels = Kernels { isa, bitslice };
        for (name, cfg) in speed_cases() {
            let label = format!("{family}{} {name}", isa.name());
            let keep = match filter.strip_prefix('^') {
                Some(head) => label.starts_with(head),
                None => label.contains(filter.as_str()),
            };
            if !keep {
                continue;
            }
            let state = cfg.mode == Mode::State;
            let cfg = McConfig {
                horizon: env_or("MC_SPEED_HORIZON", 10_000),
                runs: env_or("MC_SPEED_RUNS", if state { 256 } else { 8192 } * threads) as u64,
                ..cfg
            };
            let sys = if name.contains("10-state") {
                &big
            } else {
                &sys
            };
            let (best, best_cpu, j) = pool.install(|| best_speed(sys, &cfg, kernels));
            println!(
                "{label}: {best:.3e} steps/s wall, {best_cpu:.3e} per CPU-s ({threads} threads; j = {j:.6})"
            );
        }
    }
}

/// The speed test's experiments, by name.
fn speed_cases() -> Vec<(&'static str, McConfig)> {
    let attack = || Some(vec![true, false, false]);
    let offline = McSchedule::Offline {
        pattern: vec![1, 0, 0, 0, 0, 0, 0],
    };
    let state = |cfg: McConfig| McConfig {
        mode: Mode::State,
        ..cfg
    };
    vec![
        ("online z0=2 mu=1", online(0.5, 2, 1.0, None)),
        ("online z0=2 mu=0.4", online(0.5, 2, 0.4, None)),
        ("online attack 1/3 B", online(0.5, 2, 1.0, attack())),
        (
            "online attack 1/3 A",
            McConfig {
                protocol: Protocol::A,
                ..online(0.5, 2, 1.0, attack())
            },
        ),
        ("online mu=0.4 attack B", online(0.5, 2, 0.4, attack())),
        (
            "online attack 1/5 B",
            online(0.5, 2, 1.0, Some(vec![true, false, false, false, false])),
        ),
        (
            "online random 0.2 B",
            McConfig {
                attack: Some(Attack::random(0.2).unwrap()),
                ..online(0.5, 2, 1.0, None)
            },
        ),
        (
            "online random 0.2 A",
            McConfig {
                attack: Some(Attack::random(0.2).unwrap()),
                protocol: Protocol::A,
                ..online(0.5, 2, 1.0, None)
            },
        ),
        (
            "online inject 0.05 B",
            McConfig {
                attack: Some(Attack::injection(0.05, None).unwrap()),
                ..online(0.5, 2, 1.0, None)
            },
        ),
        (
            "online inject 0.05+random 0.2 B",
            McConfig {
                attack: Some(Attack::injection(0.05, Some(Attack::random(0.2).unwrap())).unwrap()),
                ..online(0.5, 2, 1.0, None)
            },
        ),
        (
            "offline 1/7",
            McConfig {
                schedule: offline.clone(),
                ..online(0.5, 2, 1.0, None)
            },
        ),
        ("state online z0=2 mu=1", state(online(0.5, 2, 1.0, None))),
        (
            "state online attack 1/5",
            state(online(
                0.5,
                2,
                1.0,
                Some(vec![true, false, false, false, false]),
            )),
        ),
        (
            "state 10-state online z0=2 mu=1",
            state(online(0.5, 2, 1.0, None)),
        ),
        (
            "state offline 1/7",
            state(McConfig {
                schedule: offline,
                ..online(0.5, 2, 1.0, None)
            }),
        ),
    ]
}

/// State mode on a 10-state, 3-output system (n_x = 10: the size at which state mode should stay useful).
fn ten_state_sys() -> LinearSystem {
    let n = 10;
    let mut a = DMatrix::<f64>::identity(n, n) * 0.95;
    for i in 0..n - 1 {
        a[(i, i + 1)] = 0.2;
    }
    a[(0, 0)] = 1.1;
    let mut c = DMatrix::<f64>::zeros(3, n);
    for i in 0..3 {
        c[(i, 3 * i)] = 1.0;
        c[(i, 3 * i + 1)] = 0.5;
    }
    let q = DMatrix::<f64>::identity(n, n) * 0.1;
    let r = DMatrix::<f64>::identity(3, 3);
    LinearSystem::new(a, c, q, r).unwrap()
}

/// The best of `MC_SPEED_REPS` (5) runs of `cfg`, the least disturbed by other processes:
/// (steps/s wall, steps per CPU-second, J).
fn best_speed(sys: &LinearSystem, cfg: &McConfig, kernels: Kernels) -> (f64, f64, f64) {
    let (mut best, mut best_cpu, mut j) = (0.0f64, 0.0f64, 0.0);
    for _ in 0..env_or("MC_SPEED_REPS", 5) {
        let (t, c) = (std::time::Instant::now(), cpu_seconds());
        let r = simulate_with(
            sys,
            cfg,
            &AtomicBool::new(false),
            &AtomicU64::new(0),
            kernels,
        )
        .unwrap();
        let (dt, dc) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        let steps = cfg.runs as f64 * cfg.horizon as f64;
        best = best.max(steps / dt);
        best_cpu = best_cpu.max(steps / dc);
        j = r.j;
    }
    (best, best_cpu, j)
}
