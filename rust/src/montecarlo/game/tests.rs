//! The closed loop against the exact stationary costs, determinism, the policies' switching, and
//! (ignored) its speed.

use super::plan::Plan;
use super::*;
use crate::schedule::{offline_schedule, Ratio};

/// Attacker automata.
mod automaton;
/// The game on a Markov channel.
mod channel;
/// The CUSUM policy.
mod cusum;
/// The likelihood-ratio window test.
mod lr;
/// The support check.
mod support;

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

fn config(attack: Option<Attack>, policy: Policy) -> GameConfig {
    GameConfig {
        lam: 0.5,
        channel: None,
        design: OnlineDesign::fixed(2).unwrap(),
        offline: offline_schedule(Ratio::new(1, 7).unwrap()).unwrap(),
        attack,
        automaton: None,
        policy,
        window: 1000,
        horizon: 20_000,
        burn_in: 1000,
        runs: 512,
        seed: 7,
    }
}

/// The results of both kernels: the bit-sliced one, then the lane kernel (each checked to report
/// every run done).
fn both(sys: &LinearSystem, cfg: &GameConfig) -> [GameRuns; 2] {
    assert!(Sliced::of(&Plan::new(sys, cfg).unwrap()).is_some());
    [true, false].map(|sliced| {
        let progress = AtomicU64::new(0);
        let out = simulate_on(sys, cfg, &AtomicBool::new(false), &progress, sliced).unwrap();
        // Progress counts runs, a partial last block or tile counting only its runs.
        assert_eq!(progress.into_inner(), cfg.runs);
        out
    })
}

fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
    (m, (v / n).sqrt())
}

#[test]
fn online_matches_the_exact_costs_and_rates() {
    let sys = paper();
    let design = OnlineDesign::fixed(2).unwrap();
    for attack in [
        None,
        Some(Attack::periodic(1, 5).unwrap()),
        Some(Attack::mask(vec![true, false, true, true, false]).unwrap()),
        Some(Attack::random(0.3).unwrap()),
        Some(Attack::injection(0.1, None).unwrap()),
        Some(Attack::injection(0.04, Some(Attack::random(0.2).unwrap())).unwrap()),
    ] {
        for res in both(&sys, &config(attack.clone(), Policy::Online)) {
            let (j, se) = mean_se(&res.cost);
            let exact = match &attack {
                None => sys.j_online(0.5, design).unwrap(),
                Some(a) => sys.j_attack(0.5, design, a).unwrap(),
            };
            assert!(
                (j - exact).abs() < 4.0 * se,
                "{attack:?}: {j} ± {se} vs {exact}"
            );
            let (hp, se_hp) = mean_se(&res.high_power);
            let rate = crate::flag_rates(0.5, design, attack.as_ref())
                .unwrap()
                .delivered;
            assert!((hp - rate).abs() < 4.0 * se_hp + 1e-4, "{hp} vs {rate}");
            // Online, the sensor uses high power exactly after each flag-ACK that reaches it.
            for (d, h) in res.delivered.iter().zip(&res.high_power) {
                assert!(
                    (*d as f64 - h * 20_000.0).abs() <= 1.5,
                    "{attack:?}: {d} vs {}",
                    h * 20_000.0
                );
            }
            assert!(res.online.iter().all(|&o| o == 1.0));
        }
    }
}

#[test]
fn offline_matches_the_offline_cost() {
    let sys = paper();
    let cfg = config(Some(Attack::periodic(2, 3).unwrap()), Policy::Offline);
    for res in both(&sys, &cfg) {
        let (j, se) = mean_se(&res.cost);
        let exact = sys.j_offline(0.5, Ratio::new(1, 7).unwrap()).unwrap();
        assert!((j - exact).abs() < 4.0 * se, "{j} ± {se} vs {exact}");
        assert!(res.high_power.iter().all(|&h| (h - 1.0 / 7.0).abs() < 1e-3));
        assert!(res.online.iter().all(|&o| o == 0.0));
    }
}

#[test]
fn results_depend_on_the_seed_and_the_run_only() {
    let sys = paper();
    let mut cfg = config(Some(Attack::random(0.3).unwrap()), Policy::Online);
    cfg.runs = 37;
    cfg.horizon = 3000;
    let a = both(&sys, &cfg);
    assert_eq!(a, both(&sys, &cfg));
    cfg.runs = 20;
    let c = both(&sys, &cfg);
    for (a, c) in a.iter().zip(&c) {
        assert_eq!(&a.cost[..20], &c.cost[..]);
    }
    cfg.seed = 8;
    let d = both(&sys, &cfg);
    for (d, c) in d.iter().zip(&c) {
        assert_ne!(d.cost, c.cost);
    }
}

#[test]
fn a_test_that_never_fires_is_the_online_schedule() {
    let sys = paper();
    let never = Policy::Test {
        detector: Detector::Count {
            lo: -1,
            hi: 1 << 40,
        },
        harmful_at_most: None,
        fallback: 3,
        min_gap: 0,
    };
    let attack = Some(Attack::periodic(1, 5).unwrap());
    let a = both(&sys, &config(attack.clone(), never));
    let b = both(&sys, &config(attack, Policy::Online));
    for (a, b) in a.iter().zip(&b) {
        assert_eq!(a.cost, b.cost);
        assert!(a.tested.iter().all(|&t| t == 20) && a.alarms.iter().all(|&x| x == 0));
    }
}

#[test]
fn a_test_that_always_fires_alternates() {
    // 20 windows: online, 3 offline, online, ... -> 5 online windows, each an alarm.
    let sys = paper();
    let always = Policy::Test {
        detector: Detector::Count {
            lo: 1 << 40,
            hi: 1 << 40,
        },
        harmful_at_most: None,
        fallback: 3,
        min_gap: 0,
    };
    for res in both(&sys, &config(None, always)) {
        assert!(res.tested.iter().all(|&t| t == 5));
        assert!(res.fallbacks.iter().all(|&f| f == 5));
        assert!(res.online.iter().all(|&o| (o - 0.25).abs() < 1e-12));
    }
    // The harmful rule with a bound no count meets: alarms, but no fall-back.
    let harmless = Policy::Test {
        detector: Detector::Count {
            lo: 1 << 40,
            hi: 1 << 40,
        },
        harmful_at_most: Some(-1),
        fallback: 3,
        min_gap: 0,
    };
    for res in both(&sys, &config(None, harmless)) {
        assert!(res.alarms.iter().all(|&a| a == 20) && res.fallbacks.iter().all(|&f| f == 0));
    }
}

#[test]
fn interval_statistic_of_a_window() {
    // One bin holding everything: X² = (N - E)² / E, so an alarm iff |N - E| > sqrt(c E).
    let sys = paper();
    let e = 1000.0 / 7.0;
    let policy = |critical: f64| Policy::Test {
        detector: Detector::Interval {
            edges: vec![1],
            expected: vec![e],
            critical,
        },
        harmful_at_most: None,
        fallback: 0,
        min_gap: 0,
    };
    let mut cfg = config(None, policy(1e9));
    cfg.runs = 64;
    let alarms = |cfg: &GameConfig| both(&sys, cfg).map(|r| r.alarms);
    for a in alarms(&cfg) {
        assert!(a.iter().all(|&a| a == 0));
    }
    cfg.policy = policy(-1.0);
    for a in alarms(&cfg) {
        assert!(a.iter().all(|&a| a == 20));
    }
    // With blocking of every other flag the count halves: far outside sqrt(c E) for c = 9.
    cfg.policy = policy(9.0);
    cfg.attack = Some(Attack::periodic(1, 2).unwrap());
    for a in alarms(&cfg) {
        assert!(a.iter().all(|&a| a == 20));
    }
}

#[test]
fn cancelled_runs_stop() {
    let sys = paper();
    let cancel = AtomicBool::new(true);
    let err = sys
        .simulate_game_with(&config(None, Policy::Online), &cancel, &AtomicU64::new(0))
        .unwrap_err();
    assert_eq!(err, Error::Interrupted);
}

#[test]
fn bad_configs_name_the_field() {
    let sys = paper();
    let mut cfg = config(None, Policy::Online);
    cfg.window = 0;
    assert!(sys
        .simulate_game(&cfg)
        .unwrap_err()
        .to_string()
        .starts_with("window:"));
    let mut cfg = config(None, Policy::Online);
    cfg.runs = 0;
    assert!(sys
        .simulate_game(&cfg)
        .unwrap_err()
        .to_string()
        .starts_with("runs:"));
    let mut cfg = config(None, Policy::Online);
    cfg.offline = vec![1, 2];
    assert!(sys
        .simulate_game(&cfg)
        .unwrap_err()
        .to_string()
        .starts_with("offline:"));
    let cfg = config(
        None,
        Policy::Test {
            detector: Detector::Interval {
                edges: vec![1, 3],
                expected: vec![1.0],
                critical: 1.0,
            },
            harmful_at_most: None,
            fallback: 1,
            min_gap: 0,
        },
    );
    assert!(sys
        .simulate_game(&cfg)
        .unwrap_err()
        .to_string()
        .starts_with("expected:"));
}

/// A count test of 1000-step windows on the paper's example with bounds `half_width` flag-ACKs
/// either side of the attack-free mean count, `fallback` offline windows after any alarm and the
/// support check at `min_gap` (0: none).
pub(super) fn free_count_policy(half_width: f64, fallback: u64, min_gap: u64) -> Policy {
    let design = OnlineDesign::fixed(2).unwrap();
    let free = crate::flag_rates(0.5, design, None).unwrap().delivered * 1000.0;
    Policy::Test {
        detector: Detector::Count {
            lo: (free - half_width) as i64,
            hi: (free + half_width) as i64,
        },
        harmful_at_most: None,
        fallback,
        min_gap,
    }
}

/// An interval test on 5 bins of gaps whose alarms, on the paper's example, are neither rare nor
/// sure (about 73% under injection at γ = 0.05), with `fallback` offline windows after any alarm.
fn interval_policy(fallback: u64) -> Policy {
    Policy::Test {
        detector: Detector::Interval {
            edges: vec![1, 2, 3, 4, 6],
            expected: vec![40.0, 60.0, 80.0, 60.0, 40.0],
            critical: 100.0,
        },
        harmful_at_most: None,
        fallback,
        min_gap: 0,
    }
}

/// `cargo test --release --lib game_speed -- --ignored --nocapture`
#[test]
#[ignore]
fn game_speed() {
    let sys = paper();
    // The policies: online throughout, and the count test (bounds at about 2.6 standard
    // deviations of the attack-free count) and a 5-bin interval test, each with two offline
    // windows after any alarm.
    let count = free_count_policy(40.0, 2, 0);
    let interval = interval_policy(2);
    // The count test with the support check at z0 + 1.
    let mut support = count.clone();
    if let Policy::Test { min_gap, .. } = &mut support {
        *min_gap = 3;
    }
    for (policy_name, policy) in [
        ("online", Policy::Online),
        ("count", count),
        ("count + support", support),
        ("interval", interval),
    ] {
        for (name, attack) in [
            ("none", None),
            ("periodic 1/5", Some(Attack::periodic(1, 5).unwrap())),
            (
                "rate matching",
                Some(Attack::injection(0.0365, Some(Attack::random(0.2).unwrap())).unwrap()),
            ),
        ] {
            let mut cfg = config(attack, policy.clone());
            cfg.runs = 4096;
            cfg.horizon = 100_000;
            cfg.burn_in = 0;
            for (kernel, sliced) in [("bit-sliced", true), ("lanes", false)] {
                let start = std::time::Instant::now();
                simulate_on(
                    &sys,
                    &cfg,
                    &AtomicBool::new(false),
                    &AtomicU64::new(0),
                    sliced,
                )
                .unwrap();
                let s = start.elapsed().as_secs_f64();
                println!(
                    "{policy_name} / {name} ({kernel}): {:.2e} steps/s",
                    (cfg.runs * cfg.horizon) as f64 / s
                );
            }
        }
    }
}

/// Mean and standard error of a per-run count.
fn mean_se_u64(x: &[u64]) -> (f64, f64) {
    mean_se(&x.iter().map(|&v| v as f64).collect::<Vec<_>>())
}

#[test]
fn the_two_kernels_agree_on_testing_policies() {
    // Their random streams differ: every mean within 4.5 combined standard errors. The counts'
    // bounds and the bins make alarms neither rare nor sure, so the fall-backs take part.
    let sys = paper();
    let design = OnlineDesign::fixed(2).unwrap();
    let delivered = |a: Option<&Attack>| crate::flag_rates(0.5, design, a).unwrap().delivered;
    let attack = Attack::periodic(1, 5).unwrap();
    let random = Attack::random(0.1).unwrap();
    let free = delivered(None) * 1000.0;
    let (attacked, random_count) = (
        delivered(Some(&attack)) * 1000.0,
        delivered(Some(&random)) * 1000.0,
    );
    let cases = [
        (
            Some(attack.clone()),
            Policy::Test {
                detector: Detector::Count {
                    lo: attacked as i64,
                    hi: (free + 30.0) as i64,
                },
                harmful_at_most: None,
                fallback: 2,
                min_gap: 0,
            },
        ),
        (
            Some(random),
            Policy::Test {
                detector: Detector::Count {
                    lo: random_count as i64,
                    hi: 1 << 40,
                },
                harmful_at_most: Some(random_count as i64 - 5),
                fallback: 3,
                min_gap: 0,
            },
        ),
        (
            Some(Attack::injection(0.05, None).unwrap()),
            interval_policy(1),
        ),
    ];
    for (attack, policy) in cases {
        let mut cfg = config(attack, policy);
        cfg.runs = 2048;
        let [a, b] = both(&sys, &cfg);
        let close = |what: &str, (m1, s1): (f64, f64), (m2, s2): (f64, f64)| {
            let tol = 4.5 * (s1 * s1 + s2 * s2).sqrt();
            assert!((m1 - m2).abs() <= tol, "{what}: {m1} vs {m2} (± {tol})");
        };
        close("cost", mean_se(&a.cost), mean_se(&b.cost));
        close("online", mean_se(&a.online), mean_se(&b.online));
        close("high", mean_se(&a.high_power), mean_se(&b.high_power));
        close("tested", mean_se_u64(&a.tested), mean_se_u64(&b.tested));
        close("alarms", mean_se_u64(&a.alarms), mean_se_u64(&b.alarms));
        close(
            "fallbacks",
            mean_se_u64(&a.fallbacks),
            mean_se_u64(&b.fallbacks),
        );
        close(
            "delivered",
            mean_se_u64(&a.delivered),
            mean_se_u64(&b.delivered),
        );
        let (alarms, _) = mean_se_u64(&a.alarms);
        let (tested, _) = mean_se_u64(&a.tested);
        assert!(
            alarms > 0.05 * tested && alarms < 0.95 * tested,
            "{alarms} of {tested}"
        );
    }
}
