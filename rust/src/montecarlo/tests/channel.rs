//! The bit-sliced kernel on a two-state Markov channel: its per-lane draws against their exact
//! definition, the results against the exact engine, and the seed alone fixing them.

use super::*;
use crate::engine::{Attacker, Channel, Engine, PowerSchedule};
use crate::montecarlo::bitslice::words::{lane, Portable, Prob, Rng4, RUNS};
use crate::schedule::OnlineDesign;

/// GE(p, q, lam_good, lam_bad) with high power always arriving.
fn ge(p: f64, q: f64, good: f64, bad: f64) -> TwoStateChannel {
    TwoStateChannel {
        p,
        q,
        low: [good, bad],
    }
}

/// An online experiment on `channel` under `attack`.
fn on(channel: TwoStateChannel, attack: Option<Attack>, protocol: Protocol) -> McConfig {
    McConfig {
        channel: Some(channel),
        attack,
        protocol,
        ..online(0.5, 2, 1.0, None)
    }
}

/// Each lane's uniform as the bit-serial draws read it: bit 63 - i is the lane's bit of the
/// i-th word.
fn uniforms(rng: &mut Rng4) -> [u64; RUNS] {
    let mut u = [0u64; RUNS];
    for i in 0..64 {
        let w = rng.next(Portable);
        for (l, x) in u.iter_mut().enumerate() {
            *x |= u64::from(lane(&w, l)) << (63 - i);
        }
    }
    u
}

/// `bernoulli_sel` hits exactly where the lane's uniform is below its own threshold (`b`'s in
/// `sel`, `a`'s elsewhere), with certainty for p = 1 and never for p = 0, and nowhere outside
/// `need`: checked lane by lane against the uniforms rebuilt from the same words.
#[test]
fn per_lane_draws_are_exact() {
    let probs = [0.0, 1.0, 0.5, 0.2, 0.3, 0.9, 1.0 - 1e-12, 3e-17];
    let sel = crate::montecarlo::bitslice::words::from_lanes(|l| l % 3 == 1 || l > 200);
    let need = crate::montecarlo::bitslice::words::from_lanes(|l| l % 5 != 0);
    let mut seed = 0;
    for &pa in &probs {
        for &pb in &probs {
            seed += 1;
            let (a, b) = (Prob::new(pa), Prob::new(pb));
            let mut rng = Rng4::for_block(seed, 3);
            let mut copy = Rng4 { s: rng.s };
            let hit = rng.bernoulli_sel(Portable, (a, b), sel, need);
            let u = uniforms(&mut copy);
            for (l, &ul) in u.iter().enumerate() {
                let (p, want_p) = if lane(&sel, l) { (b, pb) } else { (a, pa) };
                let want = lane(&need, l) && (p.one || ul < p.thr);
                assert_eq!(lane(&hit, l), want, "p = {want_p}, lane {l}");
            }
        }
    }
}

/// The exact engine's J_H and high-power rate for `cfg` (an online design z0, μ = 1).
fn exact(sys: &LinearSystem, cfg: &McConfig) -> (f64, f64) {
    let ch = cfg.channel.unwrap();
    let channel = Channel::gilbert_elliott(ch.p, ch.q, ch.low[0], ch.low[1], 1.0, 1.0).unwrap();
    let McSchedule::Online { z0, mu } = cfg.schedule else {
        unreachable!()
    };
    let attacker = match &cfg.attack {
        None => Attacker::None,
        Some(a) => Attacker::Attack {
            attack: a.clone(),
            min_gap: 1,
        },
    };
    let sched = PowerSchedule::Online(OnlineDesign::new(z0, mu).unwrap());
    let engine = Engine::new(&channel, &sched, &attacker, 1_000_000).unwrap();
    let (_, j_k) = engine.cost_curve(sys, cfg.horizon).unwrap();
    (j_k[cfg.horizon - 1], engine.high_power_rate().unwrap())
}

/// J_H within 4 standard errors of the exact engine's, and the high-power rate within its
/// binomial tolerance of the stationary one, on the two Gilbert-Elliott channels of the tests under every attack
/// kind the kernel takes, protocols A and B (the Python tests cover the same grid with more
/// runs; this is the Rust side's own check, small in unoptimised builds).
#[test]
fn agrees_with_the_exact_engine() {
    let sys = scalar_sys();
    let attacks = [
        None,
        Some(Attack::Periodic { r: 1, t: 5 }),
        Some(Attack::Mask(vec![true, false, true, true, false])),
        Some(Attack::Random { beta: 0.3 }),
        Some(Attack::Injection {
            gamma: 0.05,
            block: None,
        }),
        Some(Attack::Injection {
            gamma: 0.1,
            block: Some(Box::new(Attack::Periodic { r: 1, t: 4 })),
        }),
    ];
    for ch in [ge(0.2, 0.2, 1.0, 0.0), ge(0.1, 0.3, 0.9, 0.2)] {
        for (i, attack) in attacks.iter().enumerate() {
            // One protocol per attack in debug builds, both in release.
            for protocol in [Protocol::A, Protocol::B] {
                if cfg!(debug_assertions) && (i % 2 == 0) != (protocol == Protocol::A) {
                    continue;
                }
                let cfg = McConfig {
                    horizon: 200,
                    runs: scaled(20_000),
                    ..on(ch, attack.clone(), protocol)
                };
                assert!(Plan::new(&sys, &cfg).unwrap().bitslice.is_some());
                let res = run(&sys, &cfg).unwrap();
                let (j, rate) = exact(&sys, &cfg);
                let what = format!("{ch:?} {attack:?} {protocol:?}");
                assert_close(&what, res.j, j, res.stderr, 4.0);
                let tol = binomial_tol(rate, &cfg);
                assert!(
                    (res.high_power_rate - rate).abs() <= tol,
                    "{what}: rate {} vs {rate}",
                    res.high_power_rate
                );
            }
        }
    }
}

/// One seed, one result: 1 and 2 threads, the portable and the AVX2 builds, partial blocks,
/// with and without recording; different seeds differ.
#[test]
fn independent_of_threads_and_build() {
    let sys = scalar_sys();
    let (one, two) = (pool(1), pool(2));
    let cases = [
        on(
            ge(0.2, 0.2, 1.0, 0.0),
            Some(Attack::Periodic { r: 1, t: 5 }),
            Protocol::B,
        ),
        on(
            ge(0.1, 0.3, 0.9, 0.2),
            Some(Attack::Random { beta: 0.3 }),
            Protocol::A,
        ),
        on(
            ge(0.1, 0.3, 0.9, 0.2),
            Some(Attack::Injection {
                gamma: 0.1,
                block: None,
            }),
            Protocol::B,
        ),
    ];
    for base in cases {
        let cfg = McConfig {
            horizon: 150,
            runs: 3 * BLOCK_RUNS + 17,
            record_runs: true,
            ..base
        };
        let go = |isa| {
            let kernels = Kernels {
                isa,
                bitslice: true,
            };
            let (c, p) = (AtomicBool::new(false), AtomicU64::new(0));
            simulate_with(&sys, &cfg, &c, &p, kernels).unwrap()
        };
        let portable = one.install(|| go(Isa::Portable));
        assert_eq!(two.install(|| go(Isa::Portable)), portable, "{cfg:?}");
        if let Some(avx2) = avx2_or_skip("independent_of_threads_and_build") {
            assert_eq!(two.install(|| go(avx2)), portable, "{cfg:?}");
            assert_eq!(one.install(|| go(avx2)), portable, "{cfg:?}");
        }
        let other = run(
            &sys,
            &McConfig {
                seed: 2,
                ..cfg.clone()
            },
        )
        .unwrap();
        assert_ne!(other.j, portable.j);
    }
}

/// The channel with one arrival probability in both states is the i.i.d. one: its J and rate
/// agree with the i.i.d. kernel's exact closed-form values (the engine on the Bernoulli
/// channel), whatever p and q.
#[test]
fn equal_states_are_the_iid_channel() {
    let sys = scalar_sys();
    let cfg = McConfig {
        horizon: 200,
        runs: scaled(20_000),
        ..on(
            ge(0.3, 0.05, 0.6, 0.6),
            Some(Attack::Random { beta: 0.2 }),
            Protocol::B,
        )
    };
    let res = run(&sys, &cfg).unwrap();
    let iid = Engine::new(
        &Channel::bernoulli(0.6).unwrap(),
        &PowerSchedule::Online(OnlineDesign::new(2, 1.0).unwrap()),
        &Attacker::Attack {
            attack: Attack::Random { beta: 0.2 },
            min_gap: 1,
        },
        1_000_000,
    )
    .unwrap();
    let j = iid.cost_curve(&sys, 200).unwrap().1[199];
    assert_close("equal states", res.j, j, res.stderr, 4.0);
}

/// Refusals: state mode, bad channel parameters, the lane kernels; a plan outside the
/// bit-sliced kernel's limits is `None` from `simulate_if_supported` and an error from
/// `simulate`.
#[test]
fn channel_refusals() {
    let sys = scalar_sys();
    let ok = on(ge(0.2, 0.2, 1.0, 0.0), None, Protocol::B);
    let err_arg = |cfg: &McConfig| match run(&sys, cfg) {
        Err(Error::InvalidArgument { arg, .. }) => arg,
        other => panic!("{cfg:?}: {other:?}"),
    };
    let state = McConfig {
        mode: Mode::State,
        ..ok.clone()
    };
    assert_eq!(err_arg(&state), "mode");
    for (ch, arg) in [
        (ge(-0.1, 0.2, 1.0, 0.0), "channel.p"),
        (ge(0.1, 1.5, 1.0, 0.0), "channel.q"),
        (ge(0.1, 0.2, f64::NAN, 0.0), "channel.low[0]"),
        (ge(0.1, 0.2, 1.0, 2.0), "channel.low[1]"),
        (ge(0.0, 0.0, 1.0, 0.0), "channel"),
    ] {
        let cfg = McConfig {
            channel: Some(ch),
            ..ok.clone()
        };
        assert_eq!(err_arg(&cfg), arg);
    }
    let kernels = Kernels {
        isa: detect_isa(),
        bitslice: false,
    };
    let (c, p) = (AtomicBool::new(false), AtomicU64::new(0));
    assert!(simulate_with(&sys, &ok, &c, &p, kernels).is_err());
    // z0 = 40: the memory is deeper than the thermometer.
    let deep = McConfig {
        schedule: McSchedule::Online { z0: 40, mu: 1.0 },
        attack: Some(Attack::Periodic { r: 1, t: 5 }),
        ..ok.clone()
    };
    assert!(simulate_if_supported(&sys, &deep, &c, &p)
        .unwrap()
        .is_none());
    assert_eq!(err_arg(&deep), "channel");
    let fits = simulate_if_supported(&sys, &ok, &c, &p).unwrap();
    assert_eq!(fits, Some(run(&sys, &ok).unwrap()));
}
