//! The game on a Markov channel: against the exact engine, determinism across threads, the
//! i.i.d. channel's results pinned bit for bit, and the channel's validation.

use super::super::*;
use crate::engine::{Attacker, Engine, PowerSchedule};
use crate::schedule::{offline_schedule, Ratio};

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

/// FNV-1a over a run's results, every float by its bits.
fn fnv(h: &mut u64, x: u64) {
    for b in x.to_le_bytes() {
        *h = (*h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
}

fn digest(res: &GameRuns) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325;
    for v in [&res.cost, &res.high_power, &res.online] {
        v.iter().for_each(|x| fnv(&mut h, x.to_bits()));
    }
    for v in [&res.tested, &res.alarms, &res.fallbacks, &res.delivered] {
        v.iter().for_each(|&x| fnv(&mut h, x));
    }
    h
}

/// Configurations that reach every branch of both kernels on the i.i.d. channel: each policy,
/// each blocking rule, forging, a random memory length, partial tiles and blocks, a burn-in
/// that ends inside a window and a horizon that ends inside one.
fn pinned_configs() -> Vec<GameConfig> {
    // Count bounds about one standard deviation either side of the attacked count, so that
    // alarms are neither rare nor sure.
    let count = |lam: f64, z0: u64, mu: f64, a: &Attack| {
        let design = OnlineDesign::new(z0, mu).unwrap();
        let n = crate::flag_rates(lam, design, Some(a)).unwrap().delivered * 250.0;
        Policy::Test {
            detector: Detector::Count {
                lo: (n - 4.0) as i64,
                hi: (n + 4.0) as i64,
            },
            harmful_at_most: None,
            fallback: 2,
            min_gap: 0,
        }
    };
    let (periodic, random) = (
        Attack::periodic(1, 5).unwrap(),
        Attack::random(0.3).unwrap(),
    );
    let interval = Policy::Test {
        detector: Detector::Interval {
            edges: vec![1, 2, 3, 4, 6],
            expected: vec![10.0, 15.0, 20.0, 15.0, 10.0],
            critical: 25.0,
        },
        harmful_at_most: Some(70),
        fallback: 1,
        min_gap: 0,
    };
    let cases = [
        (None, Policy::Online, 2, 1.0),
        (
            Some(periodic.clone()),
            count(0.3, 2, 1.0, &periodic),
            2,
            1.0,
        ),
        (
            Some(Attack::mask(vec![true, false, true, true, false]).unwrap()),
            interval.clone(),
            3,
            0.4,
        ),
        (Some(random.clone()), count(0.5, 2, 0.7, &random), 2, 0.7),
        (
            Some(Attack::injection(0.05, None).unwrap()),
            interval,
            2,
            1.0,
        ),
        (
            Some(Attack::injection(0.04, Some(Attack::random(0.2).unwrap())).unwrap()),
            Policy::Online,
            1,
            1.0,
        ),
        (
            Some(Attack::periodic(2, 3).unwrap()),
            Policy::Offline,
            2,
            1.0,
        ),
    ];
    cases
        .into_iter()
        .enumerate()
        .map(|(i, (attack, policy, z0, mu))| GameConfig {
            lam: [0.5, 0.3, 0.7][i % 3],
            channel: None,
            design: OnlineDesign::new(z0, mu).unwrap(),
            offline: offline_schedule(Ratio::new(2, 7).unwrap()).unwrap(),
            attack,
            automaton: None,
            policy,
            window: 250,
            horizon: 1900,
            burn_in: 330,
            runs: 300,
            seed: 11 + i as u64,
        })
        .collect()
}

#[test]
fn the_iid_channel_is_pinned_bit_for_bit() {
    let sys = paper();
    let mut got = Vec::new();
    for cfg in pinned_configs() {
        assert!(sliced::Sliced::of(&plan::Plan::new(&sys, &cfg).unwrap()).is_some());
        for sliced in [true, false] {
            let out = simulate_on(
                &sys,
                &cfg,
                &AtomicBool::new(false),
                &AtomicU64::new(0),
                sliced,
            )
            .unwrap();
            got.push(digest(&out));
        }
    }
    // Digests of the results before the game took a Markov channel (commit 48ae6b8), per
    // configuration the bit-sliced kernel then the lane kernel.
    let pinned: [u64; 14] = [
        0xc53f56fab7a7416f,
        0xf4bdb3c0fb1a18a8,
        0x75731024555f1900,
        0x1dd4945a632c0d49,
        0xa144e5cc2c5b5060,
        0xed982db77c625a12,
        0xc753db8795547a03,
        0x1a4f5e32898e4abe,
        0xc3613109ecd68b62,
        0x9485ea52ccc98e7d,
        0x0bf56dd03551590e,
        0x02721c358bdafd8f,
        0x871eb7b6e4207475,
        0xc996937a52b97510,
    ];
    assert_eq!(got, pinned);
}

/// A Gilbert-Elliott channel (good: λ = 0.8, bad: λ = 0.15; high power always arrives).
pub(super) fn gilbert_elliott() -> MarkovChannel {
    MarkovChannel {
        p: vec![vec![0.9, 0.1], vec![0.25, 0.75]],
        low: vec![0.8, 0.15],
        high: vec![1.0, 1.0],
    }
}

/// Three states, the third one losing high-power packets too.
fn three_state() -> MarkovChannel {
    MarkovChannel {
        p: vec![
            vec![0.8, 0.15, 0.05],
            vec![0.2, 0.7, 0.1],
            vec![0.3, 0.3, 0.4],
        ],
        low: vec![0.8, 0.4, 0.2],
        high: vec![1.0, 1.0, 0.6],
    }
}

fn engine_channel(ch: &MarkovChannel) -> crate::engine::Channel {
    crate::engine::Channel::markov(ch.p.clone(), ch.low.clone(), ch.high.clone()).unwrap()
}

/// A count test that never alarms: the closed loop is the plain protocol.
fn never() -> Policy {
    Policy::Test {
        detector: Detector::Count {
            lo: -1,
            hi: 1 << 40,
        },
        harmful_at_most: None,
        fallback: 3,
        min_gap: 0,
    }
}

fn channel_config(channel: MarkovChannel, attack: Option<Attack>, policy: Policy) -> GameConfig {
    GameConfig {
        lam: f64::NAN,
        channel: Some(channel),
        design: OnlineDesign::fixed(2).unwrap(),
        offline: vec![0, 1, 0, 0, 1, 1, 0],
        attack,
        automaton: None,
        policy,
        window: 1000,
        horizon: 10_000,
        burn_in: 500,
        runs: 256,
        seed: 5,
    }
}

fn run(sys: &LinearSystem, cfg: &GameConfig) -> GameRuns {
    let progress = AtomicU64::new(0);
    let out = simulate_on(sys, cfg, &AtomicBool::new(false), &progress, true).unwrap();
    assert_eq!(progress.into_inner(), cfg.runs);
    out
}

fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
    (m, (v / n).sqrt())
}

/// The engine's exact mean of E Tr P_k over the measured steps (from the paper's initial
/// condition, as the runs start) and its stationary high-power rate.
fn exact(
    sys: &LinearSystem,
    cfg: &GameConfig,
    schedule: PowerSchedule,
    att: Attacker,
) -> (f64, f64) {
    let ch = engine_channel(cfg.channel.as_ref().unwrap());
    let e = Engine::new(&ch, &schedule, &att, crate::engine::DEFAULT_MAX_STATES).unwrap();
    assert!(e.stability_index(sys).unwrap() < 0.9);
    let steps = (cfg.burn_in + cfg.horizon) as usize;
    let (trace, _) = e.cost_curve(sys, steps).unwrap();
    let measured = &trace[cfg.burn_in as usize..];
    let j = measured.iter().sum::<f64>() / measured.len() as f64;
    (j, e.high_power_rate().unwrap())
}

#[test]
fn markov_channels_match_the_exact_engine() {
    let sys = paper();
    let design = OnlineDesign::fixed(2).unwrap();
    for channel in [gilbert_elliott(), three_state()] {
        for attack in [
            None,
            Some(Attack::periodic(1, 5).unwrap()),
            Some(Attack::random(0.3).unwrap()),
            Some(Attack::injection(0.1, None).unwrap()),
        ] {
            let cfg = channel_config(channel.clone(), attack.clone(), never());
            let res = run(&sys, &cfg);
            let att = attack.clone().map_or(Attacker::None, Attacker::attack);
            let (j, rate) = exact(&sys, &cfg, PowerSchedule::Online(design), att);
            let (m, se) = mean_se(&res.cost);
            assert!((m - j).abs() < 4.0 * se, "{attack:?}: J {m} ± {se} vs {j}");
            let (hp, se_hp) = mean_se(&res.high_power);
            assert!(
                (hp - rate).abs() < 4.0 * se_hp + 1e-4,
                "{attack:?}: high power {hp} ± {se_hp} vs {rate}"
            );
            // Online, high power exactly after each flag-ACK that reaches the sensor.
            for (d, h) in res.delivered.iter().zip(&res.high_power) {
                assert!((*d as f64 - h * 1e4).abs() <= 1.5);
            }
            assert!(res.tested.iter().all(|&t| t == 10) && res.alarms.iter().all(|&a| a == 0));
        }
    }
    // Offline on the given pattern (starting with a low-power step), no attack.
    let cfg = channel_config(three_state(), None, Policy::Offline);
    let res = run(&sys, &cfg);
    let pattern = cfg.offline.iter().map(|&g| g == 1).collect();
    let (j, rate) = exact(&sys, &cfg, PowerSchedule::Offline(pattern), Attacker::None);
    let (m, se) = mean_se(&res.cost);
    assert!((m - j).abs() < 4.0 * se, "offline: J {m} ± {se} vs {j}");
    assert!(res.high_power.iter().all(|&h| (h - rate).abs() < 2e-4));
}

#[test]
fn markov_results_depend_on_the_seed_and_the_run_only() {
    let sys = paper();
    let mut cfg = channel_config(three_state(), Some(Attack::random(0.3).unwrap()), never());
    (cfg.runs, cfg.horizon) = (37, 2000);
    let with = |threads: usize, cfg: &GameConfig| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&sys, cfg))
    };
    let one = with(1, &cfg);
    assert_eq!(one, with(2, &cfg));
    cfg.runs = 20;
    assert_eq!(&one.cost[..20], &with(2, &cfg).cost[..]);
    cfg.seed += 1;
    assert_ne!(&one.cost[..20], &with(2, &cfg).cost[..]);
}

#[test]
fn bad_channels_name_the_argument() {
    let sys = paper();
    let starts = |ch: MarkovChannel, arg: &str| {
        let cfg = channel_config(ch, None, Policy::Online);
        let e = sys.simulate_game(&cfg).unwrap_err().to_string();
        assert!(e.starts_with(arg), "{e}");
    };
    let mut ch = gilbert_elliott();
    ch.p[1] = vec![0.25];
    starts(ch, "P:");
    let mut ch = gilbert_elliott();
    ch.p[0][0] = 0.8;
    starts(ch, "P:");
    // Two closed classes.
    let mut ch = gilbert_elliott();
    ch.p = vec![vec![1.0, 0.0], vec![0.0, 1.0]];
    starts(ch, "P:");
    let mut ch = gilbert_elliott();
    ch.p = vec![];
    starts(ch, "P:");
    let k = MAX_CHANNEL_STATES + 1;
    let mut ch = gilbert_elliott();
    ch.p = vec![vec![1.0 / k as f64; k]; k];
    starts(ch, "P:");
    let mut ch = gilbert_elliott();
    ch.low.push(0.5);
    starts(ch, "low:");
    let mut ch = gilbert_elliott();
    ch.high[1] = f64::NAN;
    starts(ch, "high:");
    let mut ch = gilbert_elliott();
    ch.high[0] = 1.5;
    starts(ch, "high:");
    // The i.i.d. channel still checks λ; an empty or non-binary offline pattern is refused.
    let mut cfg = channel_config(gilbert_elliott(), None, Policy::Online);
    cfg.channel = None;
    assert!(sys
        .simulate_game(&cfg)
        .unwrap_err()
        .to_string()
        .starts_with("lam:"));
    cfg.lam = 0.5;
    cfg.offline = vec![];
    assert!(sys
        .simulate_game(&cfg)
        .unwrap_err()
        .to_string()
        .starts_with("offline:"));
}
