//! Tests of the automaton Monte Carlo: its alias tables, exact expected values on the paper's
//! channel (the exact finite-horizon curve under the periodic attack written as an automaton)
//! and on a Gilbert-Elliott channel with an offline pattern (a small exact propagation of the
//! law of (τ, c) written here), determinism across thread counts, the argument errors, and the
//! ignored throughput check.

use std::sync::atomic::{AtomicBool, AtomicU64};

use super::tables::{threshold63, Aliases};
use super::*;
use crate::{Attack, Schedule};

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

fn run(sys: &LinearSystem, cfg: &AutomatonConfig) -> Result<McResult> {
    simulate(sys, cfg, &AtomicBool::new(false), &AtomicU64::new(0))
}

fn t(p: f64, deliver: bool, next: usize) -> Transition {
    Transition { p, deliver, next }
}

/// PeriodicBlocking(r, t) as an automaton: the counter of genuine flag-ACKs modulo t, the first
/// r of every t blocked.
fn periodic(r: usize, period: usize) -> Attacker {
    Attacker {
        flag: (0..period)
            .map(|s| vec![t(1.0, s >= r, (s + 1) % period)])
            .collect(),
        quiet: (0..period).map(|s| vec![t(1.0, false, s)]).collect(),
        start: 0,
    }
}

/// A two-state on/off attacker: off, it lets flag-ACKs through and turns on at a flag-ACK with
/// probability 1/2; on, it blocks them and turns off on a quiet step with probability 0.2.
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

fn online(channel: MarkovChannel, attacker: Option<Attacker>) -> AutomatonConfig {
    AutomatonConfig {
        channel,
        sensor: Sensor::Online { z0: 2, mu: 1.0 },
        attacker,
        mode: Mode::Covariance,
        horizon: 1000,
        runs: 1024,
        seed: 7,
        record_runs: false,
    }
}

fn gilbert_elliott() -> MarkovChannel {
    MarkovChannel {
        p: vec![vec![0.9, 0.1], vec![0.3, 0.7]],
        low: vec![0.8, 0.2],
        high: vec![1.0, 0.9],
    }
}

/// The mass each entry of an alias table receives: its own share below its threshold plus
/// the shares of the columns that alias to it.
fn masses(al: &Aliases, dist: usize) -> Vec<f64> {
    let (off, n) = al.index[dist];
    let (off, n) = (off as usize, n as usize);
    let mut m = vec![0.0; n];
    for e in &al.entries[off..off + n] {
        let keep = e.thr as f64 / 2f64.powi(63);
        m[e.own as usize] += keep / n as f64;
        m[e.alt as usize] += (1.0 - keep) / n as f64;
    }
    m
}

/// Every alias table gives back its distribution (to rounding), zero entries included, and the
/// thresholds are exact at 0 and 1.
#[test]
fn alias_tables_reproduce_their_distributions() {
    assert_eq!(threshold63(0.0), 0);
    assert_eq!(threshold63(1.0), 1 << 63);
    assert_eq!(threshold63(0.5), 1 << 62);
    let dists: [&[f64]; 5] = [
        &[1.0],
        &[0.5, 0.5],
        &[0.1, 0.0, 0.6, 0.3],
        &[0.0, 1.0],
        &[0.01, 0.02, 0.03, 0.04, 0.9],
    ];
    let mut al = Aliases::default();
    for d in dists {
        let values: Vec<u64> = (0..d.len() as u64).collect();
        let i = al.push(d, &values);
        for (got, want) in masses(&al, i).iter().zip(d) {
            assert!((got - want).abs() < 1e-14, "{d:?}: {got} vs {want}");
        }
    }
}

/// The paper's channel under PeriodicBlocking(1, 5) as an automaton: the per-step mean trace
/// follows the exact finite-horizon curve and J_H its mean, within 4 standard errors, and the
/// flag counts the exact stationary rates to a loose tolerance.
#[test]
fn periodic_attack_matches_the_exact_curve() {
    let sys = paper();
    let cfg = online(MarkovChannel::bernoulli(0.5), Some(periodic(1, 5)));
    let res = run(&sys, &cfg).unwrap();
    let design = crate::OnlineDesign::fixed(2).unwrap();
    let attack = Attack::periodic(1, 5).unwrap();
    let curve = sys
        .expected_trace_curve(0.5, Schedule::Online(design), Some(&attack), cfg.horizon)
        .unwrap();
    let exact = curve.iter().sum::<f64>() / cfg.horizon as f64;
    assert!(
        (res.j - exact).abs() < 4.0 * res.stderr,
        "{} ± {} vs {exact}",
        res.j,
        res.stderr
    );
    // Step k's Tr P_k takes a few values (tr_0.. tr_6); its spread is at most tr_6.
    let tr6 = sys.h_traces(6)[6];
    let se = tr6 / (cfg.runs as f64).sqrt();
    for (k, (m, e)) in res.mean_trace.iter().zip(&curve).enumerate() {
        assert!((m - e).abs() < 4.5 * se, "k = {k}: {m} vs {e}");
    }
    // Step 1 is high power: τ_1 = 0 in every run.
    assert!((res.mean_trace[0] - sys.h_traces(0)[0]).abs() < 1e-12);
    let rates = crate::flag_rates(0.5, design, Some(&attack)).unwrap();
    assert!((res.flags_sent - rates.sent).abs() < 0.01, "{res:?}");
    assert!((res.flags_blocked - rates.sent / 5.0).abs() < 0.01);
    assert_eq!(res.flags_forged, 0.0);
    assert!((res.high_power_rate - rates.delivered).abs() < 0.01);
    let j = sys.j_attack(0.5, design, &attack).unwrap();
    assert!(
        (res.j - j).abs() < 4.0 * res.stderr + 2e-3,
        "{} vs {j}",
        res.j
    );
}

/// The exact E Tr P_k, k = 1..horizon, of an offline pattern on a Markov channel: the law of
/// (τ, c) propagated step by step (indexed loops: the law is indexed by state, as in the text).
#[allow(clippy::needless_range_loop)]
fn offline_curve(sys: &LinearSystem, ch: &MarkovChannel, pattern: &[bool], h: usize) -> Vec<f64> {
    let k = ch.p.len();
    let tr = sys.h_traces(h);
    // c_1's stationary law by power iteration (the channel mixes fast).
    let mut pi = vec![1.0 / k as f64; k];
    for _ in 0..10_000 {
        pi = (0..k)
            .map(|j| (0..k).map(|i| pi[i] * ch.p[i][j]).sum())
            .collect();
    }
    let mut law = vec![vec![0.0; k]; h + 1]; // law[τ][c] before the step
    law[0] = pi;
    let mut out = Vec::with_capacity(h);
    for step in 0..h {
        let high = pattern[step % pattern.len()];
        let mut next = vec![vec![0.0; k]; h + 1];
        let mut e = 0.0;
        for tau in 0..h {
            for c in 0..k {
                let w = law[tau][c];
                if w == 0.0 {
                    continue;
                }
                let pa = if high { ch.high[c] } else { ch.low[c] };
                e += w * (pa * tr[0] + (1.0 - pa) * tr[tau + 1]);
                for c2 in 0..k {
                    next[0][c2] += w * pa * ch.p[c][c2];
                    next[tau + 1][c2] += w * (1.0 - pa) * ch.p[c][c2];
                }
            }
        }
        out.push(e);
        law = next;
    }
    out
}

/// An offline pattern that starts low on a Gilbert-Elliott channel: J_H and the per-step mean
/// trace against the exact propagation, the high-power rate exactly the pattern's, no flags.
#[test]
fn offline_pattern_on_a_markov_channel_matches_the_exact_law() {
    let sys = paper();
    let ch = gilbert_elliott();
    let pattern = vec![false, true, false, false];
    let cfg = AutomatonConfig {
        sensor: Sensor::Offline {
            pattern: pattern.clone(),
        },
        horizon: 300,
        runs: 2048,
        seed: 11,
        ..online(ch.clone(), None)
    };
    let res = run(&sys, &cfg).unwrap();
    let curve = offline_curve(&sys, &ch, &pattern, cfg.horizon);
    let exact = curve.iter().sum::<f64>() / cfg.horizon as f64;
    assert!(
        (res.j - exact).abs() < 4.0 * res.stderr,
        "{} ± {} vs {exact}",
        res.j,
        res.stderr
    );
    assert_eq!(res.high_power_rate, 0.25);
    assert_eq!((res.flags_sent, res.flags_forged), (0.0, 0.0));
    let tr = sys.h_traces(cfg.horizon);
    for (k, (m, e)) in res.mean_trace.iter().zip(&curve).enumerate().take(40) {
        // Tr P_k <= tr_k: the spread of step k's value is below that.
        let se = tr[k + 1] / (cfg.runs as f64).sqrt();
        assert!((m - e).abs() < 4.5 * se, "k = {k}: {m} vs {e}");
    }
}

/// The same seed gives the same result bit for bit on one thread and on three, a partial last
/// block included; another seed gives another; recording matches the flag counts.
#[test]
fn deterministic_whatever_the_thread_count() {
    let sys = paper();
    let cfg = AutomatonConfig {
        runs: 700,
        horizon: 200,
        record_runs: true,
        sensor: Sensor::Online { z0: 2, mu: 0.4 },
        ..online(gilbert_elliott(), Some(on_off()))
    };
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let a = pool(1).install(|| run(&sys, &cfg)).unwrap();
    let b = pool(3).install(|| run(&sys, &cfg)).unwrap();
    assert_eq!(a, b);
    let c = run(
        &sys,
        &AutomatonConfig {
            seed: 8,
            ..cfg.clone()
        },
    )
    .unwrap();
    assert_ne!(a.j, c.j);
    assert_eq!(a.delivered_per_run.len(), 700);
    let delivered: u64 = a.delivered_per_run.iter().sum();
    let steps = 700.0 * 200.0;
    let rate = a.flags_sent - a.flags_blocked + a.flags_forged;
    assert!((delivered as f64 / steps - rate).abs() < 1e-12);
    assert!(a.flags_blocked > 0.0 && a.stderr.is_finite());
}

fn err_arg(r: Result<McResult>) -> String {
    match r {
        Err(Error::InvalidArgument { arg, .. }) | Err(Error::TooLarge { arg, .. }) => arg,
        other => panic!("expected an argument error, got {other:?}"),
    }
}

/// Each bad input is refused with an error naming its argument.
#[test]
fn bad_inputs_name_the_argument() {
    let sys = paper();
    let base = online(gilbert_elliott(), Some(on_off()));
    let with_channel = |f: &dyn Fn(&mut MarkovChannel)| {
        let mut cfg = base.clone();
        f(&mut cfg.channel);
        err_arg(run(&sys, &cfg))
    };
    assert_eq!(with_channel(&|c| c.p[0] = vec![0.5, 0.6]), "P");
    assert_eq!(with_channel(&|c| c.p[1] = vec![1.0]), "P");
    assert_eq!(with_channel(&|c| c.p = vec![]), "P");
    assert_eq!(with_channel(&|c| c.p[0] = vec![1.5, -0.5]), "P");
    // Two closed classes: no unique stationary law.
    assert_eq!(
        with_channel(&|c| c.p = vec![vec![1.0, 0.0], vec![0.0, 1.0]]),
        "P"
    );
    assert_eq!(with_channel(&|c| c.low = vec![0.5]), "low");
    assert_eq!(with_channel(&|c| c.high[1] = f64::NAN), "high");
    let with_attacker = |f: &dyn Fn(&mut Attacker)| {
        let mut cfg = base.clone();
        f(cfg.attacker.as_mut().unwrap());
        err_arg(run(&sys, &cfg))
    };
    assert_eq!(with_attacker(&|a| a.flag[0][0].p = 0.4), "flag");
    assert_eq!(with_attacker(&|a| a.flag[1][0].next = 2), "flag");
    assert_eq!(with_attacker(&|a| a.quiet[0].clear()), "quiet");
    assert_eq!(
        with_attacker(&|a| a.quiet.pop().map(|_| ()).unwrap()),
        "quiet"
    );
    assert_eq!(with_attacker(&|a| a.start = 2), "start");
    assert_eq!(
        with_attacker(&|a| (a.flag, a.quiet) = (vec![], vec![])),
        "flag"
    );
    let with = |f: &dyn Fn(&mut AutomatonConfig)| {
        let mut cfg = base.clone();
        f(&mut cfg);
        err_arg(run(&sys, &cfg))
    };
    assert_eq!(
        with(&|c| c.sensor = Sensor::Online { z0: 0, mu: 1.0 }),
        "z0"
    );
    assert_eq!(
        with(&|c| c.sensor = Sensor::Online { z0: 2, mu: 1.5 }),
        "mu"
    );
    let empty = Sensor::Offline { pattern: vec![] };
    assert_eq!(with(&|c| c.sensor = empty.clone()), "offline");
    assert_eq!(with(&|c| c.horizon = 0), "horizon");
    assert_eq!(with(&|c| c.runs = 0), "runs");
}

/// A set cancel flag stops the run with [`Error::Interrupted`].
#[test]
fn cancel_interrupts() {
    let cfg = online(gilbert_elliott(), Some(on_off()));
    let r = simulate(&paper(), &cfg, &AtomicBool::new(true), &AtomicU64::new(0));
    assert_eq!(r, Err(Error::Interrupted));
}

/// Huge holding times cost no memory: with every flag-ACK blocked on a channel that almost
/// never delivers, the traces overflow, J and its standard error are +inf (never NaN), and the
/// table stopped where it settled.
#[test]
fn overflowing_traces_give_inf() {
    let sys = paper();
    let ch = MarkovChannel::bernoulli(1e-4);
    let block_all = Attacker {
        flag: vec![vec![t(1.0, false, 0)]],
        quiet: vec![vec![t(1.0, false, 0)]],
        start: 0,
    };
    let cfg = AutomatonConfig {
        horizon: 20_000,
        runs: 8,
        ..online(ch, Some(block_all))
    };
    let plan = Plan::new(&sys, &cfg).unwrap();
    assert!(plan.tr.len() < 3000 && plan.tr.last().unwrap().is_infinite());
    let res = run(&sys, &cfg).unwrap();
    assert!(res.j.is_infinite() && res.stderr.is_infinite());
    assert!(res.mean_trace.iter().all(|x| !x.is_nan()));
}

/// Throughput on the paper's example under the two-state on/off attacker, 10^5 runs × 10^3
/// steps on two threads:
/// `cargo test --release --lib automaton::tests::speed -- --ignored --nocapture`.
#[test]
#[ignore]
fn speed() {
    let sys = paper();
    let threads = std::env::var("MC_SPEED_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    for (name, ch) in [
        ("bernoulli", MarkovChannel::bernoulli(0.5)),
        ("gilbert-elliott", gilbert_elliott()),
    ] {
        let cfg = AutomatonConfig {
            runs: 100_000,
            horizon: 1000,
            ..online(ch, Some(on_off()))
        };
        let mut best = 0.0f64;
        let mut j = 0.0;
        for _ in 0..3 {
            let t0 = std::time::Instant::now();
            j = pool.install(|| run(&sys, &cfg)).unwrap().j;
            best = best.max(1e8 / t0.elapsed().as_secs_f64());
        }
        println!("automaton {name} on/off: {best:.3e} steps/s ({threads} threads; j = {j:.6})");
    }
}

/// The plain and the AVX2 builds of the kernel give the same results bit for bit (where the CPU
/// has AVX2), on each of its instantiations.
#[test]
fn plain_and_avx2_builds_agree() {
    let Some(token) = crate::montecarlo::cpu::Avx2::detect() else {
        return;
    };
    let sys = paper();
    let sensors = [
        Sensor::Online { z0: 2, mu: 1.0 },
        Sensor::Online { z0: 2, mu: 0.3 },
        Sensor::Offline {
            pattern: vec![true, false, false],
        },
    ];
    for ch in [MarkovChannel::bernoulli(0.5), gilbert_elliott()] {
        for sensor in &sensors {
            let cfg = AutomatonConfig {
                sensor: sensor.clone(),
                runs: 300,
                horizon: 100,
                ..online(ch.clone(), Some(on_off()))
            };
            let (cancel, progress) = (AtomicBool::new(false), AtomicU64::new(0));
            let plain = simulate_on(&sys, &cfg, &cancel, &progress, None).unwrap();
            let avx2 = simulate_on(&sys, &cfg, &cancel, &progress, Some(token)).unwrap();
            assert_eq!(plain, avx2);
        }
    }
}
