//! The game on a Markov channel: against the exact engine, determinism across threads, the
//! i.i.d. channel's results pinned bit for bit, and the channel's validation.

use super::*;
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
            design: OnlineDesign::new(z0, mu).unwrap(),
            offline: offline_schedule(Ratio::new(2, 7).unwrap()).unwrap(),
            attack,
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
