//! The closed loop against the exact stationary costs, determinism, the policies' switching, and
//! (ignored) its speed.

use super::*;
use crate::schedules::{offline_schedule, Ratio};

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

fn config(attack: Option<Attack>, policy: Policy) -> GameConfig {
    GameConfig {
        lam: 0.5,
        design: OnlineDesign::fixed(2).unwrap(),
        offline: offline_schedule(Ratio::new(1, 7).unwrap()).unwrap(),
        attack,
        policy,
        window: 1000,
        horizon: 20_000,
        burn_in: 1000,
        runs: 512,
        seed: 7,
    }
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
        let res = sys
            .simulate_game(&config(attack.clone(), Policy::Online))
            .unwrap();
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

#[test]
fn offline_matches_the_offline_cost() {
    let sys = paper();
    let res = sys
        .simulate_game(&config(
            Some(Attack::periodic(2, 3).unwrap()),
            Policy::Offline,
        ))
        .unwrap();
    let (j, se) = mean_se(&res.cost);
    let exact = sys.j_offline(0.5, Ratio::new(1, 7).unwrap()).unwrap();
    assert!((j - exact).abs() < 4.0 * se, "{j} ± {se} vs {exact}");
    assert!(res.high_power.iter().all(|&h| (h - 1.0 / 7.0).abs() < 1e-3));
    assert!(res.online.iter().all(|&o| o == 0.0));
}

#[test]
fn results_depend_on_the_seed_and_the_run_only() {
    let sys = paper();
    let mut cfg = config(Some(Attack::random(0.3).unwrap()), Policy::Online);
    cfg.runs = 37;
    cfg.horizon = 3000;
    let a = sys.simulate_game(&cfg).unwrap();
    let b = sys.simulate_game(&cfg).unwrap();
    assert_eq!(a, b);
    cfg.runs = 20;
    let c = sys.simulate_game(&cfg).unwrap();
    assert_eq!(&a.cost[..20], &c.cost[..]);
    cfg.seed = 8;
    assert_ne!(sys.simulate_game(&cfg).unwrap().cost, c.cost);
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
    };
    let attack = Some(Attack::periodic(1, 5).unwrap());
    let a = sys.simulate_game(&config(attack.clone(), never)).unwrap();
    let b = sys.simulate_game(&config(attack, Policy::Online)).unwrap();
    assert_eq!(a.cost, b.cost);
    assert!(a.tested.iter().all(|&t| t == 20) && a.alarms.iter().all(|&x| x == 0));
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
    };
    let res = sys.simulate_game(&config(None, always)).unwrap();
    assert!(res.tested.iter().all(|&t| t == 5));
    assert!(res.fallbacks.iter().all(|&f| f == 5));
    assert!(res.online.iter().all(|&o| (o - 0.25).abs() < 1e-12));
    // The harmful rule with a bound no count meets: alarms, but no fall-back.
    let harmless = Policy::Test {
        detector: Detector::Count {
            lo: 1 << 40,
            hi: 1 << 40,
        },
        harmful_at_most: Some(-1),
        fallback: 3,
    };
    let res = sys.simulate_game(&config(None, harmless)).unwrap();
    assert!(res.alarms.iter().all(|&a| a == 20) && res.fallbacks.iter().all(|&f| f == 0));
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
    };
    let mut cfg = config(None, policy(1e9));
    cfg.runs = 64;
    assert!(sys
        .simulate_game(&cfg)
        .unwrap()
        .alarms
        .iter()
        .all(|&a| a == 0));
    cfg.policy = policy(-1.0);
    assert!(sys
        .simulate_game(&cfg)
        .unwrap()
        .alarms
        .iter()
        .all(|&a| a == 20));
    // With blocking of every other flag the count halves: far outside sqrt(c E) for c = 9.
    cfg.policy = policy(9.0);
    cfg.attack = Some(Attack::periodic(1, 2).unwrap());
    assert!(sys
        .simulate_game(&cfg)
        .unwrap()
        .alarms
        .iter()
        .all(|&a| a == 20));
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
    cfg.offline = vec![0, 1];
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
        },
    );
    assert!(sys
        .simulate_game(&cfg)
        .unwrap_err()
        .to_string()
        .starts_with("expected:"));
}

/// `cargo test --release --lib game_speed -- --ignored --nocapture`
#[test]
#[ignore]
fn game_speed() {
    let sys = paper();
    for (name, attack) in [
        ("none", None),
        ("periodic 1/5", Some(Attack::periodic(1, 5).unwrap())),
        (
            "rate matching",
            Some(Attack::injection(0.0365, Some(Attack::random(0.2).unwrap())).unwrap()),
        ),
    ] {
        let mut cfg = config(attack, Policy::Online);
        cfg.runs = 4096;
        cfg.horizon = 100_000;
        cfg.burn_in = 0;
        let start = std::time::Instant::now();
        sys.simulate_game(&cfg).unwrap();
        let s = start.elapsed().as_secs_f64();
        println!(
            "{name}: {:.2e} steps/s",
            (cfg.runs * cfg.horizon) as f64 / s
        );
    }
}
