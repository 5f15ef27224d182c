//! The bit-sliced game kernel against a plain per-lane simulation driven by the same random
//! words, its AVX2 build against its portable one, and the plans it refuses.
//!
//! The plain simulation keeps one integer state per run and follows the lane kernel's protocol
//! (`tile.rs`); it shares with the sliced kernel only the order of the draws: per step, λ for
//! the low-power lanes, μ for the lanes whose zero count is exactly z0, β (two decisions drawn
//! ahead per lane, refilled when a flag finds its lane without one), γ for the lanes without a
//! flag, each one `Rng4::bernoulli` call over the block's [`RUNS`] lanes.

use std::collections::VecDeque;

use super::*;
use crate::montecarlo::bitslice::words::{from_lanes, lane, ONES, ZERO};
use crate::montecarlo::game::GameConfig;
use crate::schedule::OnlineDesign;
use crate::system::LinearSystem;

/// A Bernoulli(p) draw for the lanes of `need`; a sure one (p >= 1) draws nothing.
fn draw(rng: &mut Rng4, p: f64, need: W) -> W {
    if p >= 1.0 {
        need
    } else {
        rng.bernoulli(Portable, bernoulli_threshold(p), need)
    }
}

/// The first result and lane where the kernel's results `got` differ from `want`.
fn first_difference(got: &SlicedOut, want: &SlicedOut) -> Option<String> {
    if let Some(l) = (0..RUNS).find(|&l| got.cost[l] != want.cost[l]) {
        let (g, w) = (got.cost[l], want.cost[l]);
        return Some(format!("cost, lane {l}: kernel {g}, plain {w}"));
    }
    let counts = |o: &SlicedOut| {
        let names = "high online_steps delivered tested alarms fallbacks".split(' ');
        names.zip([
            o.high,
            o.online_steps,
            o.delivered,
            o.tested,
            o.alarms,
            o.fallbacks,
        ])
    };
    for ((name, g), (_, w)) in counts(got).zip(counts(want)) {
        if let Some(l) = (0..RUNS).find(|&l| g[l] != w[l]) {
            return Some(format!("{name}, lane {l}: kernel {}, plain {}", g[l], w[l]));
        }
    }
    None
}

/// One run of the plain simulation.
#[derive(Clone, Default)]
struct Run {
    tau: usize,
    /// The detector's zero count.
    z: usize,
    /// The attacker's flag counter (a blocking mask).
    sigma: usize,
    /// Steps since the last flag-ACK that reached the sensor.
    gap: usize,
    /// A flag-ACK reached the sensor on the last step.
    pending: bool,
    online: bool,
    /// Online since the last flag-ACK that reached the sensor: its next gap is checked.
    armed: bool,
    /// The window had a gap shorter than `min_gap`.
    short: bool,
    /// Offline windows left.
    left: u64,
    /// Position in the offline pattern.
    pos: usize,
    count: i64,
    bins: Vec<u64>,
    /// β decisions for the next flags, drawn ahead.
    ahead: VecDeque<bool>,
    /// Measured steps with τ = j, j < D.
    hist: Vec<u64>,
    /// Measured steps with τ >= D, and their Σ tr[τ] in order.
    deep_steps: u64,
    deep_sum: f64,
}

/// One block of `plan` simulated run by run, with thermometer depth `depth` (the kernel's
/// summation order of the costs); also the measured steps with τ >= depth, over all lanes.
fn plain(plan: &Plan<'_>, depth: usize, block: u64) -> (SlicedOut, u64) {
    let cfg = plan.cfg;
    let (pattern, traces, z0) = (&cfg.offline, &plan.traces, cfg.design.z0 as usize);
    let gamma = cfg.attack.as_ref().map_or(0.0, Attack::forging);
    let (mut mask, mut beta) = (None, None);
    match cfg.attack.as_ref().and_then(Attack::genuine_blocking) {
        None => {}
        Some(Attack::Random { beta: b }) => beta = Some(*b),
        Some(a) => mask = Some(a.blocking_mask().unwrap().into_owned()),
    }
    let edges: &[u64] = match &cfg.policy {
        Policy::Test {
            detector: Detector::Interval { edges, .. },
            ..
        } => edges,
        _ => &[],
    };
    let min_gap = match cfg.policy {
        Policy::Test { min_gap, .. } => min_gap as usize,
        _ => 0,
    };
    let start = Run {
        pending: true,
        online: !matches!(cfg.policy, Policy::Offline),
        armed: !matches!(cfg.policy, Policy::Offline),
        bins: vec![0; edges.len()],
        hist: vec![0; depth],
        ..Run::default()
    };
    let mut runs = vec![start; RUNS];
    let mut out = SlicedOut::EMPTY;
    let mut rng = Rng4::for_block(cfg.seed, block);
    for k in 0..cfg.burn_in + cfg.horizon {
        let measured = k >= cfg.burn_in;
        let high: Vec<bool> = runs
            .iter()
            .map(|r| (r.online && r.pending) || (!r.online && pattern[r.pos] == 1))
            .collect();
        let lucky = draw(&mut rng, cfg.lam, from_lanes(|l| !high[l]));
        for (l, r) in runs.iter_mut().enumerate() {
            // (An online run's position is reset when it falls back.)
            r.pos = (r.pos + 1) % pattern.len();
            let arrive = high[l] || lane(&lucky, l);
            (r.tau, r.z) = if arrive { (0, 0) } else { (r.tau + 1, r.z + 1) };
            if measured && r.tau < depth {
                r.hist[r.tau] += 1;
            } else if measured {
                r.deep_steps += 1;
                r.deep_sum += traces[r.tau.min(traces.len() - 1)];
            }
        }
        // Memory z0 with probability μ (drawn where the count is exactly z0), else z0 + 1.
        let short = match cfg.design.mu {
            1.0 => ONES,
            mu => draw(&mut rng, mu, from_lanes(|l| runs[l].z == z0)),
        };
        let flag: Vec<bool> = (0..RUNS)
            .map(|l| runs[l].z > z0 || (runs[l].z == z0 && lane(&short, l)))
            .collect();
        if let Some(beta) = beta.filter(|&b| b < 1.0) {
            // Two decisions ahead per lane, refilled when a flag finds its lane without one.
            if (0..RUNS).any(|l| flag[l] && runs[l].ahead.is_empty()) {
                for want in 1..=2 {
                    let drawn = draw(&mut rng, beta, from_lanes(|l| runs[l].ahead.len() < want));
                    for (l, r) in runs
                        .iter_mut()
                        .enumerate()
                        .filter(|(_, r)| r.ahead.len() < want)
                    {
                        r.ahead.push_back(lane(&drawn, l));
                    }
                }
            }
        }
        let forged = match gamma {
            0.0 => ZERO,
            gamma => draw(&mut rng, gamma, from_lanes(|l| !flag[l])),
        };
        for (l, r) in runs.iter_mut().enumerate() {
            let blocked = flag[l]
                && match (&mask, beta) {
                    (Some(mask), _) => mask[r.sigma],
                    (None, Some(1.0)) => true,
                    (None, Some(_)) => r.ahead.pop_front().unwrap(),
                    (None, None) => false,
                };
            if flag[l] {
                r.z = 0;
                r.sigma = (r.sigma + 1) % mask.as_ref().map_or(1, Vec::len);
            }
            let delivered = (flag[l] && !blocked) || lane(&forged, l);
            r.pending = delivered;
            let gap = r.gap + 1;
            r.gap = if delivered { 0 } else { gap };
            if delivered && r.online {
                r.count += 1;
                // The last bin whose lower edge the gap reaches.
                if let Some(b) = edges.iter().rposition(|&e| e as usize <= gap) {
                    r.bins[b] += 1;
                }
                r.short |= r.armed && gap < min_gap;
                r.armed = true;
            }
            if measured {
                out.high[l] += u64::from(high[l]);
                out.online_steps[l] += u64::from(r.online);
                out.delivered[l] += u64::from(delivered);
            }
        }
        if (k + 1) % cfg.window == 0 {
            let counted = u64::from(k + 1 > cfg.burn_in);
            for (l, r) in runs.iter_mut().enumerate() {
                end_window(cfg, r, counted, &mut out, l);
            }
        }
    }
    for r in &runs {
        let bins = r.hist.iter().enumerate().filter(|&(_, &c)| c > 0);
        let cost = bins.fold(0.0, |s, (j, &c)| s + traces[j] * c as f64);
        out.cost.push(if r.deep_steps > 0 {
            cost + r.deep_sum
        } else {
            cost
        });
    }
    (out, runs.iter().map(|r| r.deep_steps).sum())
}

/// A full window's end for run `r` (lane `l`): its test if online, else one offline window less.
fn end_window(cfg: &GameConfig, r: &mut Run, counted: u64, out: &mut SlicedOut, l: usize) {
    if let Policy::Test {
        detector,
        harmful_at_most,
        fallback,
        ..
    } = &cfg.policy
    {
        if r.online {
            let n = r.count;
            let alarm = match detector {
                Detector::Count { lo, hi } => n <= *lo || n >= *hi,
                Detector::Likelihood { .. } => unreachable!("the lane kernel runs it"),
                Detector::Interval {
                    expected, critical, ..
                } => {
                    let mut x2 = 0.0;
                    for (e, &o) in expected.iter().zip(&r.bins) {
                        let d = o as f64 - e;
                        x2 += d * d / e;
                    }
                    x2 > *critical
                }
            };
            let alarm = alarm || r.short;
            out.tested[l] += counted;
            out.alarms[l] += counted * u64::from(alarm);
            if alarm && harmful_at_most.is_none_or(|b| n <= b) {
                out.fallbacks[l] += counted;
                if *fallback > 0 {
                    r.online = false;
                    r.armed = false;
                    r.left = *fallback;
                    r.pos = 0;
                }
            }
        } else {
            r.left -= 1;
            if r.left == 0 {
                r.online = true;
            }
        }
    }
    r.count = 0;
    r.short = false;
    r.bins.iter_mut().for_each(|b| *b = 0);
}

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

/// An offline pattern of `period` steps, high at the steps `ones`.
fn pattern(period: usize, ones: &[usize]) -> Vec<u8> {
    (0..period).map(|i| u8::from(ones.contains(&i))).collect()
}

fn count(lo: i64, hi: i64, harmful_at_most: Option<i64>, fallback: u64) -> Policy {
    Policy::Test {
        detector: Detector::Count { lo, hi },
        harmful_at_most,
        fallback,
        min_gap: 0,
    }
}

/// The interval test with edges 1, 2, 3, `last`: gap bins 1, 2, 3 to `last` - 1, `last` and above.
fn interval(last: u64, critical: f64, harmful_at_most: Option<i64>, fallback: u64) -> Policy {
    Policy::Test {
        detector: Detector::Interval {
            edges: vec![1, 2, 3, last],
            expected: vec![1.5, 2.0, 2.5, 3.0],
            critical,
        },
        harmful_at_most,
        fallback,
        min_gap: 0,
    }
}

/// A compared game, and whether some lane must reach τ >= D (the deep path).
struct Case {
    name: &'static str,
    cfg: GameConfig,
    deep: bool,
}

/// A game on the paper's system with λ, memory (z0, μ) and steps (window, horizon, burn-in):
/// online, unattacked, offline pattern 1001000 until set otherwise.
fn game(name: &'static str, lam: f64, (z0, mu): (u64, f64), steps: (u64, u64, u64)) -> Case {
    let cfg = GameConfig {
        lam,
        channel: None,
        design: OnlineDesign::new(z0, mu).unwrap(),
        offline: pattern(7, &[0, 3]),
        attack: None,
        automaton: None,
        policy: Policy::Online,
        window: steps.0,
        horizon: steps.1,
        burn_in: steps.2,
        runs: RUNS as u64,
        seed: 11,
    };
    Case {
        name,
        cfg,
        deep: false,
    }
}

impl Case {
    fn offline(mut self, pattern: Vec<u8>) -> Self {
        self.cfg.offline = pattern;
        self
    }

    fn attack(mut self, attack: Attack) -> Self {
        self.cfg.attack = Some(attack);
        self
    }

    fn policy(mut self, policy: Policy) -> Self {
        self.cfg.policy = policy;
        self
    }

    fn deep(mut self) -> Self {
        self.deep = true;
        self
    }

    /// The policy's support check at `gap`.
    fn support(mut self, gap: u64) -> Self {
        if let Policy::Test { min_gap, .. } = &mut self.cfg.policy {
            *min_gap = gap;
        }
        self
    }
}

fn cases() -> Vec<Case> {
    let two_runs = Attack::mask(vec![true, true, false, false, true, false, false]).unwrap();
    let random = |beta| Attack::random(beta).unwrap();
    let inject = |gamma, block| Attack::injection(gamma, block).unwrap();
    let offline = Policy::Offline;
    vec![
        game("online", 0.5, (2, 1.0), (100, 500, 0)),
        game("offline, burn-in", 0.3, (2, 1.0), (64, 500, 37)).policy(offline.clone()),
        game("offline, D = 32", 0.1, (2, 1.0), (100, 800, 0))
            .offline(pattern(40, &[0]))
            .policy(offline.clone())
            .deep(),
        game("offline, D = 8", 0.65, (2, 1.0), (50, 1000, 0))
            .offline(pattern(20, &[0]))
            .policy(offline)
            .deep(),
        game("count, fallback 1", 0.5, (2, 1.0), (30, 600, 45)).policy(count(2, 7, None, 1)),
        game("count, harmful, f 3", 0.5, (2, 0.4), (40, 700, 60))
            .attack(Attack::periodic(1, 3).unwrap())
            .policy(count(1, 5, Some(1), 3)),
        game("count, harmful, f 0", 0.5, (2, 1.0), (40, 600, 0))
            .attack(two_runs)
            .policy(count(1, 5, Some(5), 0)),
        game("count, f 2^40", 0.5, (2, 1.0), (40, 400, 0)).policy(count(2, 6, None, 1 << 40)),
        game("interval, β", 0.5, (2, 1.0), (20, 600, 10))
            .attack(random(0.3))
            .policy(interval(5, 6.0, None, 2)),
        game("interval, harmful, γ", 0.5, (2, 0.4), (20, 600, 10))
            .offline(pattern(6, &[0, 2]))
            .attack(inject(0.1, None))
            .policy(interval(5, 6.0, Some(4), 1)),
        game("count, β and γ, deep", 0.15, (2, 0.4), (30, 1000, 100))
            .offline(pattern(40, &[0]))
            .attack(inject(0.02, Some(random(0.8))))
            .policy(count(1, 4, Some(4), 3))
            .deep(),
        game("online, β, deep", 0.2, (2, 1.0), (100, 1200, 0))
            .attack(random(0.9))
            .deep(),
        game("sure β and γ", 0.5, (3, 1.0), (100, 300, 5)).attack(inject(1.0, Some(random(1.0)))),
        // The support check alone (a count test that never alarms), with the straddling gaps
        // and the first gap back online; beside an interval test whose last edge is below
        // `min_gap`, and one whose last edge is above it; a μ < 1 memory; the harmful rule.
        game("support, f 2", 0.5, (2, 1.0), (30, 900, 45))
            .attack(inject(0.01, None))
            .policy(count(-1, 1 << 40, None, 2))
            .support(3),
        game("support, interval, f 1", 0.5, (4, 1.0), (25, 800, 10))
            .attack(inject(0.01, Some(random(0.3))))
            .policy(interval(4, 1e9, None, 1))
            .support(5),
        game("support, interval above", 0.5, (2, 0.4), (20, 600, 0))
            .attack(inject(0.01, None))
            .policy(interval(6, 8.0, None, 1))
            .support(3),
        game("support, harmful, f 0", 0.4, (2, 1.0), (30, 600, 0))
            .attack(inject(0.02, None))
            .policy(count(-1, 1 << 40, Some(3), 0))
            .support(3),
    ]
}

/// Block `block` of `plan` on the kernel: portable, or AVX2 with the token.
fn kernel(plan: &Plan<'_>, block: u64, avx2: Option<Avx2>) -> SlicedOut {
    let s = Sliced::of(plan).unwrap();
    run_block(&s, plan, block, avx2, &AtomicBool::new(false)).unwrap()
}

#[test]
fn sliced_kernel_matches_the_plain_simulation() {
    let sys = paper();
    for (i, c) in cases().iter().enumerate() {
        let plan = Plan::new(&sys, &c.cfg).unwrap();
        let got = kernel(&plan, i as u64, None);
        let (want, deep) = plain(&plan, Sliced::of(&plan).unwrap().depth, i as u64);
        if let Some(diff) = first_difference(&got, &want) {
            panic!("{}: {diff}", c.name);
        }
        // The case exercises what it is meant to: some tested windows alarm and some do not,
        // the harmful rule lets some alarms pass, the deep path is taken.
        if let Policy::Test {
            harmful_at_most, ..
        } = c.cfg.policy
        {
            let sum = |v: [u64; RUNS]| v.iter().sum::<u64>();
            let (tested, alarms) = (sum(want.tested), sum(want.alarms));
            assert!(
                0 < alarms && alarms < tested,
                "{}: {alarms} of {tested}",
                c.name
            );
            let fallbacks = sum(want.fallbacks);
            assert!(fallbacks > 0, "{}", c.name);
            assert_eq!(fallbacks < alarms, harmful_at_most.is_some(), "{}", c.name);
        }
        assert_eq!(deep > 0, c.deep, "{}: {deep} steps at τ >= D", c.name);
    }
}

/// The AVX2 build is the same computation as the portable one, bit for bit.
#[test]
fn avx2_build_matches_the_portable_build() {
    let Some(avx2) = Avx2::detect() else {
        eprintln!("SKIPPED: this CPU has no AVX2, so the AVX2 build was not checked");
        return;
    };
    let sys = paper();
    for (i, c) in cases().iter().enumerate() {
        let plan = Plan::new(&sys, &c.cfg).unwrap();
        let portable = kernel(&plan, i as u64, None);
        let vector = kernel(&plan, i as u64, Some(avx2));
        if let Some(diff) = first_difference(&vector, &portable) {
            panic!("{}: AVX2 against portable: {diff}", c.name);
        }
    }
}

/// Plans beyond the kernel's limits go to the lane kernel; those at the limits and any
/// fall-back length do not.
#[test]
fn sliced_kernel_refuses_plans_beyond_its_limits() {
    let sys = paper();
    let fits = |c: Case| Sliced::of(&Plan::new(&sys, &c.cfg).unwrap()).is_some();
    let on = |z0| game("limits", 0.5, (z0, 1.0), (10, 20, 0));
    // A mask with `n` runs of ones: 1010...10.
    let runs = |n: usize| Attack::mask((0..2 * n).map(|i| i % 2 == 0).collect()).unwrap();
    assert!(fits(on(31)));
    assert!(!fits(on(32)));
    assert!(fits(on(2).policy(interval(64, 5.0, None, 1))));
    assert!(!fits(on(2).policy(interval(65, 5.0, None, 1))));
    assert!(fits(on(2).attack(runs(8))));
    assert!(!fits(on(2).attack(runs(9))));
    assert!(fits(on(2).policy(count(0, 9, None, u64::MAX))));
    // 64 bins, the edges 1..=64.
    let bins = Policy::Test {
        detector: Detector::Interval {
            edges: (1..=64).collect(),
            expected: vec![1.0; 64],
            critical: 1.0,
        },
        harmful_at_most: None,
        fallback: 1,
        min_gap: 0,
    };
    assert!(fits(on(2).policy(bins)));
}

/// A window without flag-ACKs has a count of 0, which a lower bound of 0 flags: every flag is
/// blocked (β = 1), so every tested window alarms, and every alarm is harmful at the bound 0.
#[test]
fn a_window_without_flags_is_at_the_lower_bound_zero() {
    let sys = paper();
    let c = game("no flags", 0.5, (2, 1.0), (10, 40, 0))
        .attack(Attack::random(1.0).unwrap())
        .policy(count(0, 1 << 40, Some(0), 0));
    let plan = Plan::new(&sys, &c.cfg).unwrap();
    let got = kernel(&plan, 0, None);
    assert!(got.tested.iter().all(|&t| t == 4));
    assert_eq!(got.alarms, got.tested);
    assert_eq!(got.fallbacks, got.tested);
}

/// The thermometers hold the zero count up to z0 + 1, so a memory of 8 or 16 steps takes the next
/// size even where the holding time would not need it (λ = 0.95).
#[test]
fn thermometers_hold_the_longest_memory() {
    let sys = paper();
    for (z0, depth) in [(7, 8), (8, 16), (15, 16), (16, 32)] {
        let c = game("memory", 0.95, (z0, 1.0), (10, 20, 0));
        let plan = Plan::new(&sys, &c.cfg).unwrap();
        assert_eq!(Sliced::of(&plan).unwrap().depth, depth, "z0 = {z0}");
        let got = kernel(&plan, 0, None);
        let (want, _) = plain(&plan, depth, 0);
        assert!(first_difference(&got, &want).is_none(), "z0 = {z0}");
    }
}

/// The body refuses a plan made for another thermometer size, or whose memory it cannot hold,
/// instead of indexing beyond its levels (`run_block` never passes one).
#[test]
fn block_body_refuses_a_plan_of_another_size() {
    let sys = paper();
    let c = game("size", 0.95, (2, 1.0), (10, 20, 0));
    let plan = Plan::new(&sys, &c.cfg).unwrap();
    let mut s = Sliced::of(&plan).unwrap();
    let cancel = AtomicBool::new(false);
    assert!(block_body::<8, _>(&s, &plan, 0, &cancel, Portable).is_ok());
    s.depth = 16;
    assert!(block_body::<8, _>(&s, &plan, 0, &cancel, Portable).is_err());
    (s.depth, s.z0) = (8, 8);
    assert!(block_body::<8, _>(&s, &plan, 0, &cancel, Portable).is_err());
}
