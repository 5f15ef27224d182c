//! Statistical checks against exact values: the offline and online schedules, the attack chain,
//! and state mode against covariance mode.

use super::*;

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
        channel: None,
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

/// The corrected online formulas (Model note 2), written out independently of `schedules`.
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
    let exact =
        crate::chain::stationary::j_attack(&chain, &sys.weighted_traces(1.0 - lam, 10)).unwrap();
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

/// Each run's J lies between the least and the largest trace it meets, so the sample standard
/// deviation of the runs' J is at most half that range (Popoviciu's inequality; the sample
/// variance has the factor n / (n - 1)): stderr <= (tr_max - tr_min) / (2 sqrt(n - 1)). Online
/// with z0 = 2 and no attack, a flag after two losses brings the next packet at high power, so
/// τ <= 2 (kills a run's J taken as its sum `%` or `*` the horizon instead of `/`, in the
/// bit-sliced and in the lane kernels' drivers).
#[test]
fn standard_error_obeys_the_range_bound() {
    let sys = scalar_sys();
    let tr = sys.h_traces(2);
    let cfg = McConfig {
        runs: 2 * BLOCK_RUNS + 37,
        ..online(0.5, 2, 1.0, None)
    };
    let n = cfg.runs as f64;
    let bound = (tr[2] - tr[0]) / (2.0 * (n - 1.0).sqrt());
    for (name, res) in run_both(&sys, &cfg) {
        assert!(
            res.stderr > 0.0 && res.stderr <= bound,
            "{name}: {} vs {bound}",
            res.stderr
        );
    }
}

/// The standard error is the sample standard deviation over sqrt(runs): finite from two runs
/// on, and four times the runs halve it (within the few per cent the standard deviation's own
/// estimate varies by). Kills `m.n < 2` turned `<=` and the variance's `m2 / (n - 1)` turned
/// `%` (which leaves the error independent of the number of runs).
#[test]
fn standard_error_shrinks_as_the_root_of_the_runs() {
    let sys = scalar_sys();
    let with = |runs: u64| {
        let cfg = McConfig {
            runs,
            ..online(0.5, 2, 1.0, None)
        };
        run_both(&sys, &cfg)
    };
    for (name, res) in with(2) {
        assert!(
            res.stderr.is_finite() && res.stderr > 0.0,
            "{name}: {}",
            res.stderr
        );
    }
    let (few, many) = (with(500), with(2000));
    for ((name, a), (_, b)) in few.iter().zip(&many) {
        let ratio = b.stderr / a.stderr;
        assert!((0.4..0.6).contains(&ratio), "{name}: {ratio}");
    }
}

/// Two runs of two steps: step 1 is at high power (τ = 0), step 2 at low power arrives or not,
/// so a run's J is tr_0 or (tr_0 + tr_1) / 2. When the two runs differ by d = (tr_1 - tr_0) / 2
/// the sample variance is d² / 2 and the standard error sqrt(d² / 2 / 2) = d / 2; else it is 0
/// (kills the variance's n - 1 turned n + 1 or n / 1).
#[test]
fn standard_error_of_two_runs_is_exact() {
    let sys = scalar_sys();
    let tr = sys.h_traces(1);
    let half_d = (tr[1] - tr[0]) / 4.0;
    let mut differed = 0;
    for seed in 1..=12 {
        let cfg = McConfig {
            runs: 2,
            horizon: 2,
            seed,
            ..online(0.5, 2, 1.0, None)
        };
        for (name, res) in run_both(&sys, &cfg) {
            if res.stderr == 0.0 {
                continue;
            }
            assert!(
                (res.stderr - half_d).abs() < 1e-12 * half_d,
                "{name}: {}",
                res.stderr
            );
            differed += 1;
        }
    }
    assert!(differed > 0);
}

/// Runs whose J is finite while their average overflows: a stable scalar system seen through
/// a useless sensor (c = 1e-200) has P̄ = q / (1 - a²) = 9.3e307, every packet is sent at high
/// power, so each of the two runs has J = P̄ exactly (no spread) but their sum is beyond the
/// double range and J is +inf. The standard error of an infinite J is infinite, never 0 (kills
/// the error's rule `nonfinite || !J.is_finite()` turned `&&`, which gives 0 here).
#[test]
fn standard_error_of_an_overflowing_mean_is_infinite() {
    let m = |x: f64| DMatrix::from_element(1, 1, x);
    let sys = LinearSystem::new(m(0.5), m(1e-200), m(7e307), m(1.0)).unwrap();
    let pbar = sys.h_traces(0)[0];
    assert!(pbar.is_finite() && 2.0 * pbar == f64::INFINITY, "{pbar}");
    let cfg = McConfig {
        schedule: McSchedule::Offline { pattern: vec![1] },
        runs: 2,
        horizon: 1,
        ..online(0.5, 2, 1.0, None)
    };
    for (name, res) in run_both(&sys, &cfg) {
        assert_eq!(res.j, f64::INFINITY, "{name}");
        assert_eq!(res.stderr, f64::INFINITY, "{name}");
    }
}
