//! The support check (an alarm at any gap between flag-ACKs reaching the sensor shorter than
//! `min_gap`) on both kernels: invisible without forging, its alarm rate against an explicit
//! recursion over the protocol, and the gaps it reads (across window starts, from the run's
//! start, not the first one after an offline stretch).

use super::super::*;
use super::{both, config, mean_se, paper};

/// A count test that never alarms, with the support check at `min_gap`: the alarms are the
/// support check's.
fn support_only(min_gap: u64, harmful_at_most: Option<i64>, fallback: u64) -> Policy {
    Policy::Test {
        detector: Detector::Count {
            lo: -1,
            hi: 1 << 40,
        },
        harmful_at_most,
        fallback,
        min_gap,
    }
}

/// `policy` with its support check at `gap`.
fn with_gap(mut policy: Policy, gap: u64) -> Policy {
    if let Policy::Test { min_gap, .. } = &mut policy {
        *min_gap = gap;
    }
    policy
}

/// The results on the kernel `sliced` (the lane kernel takes every plan).
fn on(sys: &LinearSystem, cfg: &GameConfig, sliced: bool) -> GameRuns {
    simulate_on(
        sys,
        cfg,
        &AtomicBool::new(false),
        &AtomicU64::new(0),
        sliced,
    )
    .unwrap()
}

/// Without forging no gap is shorter than the attack-free minimum, z0 + 1 (z0 + 2 at μ = 0):
/// with the check at that minimum the runs are those without it, bit for bit, on both kernels,
/// for policies whose alarms and fall-backs (so returns from offline stretches, where the
/// offline schedule allows gaps of z0) are neither rare nor sure, also under blocking.
#[test]
fn without_forging_the_check_changes_nothing() {
    let sys = paper();
    let design = |mu| OnlineDesign::new(2, mu).unwrap();
    let count = |mu: f64, attack: Option<&Attack>| {
        let n = crate::flag_rates(0.5, design(mu), attack)
            .unwrap()
            .delivered
            * 1000.0;
        Policy::Test {
            detector: Detector::Count {
                lo: (n - 8.0) as i64,
                hi: (n + 8.0) as i64,
            },
            harmful_at_most: None,
            fallback: 2,
            min_gap: 0,
        }
    };
    let interval = Policy::Test {
        // Gaps of 3, of 4 or 5, and of 6 or more have probabilities 1/4, 1/4 and 1/2 (none is
        // shorter), with about 143 flag-ACKs per window.
        detector: Detector::Interval {
            edges: vec![1, 3, 4, 6],
            expected: vec![0.5, 35.7, 35.7, 71.4],
            critical: 4.0,
        },
        harmful_at_most: Some(140),
        fallback: 1,
        min_gap: 0,
    };
    let periodic = Attack::periodic(1, 5).unwrap();
    let random = Attack::random(0.2).unwrap();
    let cases = [
        (1.0, None, count(1.0, None), 3),
        (0.4, None, count(0.4, None), 3),
        (0.0, None, count(0.0, None), 4),
        (1.0, Some(periodic.clone()), count(1.0, Some(&periodic)), 3),
        (0.4, Some(random.clone()), count(0.4, Some(&random)), 3),
        (1.0, None, interval.clone(), 3),
        (1.0, Some(random), interval, 3),
    ];
    for (mu, attack, policy, min_gap) in cases {
        let mut cfg = config(attack.clone(), policy.clone());
        (cfg.design, cfg.runs, cfg.horizon) = (design(mu), 300, 12_000);
        let [a, b] = both(&sys, &cfg);
        cfg.policy = with_gap(policy, min_gap);
        let [c, d] = both(&sys, &cfg);
        let what = format!("μ = {mu}, {attack:?}");
        assert!(a == c && b == d, "{what}: the check changed the runs");
        // The case has fall-backs, and alarms that are not sure.
        let sum = |v: &[u64]| v.iter().sum::<u64>();
        for r in [&a, &b] {
            let (tested, alarms) = (sum(&r.tested), sum(&r.alarms));
            assert!(
                sum(&r.fallbacks) > 0 && alarms < tested,
                "{what}: {alarms} of {tested}"
            );
        }
        // One step below the minimum the check would alarm at every attack-free gap (the
        // gaps are z0 + 1 or longer, and z0 + 1 is the most frequent), so it is not vacuous.
        cfg.policy = with_gap(cfg.policy, min_gap + 1);
        for r in both(&sys, &cfg) {
            assert!(
                sum(&r.alarms) > sum(&a.alarms),
                "{what}: a check one step longer"
            );
        }
    }
}

/// A channel as the recursion takes it: `P`, `low`, `high`, and the stationary law of `P`.
struct Chan {
    p: Vec<Vec<f64>>,
    low: Vec<f64>,
    high: Vec<f64>,
}

/// The state between two steps: the coming channel state, the zero count, whether the last step
/// sent a flag (which reset the memory), whether a flag-ACK reached the sensor on it (high
/// power now), and the steps since the last one that did, capped at `min_gap` - 1.
type State = (usize, usize, bool, bool, usize);

/// P(a flag-ACK reaches the sensor fewer than `min_gap` steps after the previous one in a
/// window of `n` steps) in the stationary regime, for the online schedule (z0, μ) under forging
/// with probability γ on every step without a genuine flag: the protocol written out as a
/// Markov chain over [`State`], run from the paper's initial condition until it settles, then
/// through the window with the short gaps absorbing.
fn short_gap_probability(
    ch: &Chan,
    (z0, mu): (usize, f64),
    gamma: f64,
    min_gap: usize,
    n: usize,
) -> f64 {
    use std::collections::HashMap;
    let k = ch.p.len();
    // The step from one state: (probability, next state, short gap).
    let step = |&(c, z, flagged, pending, age): &State| -> Vec<(f64, State, bool)> {
        let mut out = Vec::new();
        let a = if pending { ch.high[c] } else { ch.low[c] };
        for (pa, arrive) in [(a, true), (1.0 - a, false)] {
            // An arrival empties the memory; else one more zero, counted from a fresh memory
            // after a flag.
            let z = if arrive {
                0
            } else if flagged {
                1
            } else {
                z + 1
            };
            let p_flag = if z > z0 {
                1.0
            } else if z == z0 {
                mu
            } else {
                0.0
            };
            for (pf, flag) in [(p_flag, true), (1.0 - p_flag, false)] {
                let p_deliver = if flag { 1.0 } else { gamma };
                for (pd, delivered) in [(p_deliver, true), (1.0 - p_deliver, false)] {
                    let short = delivered && age + 1 < min_gap;
                    let age = if delivered {
                        0
                    } else {
                        (age + 1).min(min_gap - 1)
                    };
                    for (c2, &pc) in ch.p[c].iter().enumerate() {
                        let w = pa * pf * pd * pc;
                        if w > 0.0 {
                            out.push((w, (c2, z, flag, delivered, age), short));
                        }
                    }
                }
            }
        }
        out
    };
    let advance = |law: &HashMap<State, f64>, absorb: bool| {
        let mut next = HashMap::new();
        let mut lost = 0.0;
        for (s, &m) in law {
            for (w, t, short) in step(s) {
                if absorb && short {
                    lost += m * w;
                } else {
                    *next.entry(t).or_insert(0.0) += m * w;
                }
            }
        }
        (next, lost)
    };
    // The stationary law of the channel by power iteration, then the paper's start: high power
    // at k = 1, memory empty, the last flag-ACK at step 0.
    let mut pi = vec![1.0 / k as f64; k];
    for _ in 0..10_000 {
        pi = (0..k)
            .map(|j| (0..k).map(|i| pi[i] * ch.p[i][j]).sum())
            .collect();
    }
    let mut law: HashMap<State, f64> = (0..k).map(|c| ((c, 0, false, true, 0), pi[c])).collect();
    for _ in 0..3000 {
        law = advance(&law, false).0;
    }
    let mut alarm = 0.0;
    for _ in 0..n {
        let (next, lost) = advance(&law, true);
        (law, alarm) = (next, alarm + lost);
    }
    alarm
}

/// The simulated fraction of tested windows with a short gap (each run's fraction, so the
/// standard error allows for windows of one run being dependent), and its standard error.
fn alarm_fraction(res: &GameRuns) -> (f64, f64) {
    let f: Vec<f64> = res
        .alarms
        .iter()
        .zip(&res.tested)
        .map(|(&a, &t)| a as f64 / t as f64)
        .collect();
    mean_se(&f)
}

/// The check at 3 = z0 + 1 against a forger of probability γ, on the paper's channel (both
/// kernels) and on a Gilbert-Elliott channel (the lane kernel): within 4 standard errors of the
/// recursion, on windows after a burn-in of two windows.
#[test]
fn the_short_gap_rate_is_the_protocols() {
    let sys = paper();
    let iid = Chan {
        p: vec![vec![1.0]],
        low: vec![0.5],
        high: vec![1.0],
    };
    let ge = super::channel::gilbert_elliott();
    let bursty = Chan {
        p: ge.p.clone(),
        low: ge.low.clone(),
        high: ge.high.clone(),
    };
    for (gamma, n, markov) in [
        (0.0005, 1000, false),
        (0.002, 200, false),
        (0.002, 200, true),
        (0.0005, 1000, true),
    ] {
        let attack = Attack::injection(gamma, None).unwrap();
        let mut cfg = config(Some(attack), support_only(3, None, 0));
        (cfg.window, cfg.burn_in, cfg.horizon, cfg.runs) = (n, 2 * n, 10 * n, 1024);
        let ch = if markov {
            cfg.channel = Some(ge.clone());
            &bursty
        } else {
            &iid
        };
        let exact = short_gap_probability(ch, (2, 1.0), gamma, 3, n as usize);
        assert!(0.05 < exact && exact < 0.95, "{exact}");
        for sliced in if markov {
            vec![false]
        } else {
            vec![true, false]
        } {
            let res = on(&sys, &cfg, sliced);
            assert!(res.tested.iter().all(|&t| t == 10));
            let (m, se) = alarm_fraction(&res);
            println!("γ = {gamma}, n = {n}, markov {markov}, sliced {sliced}: {m:.4} ± {se:.4}, exact {exact:.4}");
            assert!(
                (m - exact).abs() < 4.0 * se,
                "γ = {gamma}, n = {n}, markov {markov}, sliced {sliced}: {m} ± {se} vs {exact}"
            );
        }
    }
}

/// The recursion against hand computations: without forging no short gap; a forger that always
/// forges delivers on every step, so every window of one step has a gap of 1.
#[test]
fn the_recursion_checks_by_hand() {
    let iid = Chan {
        p: vec![vec![1.0]],
        low: vec![0.5],
        high: vec![1.0],
    };
    assert_eq!(short_gap_probability(&iid, (2, 1.0), 0.0, 3, 100), 0.0);
    assert!((short_gap_probability(&iid, (2, 1.0), 1.0, 2, 1) - 1.0).abs() < 1e-12);
    // One step, the check at z0 + 1 = 3, a small γ: a forgery at age 0 or 1 (one or two steps
    // after a delivery). Stationary, age 0 has the delivery rate d = 1/7 + O(γ) and age 1
    // (no flag can follow a delivery at once) has d too: about 2 d γ.
    let gamma = 1e-6;
    let p = short_gap_probability(&iid, (2, 1.0), gamma, 3, 1);
    assert!((p / (2.0 * gamma / 7.0) - 1.0).abs() < 1e-4, "{p}");
}

/// γ = 1 delivers a flag-ACK on every step (a forgery where the detector sends none): with
/// windows of one step every gap straddles a window's start, and the run's start counts as a
/// flag-ACK at step 0, so the first window alarms too; after an offline window the first gap is
/// not checked. Deterministic, so both kernels give these counts exactly.
#[test]
fn the_gaps_across_window_starts_count() {
    let sys = paper();
    let attack = Attack::injection(1.0, None).unwrap();
    let mut cfg = config(Some(attack), support_only(2, None, 0));
    (cfg.window, cfg.horizon, cfg.burn_in, cfg.runs) = (1, 30, 0, 20);
    let all = |v: &[u64], x: u64| v.iter().all(|&y| y == x);
    for sliced in [true, false] {
        let res = on(&sys, &cfg, sliced);
        assert!(all(&res.tested, 30) && all(&res.alarms, 30) && all(&res.fallbacks, 30));
    }
    // One offline window after each alarm: windows 1 (alarm), 2 off, 3 (not checked), 4
    // (alarm), 5 off, ...: of 30 windows, 20 tested and 10 alarms.
    cfg.policy = support_only(2, None, 1);
    for sliced in [true, false] {
        let res = on(&sys, &cfg, sliced);
        assert!(all(&res.tested, 20) && all(&res.alarms, 10) && all(&res.fallbacks, 10));
        assert!(res.online.iter().all(|&o| (o - 20.0 / 30.0).abs() < 1e-12));
    }
    // The harmful rule: a window's count is 1, so a bound of 0 lets no alarm trigger.
    cfg.policy = support_only(2, Some(0), 1);
    for sliced in [true, false] {
        let res = on(&sys, &cfg, sliced);
        assert!(all(&res.tested, 30) && all(&res.alarms, 30) && all(&res.fallbacks, 0));
    }
    // 0 and 1 are no check.
    for gap in [0, 1] {
        cfg.policy = support_only(gap, None, 1);
        for sliced in [true, false] {
            assert!(all(&on(&sys, &cfg, sliced).alarms, 0));
        }
    }
}

/// The run's start counts as a flag-ACK at step 0. Without attack (z0 = 2, λ = 1/2) the first
/// flag-ACK comes at step 3 at the earliest (step 1 is at high power, so its packet arrives,
/// and the flag needs losses at steps 2 and 3, probability 1/4): a window of the first 4 steps
/// has one flag-ACK at most, and a gap from step 0 of 3 at least, which a check at 3 never
/// finds short and a check at 4 finds short with probability 1/4.
#[test]
fn the_runs_start_counts_as_a_flag_ack() {
    let sys = paper();
    let mut cfg = config(None, support_only(3, None, 0));
    (cfg.window, cfg.horizon, cfg.burn_in, cfg.runs) = (4, 4, 0, 4096);
    for sliced in [true, false] {
        assert!(on(&sys, &cfg, sliced).alarms.iter().all(|&a| a == 0));
    }
    cfg.policy = support_only(4, None, 0);
    for sliced in [true, false] {
        let res = on(&sys, &cfg, sliced);
        let (m, se) = mean_se_u64(&res.alarms);
        assert!((m - 0.25).abs() < 4.0 * se, "sliced {sliced}: {m} ± {se}");
    }
}

fn mean_se_u64(x: &[u64]) -> (f64, f64) {
    mean_se(&x.iter().map(|&v| v as f64).collect::<Vec<_>>())
}

/// The check goes to the lane kernel when `min_gap` exceeds the sliced kernel's gap thermometer,
/// and is refused beyond the longest run.
#[test]
fn plans_and_validation() {
    let sys = paper();
    let fits = |gap| {
        let cfg = config(None, support_only(gap, None, 1));
        sliced::Sliced::of(&plan::Plan::new(&sys, &cfg).unwrap()).is_some()
    };
    assert!(fits(0) && fits(3) && fits(64));
    assert!(!fits(65));
    let mut cfg = config(None, support_only(MAX_STEPS + 1, None, 1));
    (cfg.runs, cfg.horizon, cfg.burn_in) = (8, 3000, 0);
    let e = sys.simulate_game(&cfg).unwrap_err().to_string();
    assert!(e.starts_with("min_gap:"), "{e}");
    // Every gap is short: every online window alarms.
    cfg.policy = support_only(MAX_STEPS, None, 1);
    let res = sys.simulate_game(&cfg).unwrap();
    assert_eq!(res.alarms, res.tested);
}
