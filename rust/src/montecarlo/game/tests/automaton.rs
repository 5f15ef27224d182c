//! Attacker automata in the closed loop (the lane kernel): a built-in attack written as an
//! automaton plays as the built-in one, mimicry delivers the attack-free flag law, and
//! deterministic automata give counts derived by hand.

use super::super::*;
use super::{config, free_count_policy, mean_se, paper};
use crate::engine::{Attacker, Engine, Move, PowerSchedule, DEFAULT_MAX_STATES};

/// Mean and standard error of a per-run count.
fn mean_se_u64(x: &[u64]) -> (f64, f64) {
    mean_se(&x.iter().map(|&v| v as f64).collect::<Vec<_>>())
}

/// `cfg` with `automaton` in place of its attack.
fn with_automaton(mut cfg: GameConfig, automaton: AttackerAutomaton) -> GameConfig {
    cfg.attack = None;
    cfg.automaton = Some(automaton);
    cfg
}

/// The results on the kernel the plan chooses, checked to count every run in `progress`.
fn run(sys: &LinearSystem, cfg: &GameConfig) -> GameRuns {
    let progress = AtomicU64::new(0);
    let out = simulate_on(sys, cfg, &AtomicBool::new(false), &progress, true).unwrap();
    assert_eq!(progress.into_inner(), cfg.runs);
    out
}

/// Every per-run mean of `a` and `b` within 4 combined standard errors.
fn same_means(what: &str, a: &GameRuns, b: &GameRuns) {
    let close = |name: &str, (m1, s1): (f64, f64), (m2, s2): (f64, f64)| {
        let tol = 4.0 * (s1 * s1 + s2 * s2).sqrt();
        assert!(
            (m1 - m2).abs() <= tol,
            "{what}, {name}: {m1} vs {m2} (± {tol})"
        );
    };
    close("cost", mean_se(&a.cost), mean_se(&b.cost));
    close("high", mean_se(&a.high_power), mean_se(&b.high_power));
    close("online", mean_se(&a.online), mean_se(&b.online));
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
}

/// A count test whose alarms are neither rare nor sure under `attack`: bounds at the attacked
/// and the attack-free mean counts of a 1000-step window, two offline windows after an alarm.
fn count_policy(attack: Option<&Attack>, min_gap: u64) -> Policy {
    let design = OnlineDesign::fixed(2).unwrap();
    let delivered = |a: Option<&Attack>| crate::flag_rates(0.5, design, a).unwrap().delivered;
    let (attacked, free) = (delivered(attack) * 1000.0, delivered(None) * 1000.0);
    Policy::Test {
        detector: Detector::Count {
            lo: attacked.min(free - 10.0) as i64,
            hi: (free + 25.0) as i64,
        },
        harmful_at_most: None,
        fallback: 2,
        min_gap,
    }
}

#[test]
fn a_built_in_attack_as_an_automaton_plays_as_the_built_in_one() {
    // The built-in attack on the bit-sliced kernel, its automaton on the lane kernel: different
    // streams, the same law. The test's fall-backs and the support check take part, and the
    // attacker keeps counting flags through the offline windows in both.
    let sys = paper();
    let inject = |gamma| Attack::injection(gamma, Some(Attack::random(0.2).unwrap())).unwrap();
    // Rate matching, and (with the support check) forgeries rare enough that not every window
    // has a short gap.
    let cases = [
        (Attack::periodic(1, 5).unwrap(), 0),
        (
            Attack::mask(vec![true, false, true, true, false]).unwrap(),
            0,
        ),
        (inject(0.04), 0),
        (inject(0.003), 3),
    ];
    for (attack, min_gap) in cases {
        let mut cfg = config(Some(attack.clone()), count_policy(Some(&attack), min_gap));
        cfg.runs = 1024;
        let automaton = AttackerAutomaton::from_attack(&attack, 1).unwrap();
        let auto = with_automaton(cfg.clone(), automaton);
        let plan = Plan::new(&sys, &auto).unwrap();
        assert!(
            Sliced::of(&plan).is_none(),
            "an automaton runs on the lanes"
        );
        let (a, b) = (run(&sys, &cfg), run(&sys, &auto));
        same_means(&format!("{attack:?}, min_gap {min_gap}"), &a, &b);
        let (alarms, _) = mean_se_u64(&b.alarms);
        let (tested, _) = mean_se_u64(&b.tested);
        assert!(
            alarms > 0.05 * tested && alarms < 0.95 * tested,
            "{attack:?}: {alarms} of {tested}"
        );
    }
}

#[test]
fn an_automaton_online_matches_the_exact_engine() {
    // Never tested: J and the high-power rate are the exact engine's stationary values under
    // the same automaton (a Markov channel included, where the lane kernel draws the channel
    // after the attacker).
    let sys = paper();
    let design = OnlineDesign::fixed(2).unwrap();
    let mimicry = |ch: &Channel| AttackerAutomaton::mimicry(ch, design).unwrap();
    let ge = MarkovChannel {
        p: vec![vec![0.9, 0.1], vec![0.3, 0.7]],
        low: vec![0.7, 0.2],
        high: vec![1.0, 0.8],
    };
    let ge_engine = Channel::markov(ge.p.clone(), ge.low.clone(), ge.high.clone()).unwrap();
    let iid = Channel::bernoulli(0.5).unwrap();
    let cases = [
        (
            None,
            &iid,
            AttackerAutomaton::from_attack(&Attack::periodic(1, 5).unwrap(), 1).unwrap(),
        ),
        (
            None,
            &iid,
            AttackerAutomaton::from_attack(&Attack::injection(0.05, None).unwrap(), 3).unwrap(),
        ),
        (None, &iid, mimicry(&iid)),
        (Some(ge.clone()), &ge_engine, mimicry(&ge_engine)),
    ];
    for (channel, engine_channel, automaton) in cases {
        let mut cfg = with_automaton(config(None, Policy::Online), automaton.clone());
        cfg.channel = channel;
        cfg.runs = 512;
        let res = run(&sys, &cfg);
        let engine = Engine::new(
            engine_channel,
            &PowerSchedule::Online(design),
            &Attacker::Automaton(automaton),
            DEFAULT_MAX_STATES,
        )
        .unwrap();
        let (j, se) = mean_se(&res.cost);
        let exact = engine.cost(&sys).unwrap();
        assert!((j - exact).abs() < 4.0 * se, "J {j} ± {se} vs {exact}");
        let (hp, se_hp) = mean_se(&res.high_power);
        let rate = engine.flag_rates().unwrap().delivered;
        assert!(
            (hp - rate).abs() < 4.0 * se_hp + 1e-4,
            "high power {hp} ± {se_hp} vs {rate}"
        );
    }
}

#[test]
fn mimicry_gives_the_attack_free_alarms() {
    // The sensor sees the attack-free flag law, so the count test alarms as without attack (no
    // fall-back: every window is tested), and the support check never fires; the cost is not
    // the attack-free one (the real losses go unflagged).
    let sys = paper();
    let design = OnlineDesign::fixed(2).unwrap();
    let policy = free_count_policy(15.0, 0, 3);
    let mimicry = AttackerAutomaton::mimicry(&Channel::bernoulli(0.5).unwrap(), design).unwrap();
    let mut cfg = config(None, policy);
    cfg.runs = 1024;
    let auto = with_automaton(cfg.clone(), mimicry);
    let (clean, attacked) = (run(&sys, &cfg), run(&sys, &auto));
    for what in ["alarms", "delivered"] {
        let pick = |r: &GameRuns| {
            mean_se_u64(if what == "alarms" {
                &r.alarms
            } else {
                &r.delivered
            })
        };
        let ((m1, s1), (m2, s2)) = (pick(&clean), pick(&attacked));
        let tol = 4.0 * (s1 * s1 + s2 * s2).sqrt();
        assert!((m1 - m2).abs() <= tol, "{what}: {m1} vs {m2} (± {tol})");
    }
    let (alarms, _) = mean_se_u64(&attacked.alarms);
    assert!(alarms > 1.0 && alarms < 19.0, "{alarms} alarms of 20");
    // The support check alone, with the count test switched off: no gap is short.
    cfg.policy = Policy::Test {
        detector: Detector::Count {
            lo: -1,
            hi: 1 << 40,
        },
        harmful_at_most: None,
        fallback: 0,
        min_gap: 3,
    };
    let auto = with_automaton(cfg, auto.automaton.unwrap());
    assert!(run(&sys, &auto).alarms.iter().all(|&a| a == 0));
    let (j, se) = mean_se(&attacked.cost);
    let j_free = sys.j_online(0.5, design).unwrap();
    assert!(j - j_free > 10.0 * se, "{j} ± {se} vs attack-free {j_free}");
}

/// One state that delivers on a flag step iff `pass` and on a quiet step iff `forge`.
fn constant(pass: bool, forge: bool) -> AttackerAutomaton {
    let mv = |deliver| {
        vec![vec![Move {
            p: 1.0,
            deliver,
            next: 0,
        }]]
    };
    AttackerAutomaton::new(mv(pass), mv(forge), 0).unwrap()
}

#[test]
fn blocking_every_flag_alternates_by_hand() {
    // No flag-ACK ever reaches the sensor: every online window counts N = 0 <= lo and alarms;
    // 20 windows of 1000 steps, 3 offline after each alarm: online in windows 0, 4, 8, 12, 16.
    // High power: step 1 (the initial condition) and, in each of the five offline stretches of
    // 3000 steps, which start the period afresh, 3000 / 7 = 428 periods and the first 4 steps.
    let sys = paper();
    let policy = Policy::Test {
        detector: Detector::Count { lo: 0, hi: 1 << 40 },
        harmful_at_most: None,
        fallback: 3,
        min_gap: 3,
    };
    let mut cfg = with_automaton(config(None, policy), constant(false, false));
    cfg.burn_in = 0;
    cfg.runs = 19;
    let ones = |p: &[u8]| p.iter().map(|&g| u64::from(g)).sum::<u64>();
    let per_stretch = 428 * ones(&cfg.offline) + ones(&cfg.offline[..4]);
    let high = (1 + 5 * per_stretch) as f64 / 20_000.0;
    let res = run(&sys, &cfg);
    for l in 0..19 {
        assert_eq!((res.tested[l], res.alarms[l], res.fallbacks[l]), (5, 5, 5));
        assert_eq!(res.delivered[l], 0);
        assert!((res.online[l] - 0.25).abs() < 1e-12);
        assert!(
            (res.high_power[l] - high).abs() < 1e-12,
            "{}",
            res.high_power[l]
        );
    }
}

#[test]
fn forging_at_every_quiet_step_keeps_the_power_high() {
    // Every step delivers a flag-ACK (genuine or forged): high power throughout, where a packet
    // always arrives, so τ = 0 and Tr P_k = Tr P̄ at every step, and every gap is 1: with the
    // support check at 3 every window alarms (the first one too: the run's start counts as a
    // flag-ACK at step 0).
    let sys = paper();
    let tr = sys.h_traces(0)[0];
    let policy = Policy::Test {
        detector: Detector::Count {
            lo: -1,
            hi: 1 << 40,
        },
        harmful_at_most: None,
        fallback: 0,
        min_gap: 3,
    };
    let mut cfg = with_automaton(config(None, policy), constant(true, true));
    cfg.runs = 9;
    let res = run(&sys, &cfg);
    for l in 0..9 {
        assert!(
            (res.cost[l] - tr).abs() <= 1e-12 * tr,
            "{} vs {tr}",
            res.cost[l]
        );
        assert_eq!(res.high_power[l], 1.0);
        assert_eq!(res.delivered[l], 20_000);
        // 21 windows (the burn-in's included), 20 of them after it.
        assert_eq!((res.tested[l], res.alarms[l]), (20, 20));
    }
}

#[test]
fn automaton_runs_depend_on_the_seed_and_the_run_only() {
    let sys = paper();
    let design = OnlineDesign::fixed(2).unwrap();
    let mimicry = AttackerAutomaton::mimicry(&Channel::bernoulli(0.5).unwrap(), design).unwrap();
    let mut cfg = with_automaton(config(None, count_policy(None, 3)), mimicry);
    cfg.runs = 37;
    cfg.horizon = 3000;
    let a = run(&sys, &cfg);
    assert_eq!(a, run(&sys, &cfg));
    cfg.runs = 20;
    assert_eq!(&a.cost[..20], &run(&sys, &cfg).cost[..]);
    cfg.seed += 1;
    assert_ne!(&a.cost[..20], &run(&sys, &cfg).cost[..]);
}

#[test]
fn an_attack_and_an_automaton_together_are_refused() {
    let sys = paper();
    let mut cfg = config(Some(Attack::periodic(1, 5).unwrap()), Policy::Online);
    cfg.automaton = Some(constant(true, false));
    let err = sys.simulate_game(&cfg).unwrap_err().to_string();
    assert!(err.starts_with("automaton:"), "{err}");
}

/// The lane kernel's speed under the built-in attacks and under automata (the paper's example,
/// the count test with two offline windows after an alarm, 4096 runs of 10^5 steps, median and
/// best of 7): `cargo test --release --lib lane_speed -- --ignored --nocapture`.
#[test]
#[ignore]
fn lane_speed() {
    let sys = paper();
    let design = OnlineDesign::fixed(2).unwrap();
    let count = free_count_policy(40.0, 2, 0);
    let periodic = Attack::periodic(1, 5).unwrap();
    let rate_matching = Attack::injection(0.0365, Some(Attack::random(0.2).unwrap())).unwrap();
    let auto = |a: &Attack| Some(AttackerAutomaton::from_attack(a, 1).unwrap());
    let mimicry = AttackerAutomaton::mimicry(&Channel::bernoulli(0.5).unwrap(), design).unwrap();
    for (name, attack, automaton) in [
        ("none", None, None),
        ("periodic 1/5", Some(periodic.clone()), None),
        ("rate matching", Some(rate_matching.clone()), None),
        ("automaton periodic 1/5", None, auto(&periodic)),
        ("automaton rate matching", None, auto(&rate_matching)),
        ("automaton mimicry", None, Some(mimicry)),
    ] {
        let mut cfg = config(attack, count.clone());
        cfg.automaton = automaton;
        cfg.runs = 4096;
        cfg.horizon = 100_000;
        cfg.burn_in = 0;
        let mut rates = Vec::new();
        for _ in 0..7 {
            let start = std::time::Instant::now();
            simulate_on(
                &sys,
                &cfg,
                &AtomicBool::new(false),
                &AtomicU64::new(0),
                false,
            )
            .unwrap();
            rates.push((cfg.runs * cfg.horizon) as f64 / start.elapsed().as_secs_f64());
        }
        rates.sort_by(f64::total_cmp);
        println!(
            "lanes {name}: median {:.3e} best {:.3e} steps/s",
            rates[3], rates[6]
        );
    }
}
