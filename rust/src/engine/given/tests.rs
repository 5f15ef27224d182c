//! An automaton given as K0 and K1: equal to the built-in scenario it was exported from, equal to
//! closed forms derived by hand, and every bad input refused naming the argument.

use super::*;
use crate::engine::{Attacker, Channel, PowerSchedule};
use crate::{Attack, LinearSystem, OnlineDesign, Ratio};

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

fn close(got: f64, want: f64, tol: f64, what: &str) {
    assert!(
        (got - want).abs() <= tol * want.abs().max(1e-300),
        "{what}: {got} vs {want} (rel {:.2e})",
        (got - want).abs() / want.abs()
    );
}

type Coo = (Vec<i64>, Vec<i64>, Vec<f64>);

fn t(m: &Coo) -> Triplets<'_> {
    (&m.0, &m.1, &m.2)
}

/// The built-in engine rebuilt from its own export (with its initial law and labels).
fn rebuilt(e: &Engine) -> Engine {
    let ex = e.automaton();
    Engine::from_automaton(
        ex.labels.len(),
        t(&ex.k0),
        t(&ex.k1),
        Some(&e.product().init),
        Some(ex.labels.clone()),
        1_000_000,
    )
    .unwrap()
}

/// One state arriving with probability `lam`, as triplets.
fn single(lam: f64) -> (Coo, Coo) {
    (
        (vec![0], vec![0], vec![1.0 - lam]),
        (vec![0], vec![0], vec![lam]),
    )
}

/// Tr h^t(p̄) for a scalar system: a^(2t) p̄ + q (a^(2t) - 1)/(a² - 1).
fn h(a: f64, q: f64, pbar: f64, t: i32) -> f64 {
    let s = (a * a).powi(t);
    s * pbar + q * (s - 1.0) / (a * a - 1.0)
}

#[test]
fn the_paper_scenario_rebuilt_from_its_export() {
    let sys = paper();
    let d = OnlineDesign::fixed(2).unwrap();
    let attack = Attack::periodic(1, 5).unwrap();
    let e = Engine::new(
        &Channel::bernoulli(0.5).unwrap(),
        &PowerSchedule::Online(d),
        &Attacker::attack(attack.clone()),
        1_000_000,
    )
    .unwrap();
    let g = rebuilt(&e);
    assert_eq!(g.n_states(), e.n_states());
    // The renewal closed form is an independent route to J.
    let want = sys.j_attack(0.5, d, &attack).unwrap();
    close(g.cost(&sys).unwrap(), want, 1e-12, "J");
    close(g.cost(&sys).unwrap(), e.cost(&sys).unwrap(), 1e-12, "J");
    close(
        g.stability_index(&sys).unwrap(),
        e.stability_index(&sys).unwrap(),
        1e-12,
        "index",
    );
    assert_eq!(
        g.holding_time_law(30).unwrap(),
        e.holding_time_law(30).unwrap()
    );
    assert_eq!(
        g.cost_curve(&sys, 50).unwrap(),
        e.cost_curve(&sys, 50).unwrap()
    );
    assert_eq!(g.stationary_law().unwrap(), e.stationary_law().unwrap());
    assert_eq!(g.automaton(), e.automaton());
    for err in [
        g.high_power_rate().unwrap_err(),
        g.flag_rates().unwrap_err(),
    ] {
        assert!(err.to_string().starts_with("automaton: "), "{err}");
    }
}

#[test]
fn channels_with_memory_and_offline_patterns_rebuilt() {
    let ge = Channel::gilbert_elliott(0.1, 0.3, 0.9, 0.2, 1.0, 0.8).unwrap();
    let cases = [
        (
            PowerSchedule::Online(OnlineDesign::new(3, 0.6).unwrap()),
            Attacker::attack(Attack::random(0.4).unwrap()),
        ),
        (
            PowerSchedule::offline_ratio(Ratio::new(2, 7).unwrap()).unwrap(),
            Attacker::None,
        ),
    ];
    let m = |v: &[f64]| nalgebra::DMatrix::from_row_slice(2, 2, v);
    let vector = LinearSystem::new(
        m(&[1.1, 1.0, 0.0, 1.1]),
        nalgebra::DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        m(&[1.0, 0.0, 0.0, 1.0]),
        nalgebra::DMatrix::from_row_slice(1, 1, &[1.0]),
    )
    .unwrap();
    for (schedule, attacker) in cases {
        let e = Engine::new(&ge, &schedule, &attacker, 1_000_000).unwrap();
        let g = rebuilt(&e);
        for sys in [paper(), vector.clone()] {
            close(g.cost(&sys).unwrap(), e.cost(&sys).unwrap(), 1e-12, "J");
            assert_eq!(
                g.cost_curve(&sys, 20).unwrap(),
                e.cost_curve(&sys, 20).unwrap()
            );
        }
    }
}

#[test]
fn one_state_is_the_geometric_holding_time() {
    // τ is geometric: P(τ = t) = lam (1 - lam)^t, so J = Σ_t lam (1 - lam)^t Tr h^t(p̄)
    // = G p̄ + q (G - 1)/(a² - 1) with G = Σ_t lam ((1 - lam) a²)^t = lam / (1 - (1 - lam) a²).
    for (a, lam) in [(1.2f64, 0.6), (0.9, 0.3), (1.05, 0.1)] {
        let sys = LinearSystem::scalar(a, 0.7, 0.8, 0.8).unwrap();
        let (q, pbar) = (0.8, sys.pbar()[(0, 0)]);
        let (k0, k1) = single(lam);
        let e = Engine::from_automaton(1, t(&k0), t(&k1), None, None, 1).unwrap();
        let g = lam / (1.0 - (1.0 - lam) * a * a);
        close(
            e.cost(&sys).unwrap(),
            g * pbar + q * (g - 1.0) / (a * a - 1.0),
            1e-12,
            "J",
        );
        close(
            e.stability_index(&sys).unwrap(),
            (1.0 - lam) * a * a,
            1e-12,
            "index",
        );
        let law = e.holding_time_law(5).unwrap();
        for (k, &p) in law[..5].iter().enumerate() {
            close(p, lam * (1.0 - lam).powi(k as i32), 1e-14, "P(tau = k)");
        }
        close(law[5], (1.0 - lam).powi(5), 1e-14, "P(tau >= 5)");
        // From τ_0 = 0: P(τ_k = t) = lam (1 - lam)^t for t < k and (1 - lam)^k for t = k.
        let (trace, _) = e.cost_curve(&sys, 6).unwrap();
        for (k, &got) in trace.iter().enumerate() {
            let k = k as i32 + 1;
            let want: f64 = (0..k)
                .map(|t| lam * (1.0 - lam).powi(t) * h(a, q, pbar, t))
                .sum::<f64>()
                + (1.0 - lam).powi(k) * h(a, q, pbar, k);
            close(got, want, 1e-13, "E Tr P_k");
        }
    }
    // Past the stability bound: (1 - 0.2) 1.2² = 1.152.
    let (k0, k1) = single(0.2);
    let e = Engine::from_automaton(1, t(&k0), t(&k1), None, None, 1).unwrap();
    assert_eq!(e.cost(&paper()).unwrap(), f64::INFINITY);
}

#[test]
fn two_alternating_states_sum_their_holding_times() {
    // States 0 and 1 alternate; a step from state e arrives with probability p_e. After a step
    // from state 0 the holding time is t with probability p0, q0 p1, q0 q1 p0, ... (q = 1 - p)
    // and symmetrically from state 1; each kind of step is half of all.
    let (a, q) = (1.2f64, 0.8);
    let sys = LinearSystem::scalar(a, 0.7, q, 0.8).unwrap();
    let pbar = sys.pbar()[(0, 0)];
    for (p0, p1) in [(1.0, 0.5), (0.7, 0.4), (0.9, 0.0)] {
        let k0 = (vec![0, 1], vec![1, 0], vec![1.0 - p0, 1.0 - p1]);
        let k1 = (vec![0, 1], vec![1, 0], vec![p0, p1]);
        let init = [0.5, 0.5];
        let e = Engine::from_automaton(2, t(&k0), t(&k1), Some(&init), None, 2).unwrap();
        let mut want = 0.0;
        for (pa, pb) in [(p0, p1), (p1, p0)] {
            let mut lost = 1.0; // probability the last t steps were all lost
            for t in 0..2000 {
                if lost == 0.0 {
                    break;
                }
                let p_here = if t % 2 == 0 { pa } else { pb };
                want += 0.5 * lost * p_here * h(a, q, pbar, t);
                lost *= 1.0 - p_here;
            }
        }
        close(e.cost(&sys).unwrap(), want, 1e-12, "J");
        assert_eq!(e.automaton().labels, ["0", "1"]);
    }
}

#[test]
fn two_closed_classes_weighted_by_the_initial_law() {
    // State 0 moves to state 1 or 2 with probability 1/2 each (its packet arrives); 1 and 2 are
    // single geometric states, so J is the mean of their one-state costs.
    let sys = paper();
    let (a, q, pbar) = (1.2f64, 0.8, sys.pbar()[(0, 0)]);
    let (l1, l2) = (0.6, 0.9);
    let k0 = (vec![1, 2], vec![1, 2], vec![1.0 - l1, 1.0 - l2]);
    let k1 = (vec![0, 0, 1, 2], vec![1, 2, 1, 2], vec![0.5, 0.5, l1, l2]);
    let e = Engine::from_automaton(3, t(&k0), t(&k1), None, None, 3).unwrap();
    let j1 = |lam: f64| {
        let g = lam / (1.0 - (1.0 - lam) * a * a);
        g * pbar + q * (g - 1.0) / (a * a - 1.0)
    };
    close(e.cost(&sys).unwrap(), 0.5 * (j1(l1) + j1(l2)), 1e-12, "J");
    let pi = e.stationary_law().unwrap();
    assert_eq!(pi[0], 0.0);
    close(pi[1], 0.5, 1e-14, "pi_1");
}

#[test]
fn repeated_entries_add_up_and_zeros_are_dropped() {
    // K1 split over two entries and a zero K1 entry on state 1 (which must not count as an
    // arrival).
    let k0 = (vec![0, 1], vec![0, 1], vec![0.4, 1.0]);
    let k1 = (vec![0, 0, 1], vec![0, 0, 0], vec![0.25, 0.35, 0.0]);
    let err = Engine::from_automaton(2, t(&k0), t(&k1), Some(&[0.5, 0.5]), None, 2).unwrap_err();
    assert!(err.to_string().starts_with("K0: from state 1"), "{err}");
    let (k0, _) = single(0.6);
    let k1 = (vec![0, 0], vec![0, 0], vec![0.25, 0.35]);
    let e = Engine::from_automaton(1, t(&k0), t(&k1), None, None, 1).unwrap();
    let (s0, s1) = single(0.6);
    let f = Engine::from_automaton(1, t(&s0), t(&s1), None, None, 1).unwrap();
    assert_eq!(e.cost(&paper()).unwrap(), f.cost(&paper()).unwrap());
}

#[test]
fn bad_automata_are_refused_naming_the_argument() {
    let (k0, k1) = single(0.5);
    let build = |n: usize,
                 k0: &Coo,
                 k1: &Coo,
                 init: Option<&[f64]>,
                 labels: Option<Vec<String>>,
                 max: usize| {
        Engine::from_automaton(n, t(k0), t(k1), init, labels, max).unwrap_err()
    };
    let starts = |e: Error, arg: &str| assert!(e.to_string().starts_with(arg), "{arg}: {e}");
    let too_large = build(5, &k0, &k1, None, None, 4);
    assert_eq!(
        too_large,
        Error::TooLarge {
            arg: "K0".into(),
            requested: 5,
            limit: 4
        }
    );
    starts(build(0, &k0, &k1, None, None, 4), "K0: the automaton needs");
    starts(
        build(1, &k0, &k1, None, Some(vec![]), 4),
        "labels: 0 labels",
    );
    starts(
        build(1, &k0, &k1, Some(&[0.5, 0.5]), None, 4),
        "init: 2 entries",
    );
    starts(build(1, &k0, &k1, Some(&[0.5]), None, 4), "init: sums to");
    starts(
        build(
            2,
            &(vec![0, 1], vec![0, 1], vec![0.5, 0.5]),
            &(vec![0, 1], vec![0, 1], vec![0.5, 0.5]),
            Some(&[-0.5, 1.5]),
            None,
            4,
        ),
        "init: entry 0 is -0.5",
    );
    starts(
        build(1, &(vec![0], vec![0], vec![]), &k1, None, None, 4),
        "K0: rows, cols and vals have 1, 1 and 0",
    );
    starts(
        build(1, &k0, &(vec![1], vec![0], vec![0.5]), None, None, 4),
        "K1: row index 1 is outside 0..1",
    );
    starts(
        build(1, &k0, &(vec![0], vec![-1], vec![0.5]), None, None, 4),
        "K1: column index -1",
    );
    starts(
        build(1, &(vec![0], vec![0], vec![f64::NAN]), &k1, None, None, 4),
        "K0: entry 0 is NaN",
    );
    starts(
        build(1, &(vec![0], vec![0], vec![-0.5]), &k1, None, None, 4),
        "K0: entry 0 is -0.5",
    );
    starts(
        build(
            1,
            &(vec![0], vec![0], vec![0.5 + 1e-11]),
            &k1,
            None,
            None,
            4,
        ),
        "K0 + K1: row 0 sums to",
    );
    // State 1 is never entered from state 0.
    let k0_2 = (vec![0, 1], vec![0, 0], vec![0.5, 0.5]);
    let k1_2 = (vec![0, 1], vec![0, 1], vec![0.5, 0.5]);
    starts(
        build(2, &k0_2, &k1_2, None, None, 4),
        "init: state 1 (1) is never reached",
    );
    // State 1 loses every packet and stays (ρ(K0) = 1).
    let k0_3 = (vec![0, 1], vec![1, 1], vec![0.5, 1.0]);
    let k1_3 = (vec![0], vec![0], vec![0.5]);
    starts(
        build(
            2,
            &k0_3,
            &k1_3,
            None,
            Some(vec!["on".into(), "jammed".into()]),
            4,
        ),
        "K0: from state 1 (jammed) no packet ever arrives again",
    );
}
