//! The CUSUM policy: alarm counts derived by hand on a deterministic protocol, a statistic that
//! never alarms plays the online schedule bit for bit, and the alarm rate against a plain
//! simulation of the protocol's rules.

use super::super::*;
use super::{config, paper};
use crate::montecarlo::rng::SplitMix64;

const INF: f64 = f64::INFINITY;

fn cusum(inc_flag: &[f64], inc_quiet: &[f64], threshold: f64, fallback: u64) -> Policy {
    Policy::Cusum {
        inc_flag: inc_flag.to_vec(),
        inc_quiet: inc_quiet.to_vec(),
        threshold,
        fallback,
    }
}

/// The lane kernel's results (and the plan's kernel is the lane one).
fn lanes(sys: &LinearSystem, cfg: &GameConfig) -> GameRuns {
    simulate_on(sys, cfg, &AtomicBool::new(false), &AtomicU64::new(0), false).unwrap()
}

/// A protocol without chance: one channel state where high power always arrives and low power
/// never does, z0 = 2 and μ = 1, no attack. Online, a flag-ACK reaches the sensor every third
/// step (steps 3, 6, ... from the initial condition: high power, then two losses); offline at
/// high power every packet arrives and no flag is sent, offline at low power a flag goes out at
/// z = 2 and the loss after it makes z = 1, so one every second step.
pub(super) fn deterministic(
    policy: Policy,
    offline: Vec<u8>,
    window: u64,
    horizon: u64,
) -> GameConfig {
    let mut cfg = config(None, policy);
    cfg.channel = Some(MarkovChannel {
        p: vec![vec![1.0]],
        low: vec![0.0],
        high: vec![1.0],
    });
    cfg.offline = offline;
    cfg.window = window;
    cfg.horizon = horizon;
    cfg.burn_in = 0;
    cfg.runs = 10;
    cfg
}

/// Every run's (alarms, steps the statistic ran, online steps, delivered flag-ACKs, high-power
/// steps) equals `want`.
fn check(what: &str, cfg: &GameConfig, want: [u64; 5]) {
    let res = lanes(&paper(), cfg);
    let h = cfg.horizon as f64;
    for r in 0..cfg.runs as usize {
        let got = [
            res.alarms[r],
            res.tested[r],
            res.online_steps[r],
            res.delivered[r],
            (res.high_power[r] * h).round() as u64,
        ];
        assert_eq!(got, want, "{what}, run {r}");
        assert_eq!(
            res.fallbacks[r], res.alarms[r],
            "{what}: every alarm falls back"
        );
        assert_eq!(res.online[r], res.online_steps[r] as f64 / h, "{what}");
    }
}

#[test]
fn alarm_counts_derived_by_hand() {
    // A flag-ACK alarms (inc_flag = +inf): the first at step 3; offline (all high) for 1 window
    // of 4 steps, 4..7, where no flag is sent; online at 8 (low power: no flag-ACK at 7),
    // dormant, a flag-ACK at 9 restarts the statistic, the next (12) alarms. Alarms at 3, 12, 21,
    // 30; the statistic runs at 1-3, 10-12, 19-21, 28-30; online 1-3, 8-12, 17-21, 26-30 (18);
    // flag-ACKs at 3, 9, 12, 18, 21, 27, 30; high power at 1, 10, 19, 28 and the 12 offline
    // steps.
    let policy = cusum(&[INF], &[-INF], 1.0, 1);
    check(
        "flag alarms",
        &deterministic(policy, vec![1], 4, 30),
        [4, 12, 18, 7, 16],
    );

    // Without fall-back (0 windows) the sensor stays online: alarms at 3, 9, 15, 21, 27, each
    // followed by a dormant stretch that the next flag-ACK (6, 12, ...) ends.
    let policy = cusum(&[INF], &[-INF], 1.0, 0);
    let high = 10; // steps 1, 4, 7, ..., 28
    check(
        "no fall-back",
        &deterministic(policy, vec![1], 4, 30),
        [5, 15, 30, 10, high],
    );

    // Every running step adds 1.5 whatever happens: the fifth alarms (7.5 >= 7 > 6), at step 5.
    // Offline (all low) for 2 windows of 2 steps, 6..9: flag-ACKs at 6 and 8 (z = 2, then 1 after
    // the flag, then 2). Online at 10 (low power: nothing reached the sensor at 9): z = 2, a
    // flag-ACK restarts the statistic, which runs 11-15 and alarms at 15. Alarms at 5, 15, 25, 35
    // in 40 steps; online 1-5, 10-15, 20-25, 30-35, 40 (24); flag-ACKs online at 3, 10, 13, 20,
    // 23, 30, 33, 40 and offline at 6, 8, 16, 18, 26, 28, 36, 38; high power at 1, 4, 11, 14,
    // 21, 24, 31, 34.
    let policy = cusum(&[1.5], &[1.5], 7.0, 2);
    let cfg = deterministic(policy, vec![0], 2, 40);
    check("quiet steps add up", &cfg, [4, 20, 24, 16, 8]);
    // With a burn-in of 10 steps, measured from step 11: alarms at 15, 25, 35; online 11-15,
    // 20-25, 30-35, 40 (18); the statistic at 11-15, 21-25, 31-35; flag-ACKs at 13, 16, 18, 20,
    // 23, 26, 28, 30, 33, 36, 38, 40; high power at 11, 14, 21, 24, 31, 34.
    let burnt = GameConfig {
        burn_in: 10,
        horizon: 30,
        ..cfg
    };
    check("burn-in", &burnt, [3, 15, 18, 12, 6]);

    // y = 1 at step 1, and on the step after the flag-ACK that restarts the statistic: a quiet
    // step at y = 1 alarms, y >= 2 adds nothing (the table's last entry holds for every larger
    // y). Alarms at 1; offline (all high) 2-5; online at 6 (low), a flag-ACK at 7, an alarm at 8:
    // every 7 steps, at 1, 8, 15, 22, 29; the statistic runs only then; online at 1, 6-8, 13-15,
    // 20-22, 27-29 (13); flag-ACKs at 7, 14, 21, 28; high power at 1, 8, 15, 22, 29 and the 17
    // offline steps.
    let policy = cusum(&[0.0, 0.0, 0.0], &[1.0, 0.0, 0.0], 1.0, 1);
    check(
        "y from the start",
        &deterministic(policy, vec![1], 4, 30),
        [5, 5, 13, 4, 22],
    );
}

#[test]
fn a_statistic_that_never_alarms_is_the_online_schedule() {
    // Every increment -inf: W stays 0 and the policy plays Policy::Online, draw for draw, on
    // every blocking rule, forging, an automaton and a Markov channel.
    let sys = paper();
    let never = cusum(&[-INF; 4], &[-INF; 4], 1.0, 3);
    let ge = MarkovChannel {
        p: vec![vec![0.9, 0.1], vec![0.3, 0.7]],
        low: vec![0.7, 0.1],
        high: vec![1.0, 0.6],
    };
    let injection = Attack::injection(0.03, Some(Attack::random(0.2).unwrap())).unwrap();
    let automaton = AttackerAutomaton::from_attack(&injection, 1).unwrap();
    let attacks = [
        None,
        Some(Attack::random(0.3).unwrap()),
        Some(Attack::periodic(1, 5).unwrap()),
        Some(Attack::mask(vec![true, false, true, true, false]).unwrap()),
        Some(injection),
    ];
    let mut cases: Vec<GameConfig> = attacks
        .into_iter()
        .map(|a| config(a, Policy::Online))
        .collect();
    cases.push(GameConfig {
        automaton: Some(automaton),
        ..config(None, Policy::Online)
    });
    cases.push(GameConfig {
        channel: Some(ge),
        ..config(Some(Attack::random(0.3).unwrap()), Policy::Online)
    });
    for mut online in cases {
        online.runs = 20;
        online.horizon = 3000;
        online.burn_in = 500;
        let with = GameConfig {
            policy: never.clone(),
            ..online.clone()
        };
        assert!(Sliced::of(&Plan::new(&sys, &with).unwrap()).is_none());
        let (a, b) = (lanes(&sys, &online), lanes(&sys, &with));
        // The kernel the plan chooses is the lane kernel.
        let chosen = simulate_on(
            &sys,
            &with,
            &AtomicBool::new(false),
            &AtomicU64::new(0),
            true,
        );
        assert_eq!(chosen.unwrap(), b);
        let what = format!("{:?} {:?}", online.attack, online.channel);
        assert_eq!(a.cost, b.cost, "{what}");
        assert_eq!(a.high_power, b.high_power, "{what}");
        assert_eq!(a.online, b.online, "{what}");
        assert_eq!(a.delivered, b.delivered, "{what}");
        assert!(b.alarms.iter().all(|&n| n == 0), "{what}");
        // The statistic runs at every measured step.
        assert!(b.tested.iter().all(|&n| n == online.horizon), "{what}");
        assert!(
            b.online_steps.iter().all(|&n| n == online.horizon),
            "{what}"
        );
    }
}

/// The CUSUM game written from the protocol's rules on a plain loop, step by step, with its own
/// uniform draws: per run (alarms, online steps) over the measured horizon. Steps are numbered
/// from 1; the run's start counts as a flag-ACK at step 0.
fn plain(cfg: &GameConfig, beta: f64, run: u64) -> (u64, u64) {
    let Policy::Cusum {
        inc_flag,
        inc_quiet,
        threshold,
        fallback,
    } = &cfg.policy
    else {
        unreachable!()
    };
    let mut rng = SplitMix64::stream(cfg.seed ^ 0x5eed, run);
    let mut u = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let (z0, lam) = (cfg.design.z0, cfg.lam);
    let mut z = 0u64;
    let mut flag_last_step = false;
    let mut ack_last_step = true; // the initial condition: high power at step 1
    let mut last_ack = 0u64;
    let mut w = 0.0f64;
    let mut dormant = false;
    let mut offline_from = 0u64; // the offline stretch's first step
    let mut offline_to = 0u64; // and its last (none before the first alarm)
    let (mut alarms, mut online_steps) = (0, 0);
    for k in 1..=cfg.burn_in + cfg.horizon {
        let online = !(offline_from..=offline_to).contains(&k);
        let high = if online {
            ack_last_step
        } else {
            let period = cfg.offline.len() as u64;
            cfg.offline[((k - offline_from) % period) as usize] == 1
        };
        let arrived = high || u() < lam;
        z = if arrived {
            0
        } else if flag_last_step {
            1
        } else {
            z + 1
        };
        let flag = z >= z0; // μ = 1
        let ack = flag && u() >= beta;
        let measured = k > cfg.burn_in;
        if online {
            online_steps += u64::from(measured);
            if dormant {
                dormant = !ack;
            } else {
                let y = ((k - last_ack) as usize).min(inc_flag.len());
                let inc = if ack {
                    inc_flag[y - 1]
                } else {
                    inc_quiet[y - 1]
                };
                w = (w + inc).max(0.0);
                if w >= *threshold {
                    alarms += u64::from(measured);
                    w = 0.0;
                    dormant = true;
                    if *fallback > 0 {
                        offline_from = k + 1;
                        offline_to = k + fallback * cfg.window;
                    }
                }
            }
        }
        if ack {
            last_ack = k;
        }
        flag_last_step = flag;
        ack_last_step = ack;
    }
    (alarms, online_steps)
}

/// Σ alarms / Σ online steps over runs, and its standard error (delta method).
fn rate(alarms: &[u64], online: &[u64]) -> (f64, f64) {
    let n = alarms.len() as f64;
    let (a, o): (f64, f64) = (
        alarms.iter().map(|&x| x as f64).sum(),
        online.iter().map(|&x| x as f64).sum(),
    );
    let r = a / o;
    let var = alarms
        .iter()
        .zip(online)
        .map(|(&x, &y)| (x as f64 - r * y as f64).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    (r, (var * n).sqrt() / o)
}

#[test]
fn alarm_rate_matches_a_plain_simulation() {
    // λ = 0.5, z0 = 2, no attack and random blocking at 0.3: alarms per online step of the lane
    // kernel and of the plain loop within 4 standard errors. Gaps below z0 + 1 = 3 cannot occur
    // without forgery, so their +inf never fires; the quiet increments grow with y.
    let sys = paper();
    let policy = cusum(
        &[INF, INF, -0.4, -0.2, 0.1],
        &[0.0, 0.05, 0.15, 0.3, 0.4],
        2.0,
        2,
    );
    for beta in [0.0, 0.3] {
        let attack = (beta > 0.0).then(|| Attack::random(beta).unwrap());
        let mut cfg = config(attack, policy.clone());
        cfg.window = 50;
        cfg.horizon = 20_000;
        cfg.burn_in = 500;
        cfg.runs = 64;
        let res = lanes(&sys, &cfg);
        let (r1, s1) = rate(&res.alarms, &res.online_steps);
        let (alarms, online): (Vec<u64>, Vec<u64>) =
            (0..cfg.runs).map(|i| plain(&cfg, beta, i)).unzip();
        let (r2, s2) = rate(&alarms, &online);
        let tol = 4.0 * (s1 * s1 + s2 * s2).sqrt();
        assert!(
            (r1 - r2).abs() <= tol,
            "beta {beta}: {r1} vs {r2} (± {tol})"
        );
        // Alarms are neither rare nor every few steps, and the fall-backs take a visible share.
        assert!(r1 > 1e-3 && r1 < 0.1, "beta {beta}: rate {r1}");
        let total = (cfg.runs * cfg.horizon) as f64;
        let off = 1.0 - res.online_steps.iter().sum::<u64>() as f64 / total;
        assert!(off > 0.05, "beta {beta}: offline share {off}");
    }
}

#[test]
fn bad_cusum_configs_name_the_argument() {
    let sys = paper();
    let bad = |policy: Policy| -> String {
        let cfg = config(None, policy);
        match sys.simulate_game(&cfg) {
            Err(Error::InvalidArgument { arg, .. }) => arg,
            other => panic!("{other:?}"),
        }
    };
    assert_eq!(bad(cusum(&[], &[], 1.0, 1)), "inc_flag");
    assert_eq!(bad(cusum(&[1.0], &[], 1.0, 1)), "inc_quiet");
    assert_eq!(bad(cusum(&[f64::NAN], &[1.0], 1.0, 1)), "inc_flag");
    assert_eq!(bad(cusum(&[1.0], &[f64::NAN], 1.0, 1)), "inc_quiet");
    assert_eq!(bad(cusum(&[1.0, 2.0], &[1.0], 1.0, 1)), "inc_quiet");
    let long = vec![0.0; MAX_CUSUM_TABLE + 1];
    assert_eq!(bad(cusum(&long, &long, 1.0, 1)), "inc_flag");
    for h in [0.0, -1.0, INF, f64::NAN] {
        assert_eq!(bad(cusum(&[1.0], &[1.0], h, 1)), "threshold");
    }
    assert_eq!(bad(cusum(&[1.0], &[1.0], 1.0, u64::MAX)), "fallback");
}
