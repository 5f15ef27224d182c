//! Criterion benchmarks of the numerical core (no Python).
//!
//! ```text
//! CARGO_TARGET_DIR=/tmp/target-bench cargo bench --bench core             # everything, a few minutes
//! CARGO_TARGET_DIR=/tmp/target-bench cargo bench --bench core -- pbar     # one group (a regex filter)
//! ```
//!
//! Groups, one benchmark per size:
//! * `pbar/n_x=..`: `LinearSystem::new` (validation, Riccati doubling, the stabilising check) on a
//!   fixed pseudo-random system, n_x = 1, 10, 50, 200;
//! * `stationary/S=..`: `stationary::structured` plus J (`weighted_traces` + `stationary::j_attack`)
//!   on the paper's scalar system, |S| ≈ 1e4, 1e6, 1e7;
//! * `sweep/t_max=..`: `Segments::for_system` + `sweep::sweep`, t_max = 1e3, 1e4 (the paper's online
//!   schedule, λ = 0.5, z0 = 2, μ = 1);
//! * `random_sweep/..`: `LinearSystem::j_random_sweep`, J under independent blocking at 10⁴ budgets
//!   β on the paper's online schedule (λ = 0.5, z0 = 2, μ = 1 and 0.5), traces included;
//! * `montecarlo/..`: `montecarlo::simulate`, covariance and state modes, paper's system, online
//!   z0 = 2 under the attack "first 1 of every 5", and covariance mode under independent blocking
//!   (β = 0.2) and forged flags (γ = 0.05), and under "first 1 of every 5" on the Gilbert-Elliott
//!   channels GE(0.2, 0.2, 1, 0) and GE(0.1, 0.3, 0.9, 0.2) (the bit-sliced kernel's channel
//!   plane); throughput in simulated steps (runs × horizon);
//! * `automaton/..`: `montecarlo::automaton::simulate`, the per-run Monte Carlo of an attacker
//!   automaton, on the paper's example (λ = 0.5, z0 = 2, μ = 1) and on a Gilbert-Elliott channel,
//!   under a two-state on/off attacker, covariance mode (and state mode on the Gilbert-Elliott
//!   channel, 10^4 runs); throughput in simulated steps;
//! * `game/..`: `LinearSystem::simulate_game`, the closed loop with the sensor's count test in it
//!   (bounds at about 2.6 standard deviations of the attack-free count of a 1000-step window, two
//!   offline windows after any alarm; offline schedule 1/7), under the attack "first 1 of every
//!   5" and rate matching (β = 0.2, γ = 0.0365) (the bit-sliced kernel), and under mimicry (an
//!   attacker automaton, the lane kernel); throughput in simulated steps;
//! * `markov/..`: `engine::markov::beta_sweep`, every r/t under `GilbertElliott(0.1, 0.1, 1, 0)`
//!   with the design that meets the budget 1/7 there (z0 = 2, μ = 0.5785), t_max = 60 and 1000.
//!
//! Sample counts are criterion's minimum (10) with short measurement windows so that the whole file
//! runs in a few minutes; the machine is usually shared, so read the numbers as indicative.

use std::hint::black_box;
use std::sync::atomic::{AtomicBool, AtomicU64};
use std::time::Duration;

use criterion::{
    criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput,
};
use nalgebra::DMatrix;

use fakeack::chain::{self, AttackChain};
use fakeack::montecarlo::game::{Detector, GameConfig, Policy};
use fakeack::montecarlo::{self, McConfig, McSchedule, Mode, Protocol, TwoStateChannel};
use fakeack::online::OnlineDesign;
use fakeack::pattern::Segments;
use fakeack::rng::SplitMix64;
use fakeack::schedules::{offline_schedule, Ratio};
use fakeack::spectral::spectral_radius;
use fakeack::LinearSystem;
use fakeack::{stationary, sweep, Attack};
use fakeack::{Attacker, AttackerAutomaton, Channel, Engine, PowerSchedule, Scenario};

/// The paper's example: A = 1.2, C = 0.7, Q = R = 0.8, λ = 0.5.
const LAM: f64 = 0.5;

fn paper_system() -> LinearSystem {
    let m = |x: f64| DMatrix::from_element(1, 1, x);
    LinearSystem::new(m(1.2), m(0.7), m(0.8), m(0.8)).expect("paper system")
}

/// An attack chain of the benchmark: memory z0, r blocked of every t flag-ACKs.
struct ChainSize {
    /// The target number of states |S|.
    label: &'static str,
    z0: u64,
    r: u64,
    t: u64,
}

/// Chains with |S| = r(r+1)z0/2 + t(z0+1) within 1 of the target; half the states in the
/// growing levels σ <= r, half in the short ones (same table as benches/compare.py).
const CHAINS: [ChainSize; 3] = [
    ChainSize {
        label: "1e4",
        z0: 2,
        r: 70,
        t: 1_677,
    },
    ChainSize {
        label: "1e6",
        z0: 2,
        r: 700,
        t: 169_767,
    },
    ChainSize {
        label: "1e7",
        z0: 2,
        r: 2_236,
        t: 1_666_023,
    },
];

/// Pseudo-random test matrices from the crate's own SplitMix64 (no extra crate).
struct Rng(SplitMix64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed))
    }
    /// Uniform in (0, 1).
    fn uniform(&mut self) -> f64 {
        ((self.0.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    /// Standard normal (Box-Muller).
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
    fn matrix(&mut self, rows: usize, cols: usize) -> DMatrix<f64> {
        DMatrix::from_fn(rows, cols, |_, _| self.normal())
    }
}

/// A fixed pseudo-random system of dimension n: A scaled to spectral radius 1.05 (mildly unstable,
/// like the paper's), C with max(1, n/2) rows, Q = BB'/n + 0.1 I, R = DD'/m + 0.2 I.
fn random_system(n: usize) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let mut rng = Rng::new(0x5EED_0000 + n as u64);
    let m = (n / 2).max(1);
    let mut a = rng.matrix(n, n);
    let rho = spectral_radius(&a).expect("eigenvalues");
    a *= 1.05 / rho;
    let c = rng.matrix(m, n);
    let b = rng.matrix(n, n);
    let q = &b * b.transpose() / n as f64 + DMatrix::identity(n, n) * 0.1;
    let d = rng.matrix(m, m);
    let r = &d * d.transpose() / m as f64 + DMatrix::identity(m, m) * 0.2;
    (a, c, q, r)
}

fn bench_pbar(c: &mut Criterion) {
    let mut g = c.benchmark_group("pbar");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for n in [1usize, 10, 50, 200] {
        let sys = random_system(n);
        // Fail loudly here rather than time an error path.
        let check = LinearSystem::new(sys.0.clone(), sys.1.clone(), sys.2.clone(), sys.3.clone())
            .expect("random system is detectable");
        assert!(
            check.residual() < 1e-9,
            "n = {n}: residual {}",
            check.residual()
        );
        if n == 200 {
            g.sampling_mode(SamplingMode::Flat);
        }
        g.bench_with_input(
            BenchmarkId::new("LinearSystem::new", format!("n_x={n}")),
            &sys,
            |b, s| {
                b.iter_batched(
                    || s.clone(),
                    |(a, cm, q, r)| black_box(LinearSystem::new(a, cm, q, r).unwrap()),
                    criterion::BatchSize::LargeInput,
                )
            },
        );
    }
    g.finish();
}

fn bench_stationary(c: &mut Criterion) {
    let sys = paper_system();
    let mut g = c.benchmark_group("stationary");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .sampling_mode(SamplingMode::Flat);
    for ChainSize { label, z0, r, t } in CHAINS {
        let ch = AttackChain::new(LAM, z0, r, t).unwrap();
        let n = chain::num_states(z0, r, t);
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(
            BenchmarkId::new("structured+j_attack", format!("S={label} ({n})")),
            &ch,
            |b, ch| {
                b.iter(|| {
                    let pi = stationary::structured(black_box(ch)).unwrap();
                    let w = sys.weighted_traces(1.0 - ch.lam, ((ch.z0 + 1) * (ch.r + 1)) as usize);
                    let j = stationary::j_attack(ch, &w).unwrap();
                    black_box((pi, j))
                })
            },
        );
    }
    g.finish();
}

fn bench_sweep(c: &mut Criterion) {
    let sys = paper_system();
    let mut g = c.benchmark_group("sweep");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(5))
        .sampling_mode(SamplingMode::Flat);
    for t_max in [1_000u64, 10_000] {
        let fractions = sweep::farey_count(t_max);
        g.throughput(Throughput::Elements(fractions as u64));
        g.bench_with_input(
            BenchmarkId::new("segments+sweep", format!("t_max={t_max}")),
            &t_max,
            |b, &tm| {
                b.iter(|| {
                    let design = fakeack::OnlineDesign::fixed(2).unwrap();
                    let seg = Segments::for_system(&sys, LAM, design, tm - 1).unwrap();
                    black_box(sweep::sweep(&seg, black_box(tm)).unwrap())
                })
            },
        );
    }
    g.finish();
}

fn bench_random_sweep(c: &mut Criterion) {
    let sys = paper_system();
    let mut g = c.benchmark_group("random_sweep");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .sampling_mode(SamplingMode::Flat);
    let betas: Vec<f64> = (0..10_000).map(|i| i as f64 / 10_000.0).collect();
    g.throughput(Throughput::Elements(betas.len() as u64));
    for mu in [1.0, 0.5] {
        let design = fakeack::OnlineDesign::new(2, mu).unwrap();
        g.bench_with_input(
            BenchmarkId::new("betas=1e4", format!("mu={mu}")),
            &design,
            |b, &d| {
                b.iter(|| black_box(sys.j_random_sweep(LAM, d, 0.0, black_box(&betas)).unwrap()))
            },
        );
    }
    g.finish();
}

fn mc_config(mode: Mode, runs: u64, horizon: usize, attack: Attack) -> McConfig {
    McConfig {
        channel: None,
        lam: LAM,
        schedule: McSchedule::Online { z0: 2, mu: 1.0 },
        attack: Some(attack),
        mode,
        protocol: Protocol::B,
        horizon,
        runs,
        seed: 1,
        record_runs: false,
    }
}

fn bench_montecarlo(c: &mut Criterion) {
    let sys = paper_system();
    let mut g = c.benchmark_group("montecarlo");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(4))
        .sampling_mode(SamplingMode::Flat);
    // Block the first r = 1 of every t = 5 flag-ACKs (the paper's attack), or the new attacks.
    let periodic = Attack::periodic(1, 5).expect("r < t");
    let random = Attack::Random { beta: 0.2 };
    let inject = Attack::Injection {
        gamma: 0.05,
        block: None,
    };
    for (name, mode, runs, horizon, attack) in [
        (
            "covariance",
            Mode::Covariance,
            65_536u64,
            1_000usize,
            periodic.clone(),
        ),
        ("state", Mode::State, 4_096, 1_000, periodic.clone()),
        (
            "covariance_random0.2",
            Mode::Covariance,
            65_536,
            1_000,
            random,
        ),
        (
            "covariance_inject0.05",
            Mode::Covariance,
            65_536,
            1_000,
            inject,
        ),
        (
            "covariance_ge0.2,0.2,1,0",
            Mode::Covariance,
            65_536,
            1_000,
            periodic.clone(),
        ),
        (
            "covariance_ge0.1,0.3,0.9,0.2",
            Mode::Covariance,
            65_536,
            1_000,
            periodic.clone(),
        ),
    ] {
        let mut cfg = mc_config(mode, runs, horizon, attack);
        if let Some(ge) = name.strip_prefix("covariance_ge") {
            // GE(0.2, 0.2, 1, 0), or GE(0.1, 0.3, 0.9, 0.2) with p ≠ q.
            cfg.channel = Some(if ge == "0.2,0.2,1,0" {
                TwoStateChannel {
                    p: 0.2,
                    q: 0.2,
                    low: [1.0, 0.0],
                }
            } else {
                TwoStateChannel {
                    p: 0.1,
                    q: 0.3,
                    low: [0.9, 0.2],
                }
            });
        }
        g.throughput(Throughput::Elements(runs * horizon as u64));
        g.bench_with_input(
            BenchmarkId::new(name, format!("{runs}x{horizon}")),
            &cfg,
            |b, cfg| {
                b.iter(|| {
                    let out = montecarlo::simulate(
                        &sys,
                        cfg,
                        &AtomicBool::new(false),
                        &AtomicU64::new(0),
                    )
                    .unwrap();
                    black_box(out.j)
                })
            },
        );
    }
    g.finish();
}

fn bench_automaton(c: &mut Criterion) {
    use fakeack::montecarlo::automaton::{
        self, Attacker, AutomatonConfig, MarkovChannel, Sensor, Transition,
    };
    let sys = paper_system();
    let mut g = c.benchmark_group("automaton");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(4))
        .sampling_mode(SamplingMode::Flat);
    let t = |p, deliver, next| Transition { p, deliver, next };
    // Off: let flag-ACKs through, turn on at one with probability 1/2; on: block them, turn off
    // on a quiet step with probability 0.2.
    let on_off = Attacker {
        flag: vec![
            vec![t(0.5, true, 0), t(0.5, false, 1)],
            vec![t(1.0, false, 1)],
        ],
        quiet: vec![
            vec![t(1.0, false, 0)],
            vec![t(0.8, false, 1), t(0.2, false, 0)],
        ],
        start: 0,
    };
    let gilbert_elliott = MarkovChannel {
        p: vec![vec![0.9, 0.1], vec![0.3, 0.7]],
        low: vec![0.9, 0.2],
        high: vec![1.0, 1.0],
    };
    for (name, channel, mode, runs) in [
        (
            "paper_on_off",
            MarkovChannel::bernoulli(LAM),
            Mode::Covariance,
            100_000u64,
        ),
        (
            "gilbert_elliott_on_off",
            gilbert_elliott.clone(),
            Mode::Covariance,
            100_000,
        ),
        (
            "gilbert_elliott_on_off_state",
            gilbert_elliott,
            Mode::State,
            10_000,
        ),
    ] {
        let horizon = 1_000usize;
        let cfg = AutomatonConfig {
            channel,
            sensor: Sensor::Online { z0: 2, mu: 1.0 },
            attacker: Some(on_off.clone()),
            mode,
            horizon,
            runs,
            seed: 1,
            record_runs: false,
        };
        g.throughput(Throughput::Elements(runs * horizon as u64));
        g.bench_with_input(
            BenchmarkId::new(name, format!("{runs}x{horizon}")),
            &cfg,
            |b, cfg| {
                b.iter(|| {
                    let out =
                        automaton::simulate(&sys, cfg, &AtomicBool::new(false), &AtomicU64::new(0))
                            .unwrap();
                    black_box(out.j)
                })
            },
        );
    }
    g.finish();
}

fn bench_game(c: &mut Criterion) {
    let sys = paper_system();
    let mut g = c.benchmark_group("game");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(4))
        .sampling_mode(SamplingMode::Flat);
    let design = OnlineDesign::fixed(2).expect("z0 >= 1");
    let free = fakeack::flag_rates(LAM, design, None)
        .expect("valid")
        .delivered
        * 1000.0;
    let policy = Policy::Test {
        detector: Detector::Count {
            lo: (free - 40.0) as i64,
            hi: (free + 40.0) as i64,
        },
        harmful_at_most: None,
        fallback: 2,
        min_gap: 0,
    };
    let rate_matching =
        Attack::injection(0.0365, Some(Attack::random(0.2).expect("beta"))).expect("gamma");
    let mimicry =
        AttackerAutomaton::mimicry(&Channel::bernoulli(LAM).expect("lam"), design).expect("design");
    for (name, attack, automaton) in [
        (
            "count_periodic1/5",
            Some(Attack::periodic(1, 5).expect("r < t")),
            None,
        ),
        ("count_rate_matching0.2", Some(rate_matching), None),
        ("count_mimicry", None, Some(mimicry)),
    ] {
        let (runs, horizon) = (8_192u64, 20_000u64);
        let cfg = GameConfig {
            lam: LAM,
            channel: None,
            design,
            offline: offline_schedule(Ratio::new(1, 7).expect("ratio")).expect("pattern"),
            attack,
            automaton,
            policy: policy.clone(),
            window: 1000,
            horizon,
            burn_in: 0,
            runs,
            seed: 1,
        };
        g.throughput(Throughput::Elements(runs * horizon));
        g.bench_with_input(
            BenchmarkId::new(name, format!("{runs}x{horizon}")),
            &cfg,
            |b, cfg| b.iter(|| black_box(sys.simulate_game(cfg).unwrap().cost[0])),
        );
    }
    g.finish();
}

/// The general exact engine: the paper's scenario with construction, a Gilbert-Elliott channel
/// under a long blocking period (5,800, ~10^4 and ~7 10^5 states, scalar) and n_x = 10 on ~10^3
/// states.
fn bench_engine(c: &mut Criterion) {
    let mut g = c.benchmark_group("engine");
    let sys = paper_system();
    let design = OnlineDesign::fixed(2).unwrap();
    g.bench_function("paper_scenario_cost_with_construction", |b| {
        b.iter(|| {
            let s = Scenario::new(
                sys.clone(),
                Channel::bernoulli(black_box(0.5)).unwrap(),
                PowerSchedule::Online(design),
                Attacker::attack(Attack::periodic(1, 5).unwrap()),
            )
            .unwrap();
            black_box(s.cost().unwrap())
        })
    });
    let ge = Channel::gilbert_elliott(0.1, 0.4, 0.7, 0.2, 1.0, 1.0).unwrap();
    let sched = PowerSchedule::Online(design);
    for t in [1000u64, 1720, 125_000] {
        let attacker = Attacker::attack(Attack::periodic(t / 10, t).unwrap());
        let n = Engine::new(&ge, &sched, &attacker, 10_000_000)
            .unwrap()
            .n_states();
        if t > 10_000 {
            g.sample_size(10);
            g.measurement_time(Duration::from_secs(20));
        }
        g.bench_function(
            BenchmarkId::new("gilbert_elliott_cost", format!("{n}_states")),
            |b| {
                b.iter(|| {
                    let e = Engine::new(&ge, &sched, &attacker, 10_000_000).unwrap();
                    black_box(e.cost(&sys).unwrap())
                })
            },
        );
    }
    g.sample_size(20);
    let (a, cm, q, r) = random_system(10);
    let sys10 = LinearSystem::new(a, cm, q, r).unwrap();
    let bern = Channel::bernoulli(0.6).unwrap();
    let attacker = Attacker::attack(Attack::periodic(60, 250).unwrap());
    let e = Engine::new(&bern, &sched, &attacker, 1_000_000).unwrap();
    let _ = e.stationary_residual().unwrap();
    g.bench_function(
        BenchmarkId::new("n_x_10_cost", format!("{}_states", e.n_states())),
        |b| b.iter(|| black_box(e.cost(&sys10).unwrap())),
    );
    g.finish();
}

/// The β sweep under a Gilbert-Elliott channel by the Markov renewal.
fn bench_markov(c: &mut Criterion) {
    let mut g = c.benchmark_group("markov");
    let sys = paper_system();
    let ge = Channel::gilbert_elliott(0.1, 0.1, 1.0, 0.0, 1.0, 1.0).unwrap();
    let design = OnlineDesign::new(2, 0.5785).unwrap();
    for t_max in [60u64, 1000] {
        if t_max > 100 {
            g.sample_size(10);
        }
        g.bench_function(
            BenchmarkId::new("beta_sweep", format!("t_max={t_max}")),
            |b| {
                b.iter(|| {
                    black_box(
                        fakeack::engine::markov::beta_sweep(&sys, &ge, design, t_max, None)
                            .unwrap(),
                    )
                })
            },
        );
    }
    g.finish();
}

criterion_group!(
    benches,
    bench_pbar,
    bench_stationary,
    bench_sweep,
    bench_random_sweep,
    bench_montecarlo,
    bench_automaton,
    bench_game,
    bench_engine,
    bench_markov
);
criterion_main!(benches);
