//! The engine against the crate's independent routes (closed forms, renewal forms, explicit
//! chains, exact transient curves) and against closed forms derived here.

use nalgebra::DMatrix;

use super::*;
use crate::{design_online, flag_rates, LinearSystem, Ratio};

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

fn online(lam: f64, design: OnlineDesign, attacker: Attacker) -> Engine {
    Engine::new(
        &Channel::bernoulli(lam).unwrap(),
        &PowerSchedule::Online(design),
        &attacker,
        1_000_000,
    )
    .unwrap()
}

fn close(got: f64, want: f64, tol: f64, what: &str) {
    assert!(
        (got - want).abs() <= tol * want.abs().max(1e-300),
        "{what}: engine {got} vs {want} (rel {:.2e})",
        (got - want).abs() / want.abs()
    );
}

fn vector_systems() -> Vec<(&'static str, LinearSystem)> {
    let m = |r: usize, c: usize, v: &[f64]| DMatrix::from_row_slice(r, c, v);
    let (th, g) = (0.7f64, 1.05);
    vec![
        (
            "n_x = 3",
            LinearSystem::new(
                m(3, 3, &[0.9, 0.3, 0.0, 0.1, 1.05, 0.2, 0.0, 0.2, 0.8]),
                m(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 1.0]),
                m(3, 3, &[1.0, 0.2, 0.0, 0.2, 0.8, 0.1, 0.0, 0.1, 0.5]),
                m(2, 2, &[0.5, 0.0, 0.0, 0.7]),
            )
            .unwrap(),
        ),
        (
            "Jordan block",
            LinearSystem::new(
                m(2, 2, &[1.1, 1.0, 0.0, 1.1]),
                m(1, 2, &[1.0, 0.0]),
                DMatrix::identity(2, 2),
                m(1, 1, &[1.0]),
            )
            .unwrap(),
        ),
        (
            "rotation",
            LinearSystem::new(
                m(
                    2,
                    2,
                    &[g * th.cos(), -g * th.sin(), g * th.sin(), g * th.cos()],
                ),
                m(1, 2, &[1.0, 0.5]),
                m(2, 2, &[0.6, 0.1, 0.1, 0.4]),
                m(1, 1, &[0.3]),
            )
            .unwrap(),
        ),
    ]
}

#[test]
fn online_and_offline_without_attack() {
    let sys = paper();
    for lam in [0.3, 0.5, 0.8] {
        for (z0, mu) in [(2, 1.0), (3, 0.6), (1, 0.0), (1, 0.5)] {
            let d = OnlineDesign::new(z0, mu).unwrap();
            let e = online(lam, d, Attacker::None);
            close(
                e.cost(&sys).unwrap(),
                sys.j_online(lam, d).unwrap(),
                1e-12,
                "J_on",
            );
            close(
                e.high_power_rate().unwrap(),
                d.high_power_rate(lam).unwrap(),
                1e-12,
                "high-power rate",
            );
            assert!(e.stationary_residual().unwrap() < 1e-13);
        }
        for (p, q) in [(1, 7), (2, 7), (1, 3), (3, 4)] {
            let ratio = Ratio::new(p, q).unwrap();
            let e = Engine::new(
                &Channel::bernoulli(lam).unwrap(),
                &PowerSchedule::offline_ratio(ratio).unwrap(),
                &Attacker::None,
                1000,
            )
            .unwrap();
            close(
                e.cost(&sys).unwrap(),
                sys.j_offline(lam, ratio).unwrap(),
                1e-12,
                "J_off",
            );
            close(
                e.high_power_rate().unwrap(),
                ratio.value(),
                1e-12,
                "offline rate",
            );
        }
    }
}

/// design_online matches the budget: the engine's high-power rate is p/q.
#[test]
fn rate_matching() {
    for (lam, p, q) in [(0.5, 1, 7), (0.4, 1, 4), (0.7, 1, 10)] {
        let ratio = Ratio::new(p, q).unwrap();
        let d = design_online(lam, ratio).unwrap();
        let e = online(lam, d, Attacker::None);
        close(
            e.high_power_rate().unwrap(),
            ratio.value(),
            1e-9,
            "rate matching",
        );
    }
}

#[test]
fn blocking_attacks_match_j_attack() {
    let sys = paper();
    let attacks = [
        Attack::periodic(1, 5).unwrap(),
        Attack::periodic(2, 3).unwrap(),
        Attack::periodic(0, 1).unwrap(),
        Attack::mask(vec![true, false, true, true, false, false]).unwrap(),
        Attack::random(0.4).unwrap(),
        Attack::injection(0.1, None).unwrap(),
        Attack::injection(0.05, Some(Attack::periodic(1, 3).unwrap())).unwrap(),
        Attack::injection(0.2, Some(Attack::random(0.6).unwrap())).unwrap(),
    ];
    for lam in [0.35, 0.5] {
        for (z0, mu) in [(2, 1.0), (2, 0.7), (3, 0.3)] {
            let d = OnlineDesign::new(z0, mu).unwrap();
            for a in &attacks {
                let e = online(lam, d, Attacker::attack(a.clone()));
                let want = sys.j_attack(lam, d, a).unwrap();
                close(e.cost(&sys).unwrap(), want, 1e-12, &format!("{a}, {d:?}"));
                let r = flag_rates(lam, d, Some(a)).unwrap();
                let got = e.flag_rates().unwrap();
                close(got.sent, r.sent, 1e-12, "sent");
                close(got.delivered, r.delivered, 1e-12, "delivered");
                if r.forged > 0.0 {
                    close(got.forged, r.forged, 1e-12, "forged");
                } else {
                    assert_eq!(got.forged, 0.0);
                }
            }
        }
    }
}

/// Every flag blocked: J_max = Σ λ a^i tr_i, and ρ(K0) = a.
#[test]
fn every_flag_blocked_is_j_max() {
    let sys = paper();
    for lam in [0.4, 0.6] {
        let d = OnlineDesign::new(2, 0.5).unwrap();
        let e = online(
            lam,
            d,
            Attacker::attack(Attack::mask(vec![true, true]).unwrap()),
        );
        close(
            e.cost(&sys).unwrap(),
            sys.j_max(lam).unwrap(),
            1e-12,
            "J_max",
        );
        close(e.rho_k0().unwrap(), 1.0 - lam, 1e-12, "rho(K0)");
        close(
            e.stability_index(&sys).unwrap(),
            (1.0 - lam) * 1.44,
            1e-12,
            "index",
        );
    }
    // A = 1.2, λ = 0.2: a ρ(A)² = 1.152 > 1 (Model note 5): J_max is infinite, a finite attack's
    // J is not.
    let e = online(
        0.2,
        OnlineDesign::fixed(2).unwrap(),
        Attacker::attack(Attack::random(1.0).unwrap()),
    );
    assert_eq!(e.cost(&sys).unwrap(), f64::INFINITY);
    assert!(e.stability_index(&sys).unwrap() > 1.0);
    let p = Attack::periodic(3, 4).unwrap();
    let e = online(
        0.2,
        OnlineDesign::fixed(2).unwrap(),
        Attacker::attack(p.clone()),
    );
    close(
        e.cost(&sys).unwrap(),
        sys.j_attack(0.2, OnlineDesign::fixed(2).unwrap(), &p)
            .unwrap(),
        1e-12,
        "finite r",
    );
    assert_eq!(e.stability_index(&sys).unwrap(), 0.0);
}

#[test]
fn vector_systems_match_j_attack() {
    for (name, sys) in vector_systems() {
        for (lam, d, a) in [
            (
                0.6,
                OnlineDesign::fixed(2).unwrap(),
                Attack::periodic(1, 4).unwrap(),
            ),
            (
                0.7,
                OnlineDesign::new(2, 0.4).unwrap(),
                Attack::random(0.3).unwrap(),
            ),
            (
                0.6,
                OnlineDesign::new(1, 0.8).unwrap(),
                Attack::injection(0.1, Some(Attack::periodic(1, 2).unwrap())).unwrap(),
            ),
        ] {
            let e = online(lam, d, Attacker::attack(a.clone()));
            let want = sys.j_attack(lam, d, &a).unwrap();
            close(e.cost(&sys).unwrap(), want, 1e-11, &format!("{name}: {a}"));
        }
        let d = OnlineDesign::fixed(2).unwrap();
        let e = online(0.6, d, Attacker::None);
        close(
            e.cost(&sys).unwrap(),
            sys.j_online(0.6, d).unwrap(),
            1e-11,
            name,
        );
    }
}

#[test]
fn transient_curves_match_the_chain_route() {
    let sys = paper();
    let h = 60;
    for (d, a) in [
        (
            OnlineDesign::fixed(2).unwrap(),
            Some(Attack::periodic(1, 5).unwrap()),
        ),
        (
            OnlineDesign::new(2, 0.6).unwrap(),
            Some(Attack::random(0.5).unwrap()),
        ),
        (
            OnlineDesign::new(3, 0.3).unwrap(),
            Some(Attack::injection(0.1, None).unwrap()),
        ),
        (OnlineDesign::fixed(1).unwrap(), None),
    ] {
        let attacker = a.clone().map_or(Attacker::None, Attacker::attack);
        let e = online(0.5, d, attacker);
        let (tr, j) = e.cost_curve(&sys, h).unwrap();
        let want = sys
            .expected_trace_curve(0.5, crate::Schedule::Online(d), a.as_ref(), h)
            .unwrap();
        for k in 0..h {
            close(tr[k], want[k], 1e-12, &format!("step {}", k + 1));
        }
        let mean: f64 = want.iter().sum::<f64>() / h as f64;
        close(j[h - 1], mean, 1e-12, "J_k");
    }
    let ratio = Ratio::new(2, 7).unwrap();
    let e = Engine::new(
        &Channel::bernoulli(0.4).unwrap(),
        &PowerSchedule::offline_ratio(ratio).unwrap(),
        &Attacker::None,
        100,
    )
    .unwrap();
    let (tr, _) = e.cost_curve(&sys, 30).unwrap();
    let want = sys
        .expected_trace_curve(0.4, crate::Schedule::Offline(ratio), None, 30)
        .unwrap();
    for k in 0..30 {
        close(tr[k], want[k], 1e-12, "offline curve");
    }
    // A vector system: the curve of the Jordan block against the chain route too.
    let (_, jordan) = &vector_systems()[1];
    let d = OnlineDesign::fixed(2).unwrap();
    let a = Attack::periodic(1, 3).unwrap();
    let e = online(0.6, d, Attacker::attack(a.clone()));
    let (tr, _) = e.cost_curve(jordan, 40).unwrap();
    let want = jordan
        .expected_trace_curve(0.6, crate::Schedule::Online(d), Some(&a), 40)
        .unwrap();
    for k in 0..40 {
        close(tr[k], want[k], 1e-11, "Jordan curve");
    }
}

/// The always-low sensor on Gilbert-Elliott(p, q, 1, 0): τ = 0 in the good state, and a bad
/// run of t >= 1 steps follows a good step with probability p (1-q)^(t-1), so
/// J = q/(p+q) [tr_0 + p Σ_{t>=1} (1-q)^(t-1) tr_t], finite iff (1-q) ρ(A)² < 1.
#[test]
fn always_low_on_gilbert_elliott() {
    let sys = paper();
    let (p, q) = (0.2, 0.5);
    let ch = Channel::gilbert_elliott(p, q, 1.0, 0.0, 1.0, 1.0).unwrap();
    let e = Engine::new(
        &ch,
        &PowerSchedule::Offline(vec![false]),
        &Attacker::None,
        100,
    )
    .unwrap();
    let mut x = sys.pbar().clone();
    let mut sum = 0.0;
    let mut weight = 1.0;
    for _ in 0..300 {
        x = sys.h(&x);
        sum += weight * x.trace();
        weight *= 1.0 - q;
    }
    let want = q / (p + q) * (sys.pbar().trace() + p * sum);
    close(e.cost(&sys).unwrap(), want, 1e-12, "always low");
    close(
        e.stability_index(&sys).unwrap(),
        (1.0 - q) * 1.44,
        1e-12,
        "index",
    );
    // q = 0.25: (1 - q) ρ(A)² = 1.08 > 1.
    let ch = Channel::gilbert_elliott(p, 0.25, 1.0, 0.0, 1.0, 1.0).unwrap();
    let e = Engine::new(
        &ch,
        &PowerSchedule::Offline(vec![false]),
        &Attacker::None,
        100,
    )
    .unwrap();
    assert_eq!(e.cost(&sys).unwrap(), f64::INFINITY);
    close(
        e.stability_index(&sys).unwrap(),
        0.75 * 1.44,
        1e-12,
        "index past 1",
    );
}

/// p + q = 1 makes the Gilbert-Elliott states i.i.d.: with equal high-power arrivals it is the
/// i.i.d. channel with λ = π_good λ_good + π_bad λ_bad.
#[test]
fn memoryless_gilbert_elliott_is_iid() {
    let sys = paper();
    let (p, q, lg, lb) = (0.3, 0.7, 0.8, 0.2);
    let lam = q * lg + p * lb;
    let d = OnlineDesign::new(2, 0.8).unwrap();
    let a = Attack::periodic(1, 4).unwrap();
    let ge = Channel::gilbert_elliott(p, q, lg, lb, 1.0, 1.0).unwrap();
    let e = Engine::new(
        &ge,
        &PowerSchedule::Online(d),
        &Attacker::attack(a.clone()),
        1000,
    )
    .unwrap();
    close(
        e.cost(&sys).unwrap(),
        sys.j_attack(lam, d, &a).unwrap(),
        1e-12,
        "GE iid",
    );
    // High-power arrival below 1, against the one-state Markov channel.
    let ge = Channel::gilbert_elliott(p, q, lg, lb, 0.9, 0.9).unwrap();
    let iid = Channel::markov(vec![vec![1.0]], vec![lam], vec![0.9]).unwrap();
    let sched = PowerSchedule::Online(d);
    let e1 = Engine::new(&ge, &sched, &Attacker::attack(a.clone()), 1000).unwrap();
    let e2 = Engine::new(&iid, &sched, &Attacker::attack(a), 1000).unwrap();
    close(
        e1.cost(&sys).unwrap(),
        e2.cost(&sys).unwrap(),
        1e-12,
        "GE iid, high 0.9",
    );
}

/// The mimicry attacker's virtual system is attack-free, so on an i.i.d. channel the sensor
/// receives flags at exactly the attack-free rate.
#[test]
fn mimicry_delivers_the_attack_free_rate() {
    for (lam, d) in [
        (0.5, OnlineDesign::fixed(2).unwrap()),
        (0.3, OnlineDesign::new(3, 0.4).unwrap()),
    ] {
        let ch = Channel::bernoulli(lam).unwrap();
        let m = Attacker::Mimicry {
            channel: ch.clone(),
            design: d,
        };
        let e = Engine::new(&ch, &PowerSchedule::Online(d), &m, 100_000).unwrap();
        let free = flag_rates(lam, d, None).unwrap();
        let got = e.flag_rates().unwrap();
        close(got.delivered, free.sent, 1e-12, "mimicry delivered");
        close(
            e.high_power_rate().unwrap(),
            d.high_power_rate(lam).unwrap(),
            1e-12,
            "rate",
        );
        assert!(got.forged > 0.0 && got.sent > 0.0);
    }
}

#[test]
fn min_gap_one_is_plain_injection_and_a_gap_forges_less() {
    let sys = paper();
    let d = OnlineDesign::fixed(2).unwrap();
    let a = Attack::injection(0.3, None).unwrap();
    let plain = online(0.5, d, Attacker::attack(a.clone()));
    close(
        plain.cost(&sys).unwrap(),
        sys.j_attack(0.5, d, &a).unwrap(),
        1e-12,
        "gap 1",
    );
    let gap = online(
        0.5,
        d,
        Attacker::Attack {
            attack: a,
            min_gap: 4,
        },
    );
    let (f1, f4) = (
        plain.flag_rates().unwrap().forged,
        gap.flag_rates().unwrap().forged,
    );
    assert!(f4 < f1 && f4 > 0.0, "{f4} vs {f1}");
}

#[test]
fn holding_time_law_is_the_stationary_tau() {
    // No attack, z0 = 2, μ = 1: τ in 0..=2 with weights λ a^τ / (1 - a^3).
    let lam = 0.4;
    let a = 1.0 - lam;
    let e = online(lam, OnlineDesign::fixed(2).unwrap(), Attacker::None);
    let law = e.holding_time_law(2).unwrap();
    let den = 1.0 - a.powi(3);
    close(law[0], lam / den, 1e-13, "tau 0");
    close(law[1], lam * a / den, 1e-13, "tau 1");
    close(law[2], lam * a * a / den, 1e-12, "tau >= 2");
    let e = online(
        lam,
        OnlineDesign::fixed(2).unwrap(),
        Attacker::attack(Attack::random(1.0).unwrap()),
    );
    let law = e.holding_time_law(5).unwrap();
    close(law[5], a.powi(5), 1e-12, "geometric tail");
    close(law.iter().sum(), 1.0, 1e-13, "total");
}

#[test]
fn automaton_by_hand_equals_the_built_in_attack() {
    let sys = paper();
    let d = OnlineDesign::new(2, 0.7).unwrap();
    // Periodic blocking 1 of 3 written out by hand.
    let flag = (0..3)
        .map(|s| {
            vec![Move {
                p: 1.0,
                deliver: s >= 1,
                next: (s + 1) % 3,
            }]
        })
        .collect();
    let quiet = (0..3)
        .map(|s| {
            vec![Move {
                p: 1.0,
                deliver: false,
                next: s,
            }]
        })
        .collect();
    let a = AttackerAutomaton::new(flag, quiet, 0).unwrap();
    let e = online(0.5, d, Attacker::Automaton(a));
    let want = sys
        .j_attack(0.5, d, &Attack::periodic(1, 3).unwrap())
        .unwrap();
    close(e.cost(&sys).unwrap(), want, 1e-12, "by hand");
    let ex = e.automaton();
    assert_eq!(ex.labels.len(), e.n_states());
    let total: f64 = ex.k0.2.iter().chain(&ex.k1.2).sum();
    close(total, e.n_states() as f64, 1e-12, "rows sum to 1");
}

#[test]
fn bad_input_is_refused_naming_the_argument() {
    let starts = |e: Error, arg: &str| assert!(e.to_string().starts_with(arg), "{e}");
    starts(
        Channel::markov(
            vec![vec![0.5, 0.4], vec![0.5, 0.5]],
            vec![0.5; 2],
            vec![1.0; 2],
        )
        .unwrap_err(),
        "P:",
    );
    starts(
        Channel::markov(
            vec![vec![1.2, -0.2], vec![0.5, 0.5]],
            vec![0.5; 2],
            vec![1.0; 2],
        )
        .unwrap_err(),
        "P:",
    );
    starts(
        Channel::markov(
            vec![vec![1.0, 0.0], vec![0.0, 1.0]],
            vec![0.5; 2],
            vec![1.0; 2],
        )
        .unwrap_err(),
        "P:",
    );
    starts(
        Channel::markov(vec![vec![1.0]], vec![1.5], vec![1.0]).unwrap_err(),
        "low:",
    );
    starts(
        Channel::markov(vec![vec![1.0]], vec![0.5], vec![1.0, 1.0]).unwrap_err(),
        "high:",
    );
    let mv = |p, next| Move {
        p,
        deliver: true,
        next,
    };
    starts(
        AttackerAutomaton::new(vec![vec![mv(1.0, 3)]], vec![vec![mv(1.0, 0)]], 0).unwrap_err(),
        "automaton:",
    );
    starts(
        AttackerAutomaton::new(vec![vec![mv(0.5, 0)]], vec![vec![mv(1.0, 0)]], 0).unwrap_err(),
        "automaton:",
    );
    starts(
        AttackerAutomaton::new(
            vec![vec![mv(1.5, 0), mv(-0.5, 0)]],
            vec![vec![mv(1.0, 0)]],
            0,
        )
        .unwrap_err(),
        "automaton:",
    );
    starts(
        AttackerAutomaton::new(vec![vec![mv(1.0, 0)]], vec![vec![mv(1.0, 0)]], 1).unwrap_err(),
        "automaton:",
    );
    // Too many states: refused before the product is allocated.
    let d = OnlineDesign::fixed(2).unwrap();
    let ch = Channel::bernoulli(0.5).unwrap();
    let big = Attacker::attack(Attack::periodic(1, 1000).unwrap());
    let e = Engine::new(&ch, &PowerSchedule::Online(d), &big, 999).unwrap_err();
    assert!(matches!(e, Error::TooLarge { .. }), "{e}");
    let e = Engine::new(&ch, &PowerSchedule::Online(d), &big, 1500).unwrap_err();
    starts(e, "max_states:");
    let gap = Attacker::Attack {
        attack: Attack::injection(0.1, None).unwrap(),
        min_gap: u64::MAX,
    };
    assert!(Engine::new(&ch, &PowerSchedule::Online(d), &gap, 1000).is_err());
    let e = Engine::new(
        &ch,
        &PowerSchedule::Online(d),
        &Attacker::Attack {
            attack: Attack::random(0.1).unwrap(),
            min_gap: 2,
        },
        1000,
    )
    .unwrap_err();
    starts(e, "min_gap:");
    // No arrival from some state: λ = 0 and every flag blocked.
    let zero = Channel::bernoulli(0.0).unwrap();
    let all = Attacker::attack(Attack::random(1.0).unwrap());
    let e = Engine::new(&zero, &PowerSchedule::Online(d), &all, 1000).unwrap_err();
    starts(e, "attack:");
    let e = Engine::new(
        &zero,
        &PowerSchedule::Offline(vec![false]),
        &Attacker::None,
        10,
    );
    starts(e.unwrap_err(), "channel:");
}

/// Past the dense threshold the sparse LU (real and complex) runs: the same checks on a few
/// hundred states.
#[test]
fn sparse_path_matches_j_attack() {
    let d = OnlineDesign::new(2, 0.6).unwrap();
    let a = Attack::periodic(7, 40).unwrap();
    let e = online(0.5, d, Attacker::attack(a.clone()));
    assert!(e.n_states() > 2 * linsolve::DENSE_MAX, "{}", e.n_states());
    let mut systems = vec![("scalar", paper())];
    systems.extend(vector_systems());
    for (name, sys) in systems {
        close(
            e.cost(&sys).unwrap(),
            sys.j_attack(0.5, d, &a).unwrap(),
            1e-11,
            name,
        );
    }
    let r = flag_rates(0.5, d, Some(&a)).unwrap();
    close(
        e.flag_rates().unwrap().delivered,
        r.delivered,
        1e-12,
        "delivered",
    );
    // ρ(K0) of a finite attack is 0 only when K0 is acyclic; with μ < 1 it still is.
    assert_eq!(e.rho_k0().unwrap(), 0.0);
    let e = online(0.5, d, Attacker::attack(Attack::random(0.3).unwrap()));
    let ge = Channel::gilbert_elliott(0.1, 0.3, 0.6, 0.1, 1.0, 1.0).unwrap();
    let big = Engine::new(
        &ge,
        &PowerSchedule::Online(d),
        &Attacker::attack(Attack::mask(vec![true; 30]).unwrap()),
        10_000,
    )
    .unwrap();
    assert!(e.rho_k0().unwrap() > 0.0 && big.rho_k0().unwrap() > 0.0);
    assert!(big.stationary_residual().unwrap() < 1e-12);
}

/// A periodic channel (the state flips every step) beside an offline pattern of period 2: the
/// product has two closed classes, entered with the stationary c_1's probabilities 1/2 each.
/// High power at even phases always arrives; at odd phases a low-power packet arrives only in
/// channel state 0. Starting in c_1 = 0 the holding time alternates 0, 1; starting in c_1 = 1
/// it stays 0. So J = (tr_0 + tr_1)/4 + tr_0/2, and J_k tends to it.
#[test]
fn two_closed_classes_mix_by_the_initial_law() {
    let sys = paper();
    let ch = Channel::markov(
        vec![vec![0.0, 1.0], vec![1.0, 0.0]],
        vec![1.0, 0.0],
        vec![1.0, 1.0],
    )
    .unwrap();
    let e = Engine::new(
        &ch,
        &PowerSchedule::Offline(vec![true, false]),
        &Attacker::None,
        100,
    )
    .unwrap();
    let tr = sys.h_traces(1);
    let want = (tr[0] + tr[1]) / 4.0 + tr[0] / 2.0;
    close(e.cost(&sys).unwrap(), want, 1e-13, "two classes");
    close(e.high_power_rate().unwrap(), 0.5, 1e-13, "rate");
    let (_, j) = e.cost_curve(&sys, 2000).unwrap();
    close(j[1999], want, 1e-3, "J_k");
    // A hand-made attacker with two absorbing states behind a coin: deliver every flag from
    // then on, or none. J is the mixture of J_on and J_max.
    let d = OnlineDesign::fixed(2).unwrap();
    let mv = |p, deliver, next| Move { p, deliver, next };
    let a = AttackerAutomaton::new(
        vec![
            vec![mv(0.3, true, 1), mv(0.7, false, 2)],
            vec![mv(1.0, true, 1)],
            vec![mv(1.0, false, 2)],
        ],
        vec![
            vec![mv(1.0, false, 0)],
            vec![mv(1.0, false, 1)],
            vec![mv(1.0, false, 2)],
        ],
        0,
    )
    .unwrap();
    let e = online(0.5, d, Attacker::Automaton(a));
    let want = 0.3 * sys.j_online(0.5, d).unwrap() + 0.7 * sys.j_max(0.5).unwrap();
    close(e.cost(&sys).unwrap(), want, 1e-12, "absorbing attacker");
}

/// Two closed classes past the dense threshold (the stationary law and I - s K0 then get their
/// own orderings): a coin at the first flag-ACK chooses between passing every flag from then on
/// and the periodic blocker PeriodicBlocking(7, 40) started at that flag. Before the first flag
/// both branches act alike, so J = 0.3 J_on + 0.7 J_attack.
#[test]
fn two_closed_classes_on_the_sparse_path() {
    let sys = paper();
    let d = OnlineDesign::new(2, 0.6).unwrap();
    let a = Attack::periodic(7, 40).unwrap();
    let mv = |p, deliver, next| Move { p, deliver, next };
    // States: 0 = before the first flag, 1 = pass all, 2 + σ = the blocker's count σ.
    let mut flag = vec![
        vec![mv(0.3, true, 1), mv(0.7, false, 3)],
        vec![mv(1.0, true, 1)],
    ];
    let mut quiet = vec![vec![mv(1.0, false, 0)], vec![mv(1.0, false, 1)]];
    for s in 0..40usize {
        flag.push(vec![mv(1.0, s >= 7, 2 + (s + 1) % 40)]);
        quiet.push(vec![mv(1.0, false, 2 + s)]);
    }
    let e = online(
        0.5,
        d,
        Attacker::Automaton(AttackerAutomaton::new(flag, quiet, 0).unwrap()),
    );
    assert!(e.n_states() > 2 * linsolve::DENSE_MAX, "{}", e.n_states());
    let want = 0.3 * sys.j_online(0.5, d).unwrap() + 0.7 * sys.j_attack(0.5, d, &a).unwrap();
    close(e.cost(&sys).unwrap(), want, 1e-11, "mixture");
    assert!(e.stationary_residual().unwrap() < 1e-12);
}
