//! Tests of the automaton kernel's state mode: J from the simulated errors against the exact
//! engine's J_H on Markov channels under attacker automata and an offline pattern, on the
//! paper's system and on a 2 × 2 one; the same protocol path as covariance mode for one seed;
//! determinism across thread counts and builds; overflow to +inf on unstable A.

use std::sync::atomic::{AtomicBool, AtomicU64};

use nalgebra::DMatrix;

use super::*;
use crate::engine::{self, AttackerAutomaton, Channel, Engine, Move, PowerSchedule};
use crate::OnlineDesign;

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

/// A 2 × 2 system, unstable in one mode, observed through one output.
fn two_by_two() -> LinearSystem {
    let m = |r, c, v: &[f64]| DMatrix::from_row_slice(r, c, v);
    LinearSystem::new(
        m(2, 2, &[1.1, 0.3, 0.0, 0.8]),
        m(1, 2, &[1.0, 0.5]),
        m(2, 2, &[0.5, 0.1, 0.1, 0.3]),
        m(1, 1, &[0.6]),
    )
    .unwrap()
}

fn run(sys: &LinearSystem, cfg: &AutomatonConfig) -> McResult {
    simulate(sys, cfg, &AtomicBool::new(false), &AtomicU64::new(0)).unwrap()
}

fn t(p: f64, deliver: bool, next: usize) -> Transition {
    Transition { p, deliver, next }
}

/// PeriodicBlocking(r, t): the first r of every t genuine flag-ACKs blocked.
fn periodic(r: usize, period: usize) -> Attacker {
    Attacker {
        flag: (0..period)
            .map(|s| vec![t(1.0, s >= r, (s + 1) % period)])
            .collect(),
        quiet: (0..period).map(|s| vec![t(1.0, false, s)]).collect(),
        start: 0,
    }
}

/// Blocks each genuine flag-ACK with probability 0.3 and forges one on a quiet step with
/// probability 0.05 (random blocking beside injection).
fn random_and_forge() -> Attacker {
    Attacker {
        flag: vec![vec![t(0.3, false, 0), t(0.7, true, 0)]],
        quiet: vec![vec![t(0.05, true, 0), t(0.95, false, 0)]],
        start: 0,
    }
}

/// A two-state on/off attacker (as in the covariance tests).
fn on_off() -> Attacker {
    Attacker {
        flag: vec![
            vec![t(0.5, true, 0), t(0.5, false, 1)],
            vec![t(1.0, false, 1)],
        ],
        quiet: vec![
            vec![t(1.0, false, 0)],
            vec![t(0.8, false, 1), t(0.2, false, 0)],
        ],
        start: 0,
    }
}

fn gilbert_elliott(p: f64, q: f64, good: f64, bad: f64) -> MarkovChannel {
    MarkovChannel {
        p: vec![vec![1.0 - p, p], vec![q, 1.0 - q]],
        low: vec![good, bad],
        high: vec![1.0, 1.0],
    }
}

/// Three states; high power is lost sometimes in the worst one.
fn three_state() -> MarkovChannel {
    MarkovChannel {
        p: vec![
            vec![0.8, 0.15, 0.05],
            vec![0.2, 0.6, 0.2],
            vec![0.1, 0.3, 0.6],
        ],
        low: vec![0.9, 0.5, 0.1],
        high: vec![1.0, 0.95, 0.7],
    }
}

/// The exact J_H of `cfg` from the engine (the product automaton's law propagated).
fn exact_j(sys: &LinearSystem, cfg: &AutomatonConfig) -> f64 {
    let ch = &cfg.channel;
    let channel = Channel::markov(ch.p.clone(), ch.low.clone(), ch.high.clone()).unwrap();
    let moves = |ev: &Vec<Vec<Transition>>| -> Vec<Vec<Move>> {
        ev.iter()
            .map(|e| {
                e.iter()
                    .map(|x| Move {
                        p: x.p,
                        deliver: x.deliver,
                        next: x.next,
                    })
                    .collect()
            })
            .collect()
    };
    let (schedule, attacker) = match &cfg.sensor {
        Sensor::Online { z0, mu } => {
            let att = cfg.attacker.as_ref().map_or(engine::Attacker::None, |a| {
                let auto = AttackerAutomaton::new(moves(&a.flag), moves(&a.quiet), a.start);
                engine::Attacker::Automaton(auto.unwrap())
            });
            (
                PowerSchedule::Online(OnlineDesign::new(*z0, *mu).unwrap()),
                att,
            )
        }
        Sensor::Offline { pattern } => (
            PowerSchedule::Offline(pattern.clone()),
            engine::Attacker::None,
        ),
    };
    let eng = Engine::new(&channel, &schedule, &attacker, 1_000_000).unwrap();
    let (_, j_k) = eng.cost_curve(sys, cfg.horizon).unwrap();
    *j_k.last().unwrap()
}

fn state(channel: MarkovChannel, sensor: Sensor, attacker: Option<Attacker>) -> AutomatonConfig {
    AutomatonConfig {
        channel,
        sensor,
        attacker,
        mode: Mode::State,
        horizon: 200,
        runs: 2000,
        seed: 3,
        record_runs: false,
    }
}

const Z2: Sensor = Sensor::Online { z0: 2, mu: 1.0 };

/// State-mode J within 4 standard errors of the exact J_H: both Gilbert-Elliott channels and a
/// three-state one, under periodic blocking, random blocking with injection and the on/off
/// automaton, μ = 1 and μ strictly between 0 and 1, an offline pattern that starts low (where
/// e_0 = e^s_0 matters), on the paper's system and on a 2 × 2 one.
#[test]
fn state_mode_matches_the_exact_engine() {
    let offline = Sensor::Offline {
        pattern: vec![false, true, false, false],
    };
    let mu = Sensor::Online { z0: 2, mu: 0.4 };
    let cases = [
        (
            paper(),
            state(
                gilbert_elliott(0.2, 0.2, 1.0, 0.0),
                Z2,
                Some(periodic(1, 5)),
            ),
        ),
        (
            paper(),
            state(
                gilbert_elliott(0.1, 0.3, 0.9, 0.2),
                mu.clone(),
                Some(random_and_forge()),
            ),
        ),
        (paper(), state(three_state(), Z2, Some(on_off()))),
        (paper(), state(three_state(), offline.clone(), None)),
        (
            two_by_two(),
            state(gilbert_elliott(0.1, 0.3, 0.9, 0.2), Z2, Some(on_off())),
        ),
        (two_by_two(), state(three_state(), mu, Some(periodic(2, 3)))),
        (
            two_by_two(),
            state(gilbert_elliott(0.2, 0.2, 1.0, 0.0), offline, None),
        ),
    ];
    for (i, (sys, cfg)) in cases.iter().enumerate() {
        let res = run(sys, cfg);
        let exact = exact_j(sys, cfg);
        assert!(
            res.stderr.is_finite() && (res.j - exact).abs() < 4.0 * res.stderr,
            "case {i}: {} ± {} vs {exact}",
            res.j,
            res.stderr
        );
        assert!(res.mean_trace.iter().all(|x| x.is_finite() && *x > 0.0));
    }
}

/// For one seed state mode sees the protocol path of covariance mode: the same flag-ACK counts
/// and deliveries run by run, while J differs (the noise is sampled, not averaged).
#[test]
fn state_mode_follows_the_protocol_path_of_covariance_mode() {
    let sys = paper();
    let cfg = AutomatonConfig {
        record_runs: true,
        runs: 300,
        ..state(
            three_state(),
            Sensor::Online { z0: 2, mu: 0.4 },
            Some(random_and_forge()),
        )
    };
    let st = run(&sys, &cfg);
    let cov = run(
        &sys,
        &AutomatonConfig {
            mode: Mode::Covariance,
            ..cfg.clone()
        },
    );
    assert_eq!(st.delivered_per_run, cov.delivered_per_run);
    let counts = |r: &McResult| {
        (
            r.flags_sent,
            r.flags_blocked,
            r.flags_forged,
            r.high_power_rate,
        )
    };
    assert_eq!(counts(&st), counts(&cov));
    assert!(st.flags_forged > 0.0 && st.flags_blocked > 0.0);
    assert_ne!(st.j, cov.j);
}

/// The same seed gives the same state-mode result bit for bit on one thread and on two (a
/// partial last block and a partial last group included), and on the plain and AVX2 builds.
#[test]
fn state_mode_is_deterministic() {
    let sys = two_by_two();
    let cfg = AutomatonConfig {
        runs: 517,
        horizon: 60,
        record_runs: true,
        ..state(gilbert_elliott(0.1, 0.3, 0.9, 0.2), Z2, Some(on_off()))
    };
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let a = pool(1).install(|| run(&sys, &cfg));
    let b = pool(2).install(|| run(&sys, &cfg));
    assert_eq!(a, b);
    let c = run(
        &sys,
        &AutomatonConfig {
            seed: 4,
            ..cfg.clone()
        },
    );
    assert_ne!(a.j, c.j);
    if let Some(token) = crate::montecarlo::cpu::Avx2::detect() {
        let (cancel, progress) = (AtomicBool::new(false), AtomicU64::new(0));
        let plain = simulate_on(&sys, &cfg, &cancel, &progress, None).unwrap();
        let avx2 = simulate_on(&sys, &cfg, &cancel, &progress, Some(token)).unwrap();
        assert_eq!(plain, avx2);
        assert_eq!(plain, a);
    }
}

/// Unstable A with every flag-ACK blocked on a channel that almost never delivers: the errors
/// overflow, and J, its standard error and the late per-step means are +inf, never NaN, on the
/// scalar and on the vector recursions.
#[test]
fn state_mode_overflow_gives_inf() {
    let block_all = Attacker {
        flag: vec![vec![t(1.0, false, 0)]],
        quiet: vec![vec![t(1.0, false, 0)]],
        start: 0,
    };
    for sys in [paper(), two_by_two()] {
        let cfg = AutomatonConfig {
            horizon: 8000,
            runs: 8,
            ..state(MarkovChannel::bernoulli(1e-6), Z2, Some(block_all.clone()))
        };
        let res = run(&sys, &cfg);
        assert!(res.j.is_infinite() && res.stderr.is_infinite(), "{}", res.j);
        assert!(res.mean_trace.iter().all(|x| !x.is_nan()));
        assert!(res.mean_trace.last().unwrap().is_infinite());
    }
}
