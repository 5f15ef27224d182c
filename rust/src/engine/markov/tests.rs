//! The renewal form under Markov channels against the exact engine (an independent route: the
//! product automaton and its sparse solves), and against the i.i.d. renewal on Bernoulli channels.

use super::*;
use crate::engine::{Attacker, Engine, PowerSchedule};
use crate::Attack;

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

fn close(got: f64, want: f64, tol: f64, what: &str) {
    assert!(
        (got - want).abs() <= tol * want.abs(),
        "{what}: renewal {got} vs {want} (rel {:.2e})",
        (got - want).abs() / want.abs()
    );
}

fn channels() -> Vec<(&'static str, Channel)> {
    vec![
        (
            "ge",
            Channel::gilbert_elliott(0.1, 0.4, 0.7, 0.2, 1.0, 1.0).unwrap(),
        ),
        (
            "ge bursty",
            Channel::gilbert_elliott(0.1, 0.1, 1.0, 0.0, 1.0, 1.0).unwrap(),
        ),
        (
            "three states",
            Channel::markov(
                vec![
                    vec![0.7, 0.2, 0.1],
                    vec![0.3, 0.3, 0.4],
                    vec![0.0, 0.5, 0.5],
                ],
                vec![0.9, 0.4, 0.05],
                vec![1.0, 1.0, 1.0],
            )
            .unwrap(),
        ),
    ]
}

fn engine_j(sys: &LinearSystem, ch: &Channel, d: OnlineDesign, mask: &[bool]) -> f64 {
    let att = if mask.iter().all(|&b| !b) {
        Attacker::None
    } else {
        Attacker::attack(Attack::mask(mask.to_vec()).unwrap())
    };
    Engine::new(ch, &PowerSchedule::Online(d), &att, 1_000_000)
        .unwrap()
        .cost(sys)
        .unwrap()
}

fn designs() -> Vec<OnlineDesign> {
    vec![
        OnlineDesign::fixed(2).unwrap(),
        OnlineDesign::new(2, 0.6).unwrap(),
        OnlineDesign::new(1, 0.3).unwrap(),
        OnlineDesign::new(3, 0.0).unwrap(),
    ]
}

#[test]
fn masks_match_the_engine() {
    let sys = paper();
    let masks: Vec<Vec<bool>> = vec![
        vec![false],
        vec![true, false, false, false, false],
        vec![true, true, true, false, false, false, false],
        vec![true, false, true, true, false, true, false, false],
        vec![false, true, true, true, true, true],
    ];
    for (name, ch) in channels() {
        for d in designs() {
            for mask in &masks {
                let want = engine_j(&sys, &ch, d, mask);
                let got = mask_j(&sys, &ch, d, mask).unwrap();
                close(got, want, 1e-11, &format!("{name} {d:?} {mask:?}"));
            }
        }
    }
}

#[test]
fn vector_systems_match_the_engine() {
    let a = nalgebra::DMatrix::from_row_slice(2, 2, &[1.1, 0.4, 0.0, 0.8]);
    let c = nalgebra::DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
    let q = nalgebra::DMatrix::identity(2, 2) * 0.3;
    let r = nalgebra::DMatrix::from_element(1, 1, 0.5);
    let sys = LinearSystem::new(a, c, q, r).unwrap();
    let (_, ch) = channels().remove(0);
    let d = OnlineDesign::new(2, 0.6).unwrap();
    let mask = [true, true, false, true, false];
    close(
        mask_j(&sys, &ch, d, &mask).unwrap(),
        engine_j(&sys, &ch, d, &mask),
        1e-11,
        "vector",
    );
}

/// On a one-state channel the renewal is the i.i.d. one: the sweep equals the package's i.i.d.
/// sweep (`renewal::sweep`) and a mask its j_attack.
#[test]
fn bernoulli_reduces_to_the_iid_renewal() {
    let sys = paper();
    let ch = Channel::bernoulli(0.5).unwrap();
    for d in designs() {
        let iid = sys.beta_sweep(0.5, d, 40).unwrap();
        let ours = beta_sweep(&sys, &ch, d, 40, None).unwrap();
        assert_eq!(iid.r, ours.r);
        assert_eq!(iid.t, ours.t);
        for (i, (&a, &b)) in iid.j.iter().zip(&ours.j).enumerate() {
            close(b, a, 1e-12, &format!("{d:?} fraction {i}"));
        }
    }
}

#[test]
fn sweep_matches_single_periods() {
    let sys = paper();
    for (name, ch) in channels() {
        let d = OnlineDesign::new(2, 0.6).unwrap();
        let sw = beta_sweep(&sys, &ch, d, 30, None).unwrap();
        for i in (0..sw.j.len()).step_by(37) {
            let want = periodic_j(&sys, &ch, d, sw.r[i].into(), sw.t[i].into()).unwrap();
            close(sw.j[i], want, 1e-12, name);
        }
        let (r, t) = (sw.r[100] as u64, sw.t[100] as u64);
        let mut mask = vec![false; t as usize];
        mask[..r as usize].iter_mut().for_each(|x| *x = true);
        close(sw.j[100], engine_j(&sys, &ch, d, &mask), 1e-11, "engine");
    }
}

#[test]
fn bad_input_is_refused() {
    let sys = paper();
    let d = OnlineDesign::fixed(2).unwrap();
    let lossy_high = Channel::gilbert_elliott(0.1, 0.4, 0.7, 0.2, 0.9, 1.0).unwrap();
    let e = mask_j(&sys, &lossy_high, d, &[true, false]).unwrap_err();
    assert!(e.to_string().starts_with("channel:"), "{e}");
    let ch = Channel::bernoulli(0.5).unwrap();
    let e = mask_j(&sys, &ch, d, &[true, true]).unwrap_err();
    assert!(e.to_string().starts_with("mask:"), "{e}");
    assert!(beta_sweep(&sys, &ch, d, 1, None).is_err());
    assert!(beta_sweep(&sys, &ch, d, MAX_PERIOD + 1, None).is_err());
    assert!(periodic_j(&sys, &ch, d, 5, 5).is_err());
}

/// Time of the sweep against its target in benches/README.md (< 1 s at t_max = 1000):
/// `cargo test --release --lib engine::markov::tests::speed -- --ignored --nocapture`.
#[test]
#[ignore]
fn speed() {
    let sys = paper();
    let ch = Channel::gilbert_elliott(0.1, 0.1, 1.0, 0.0, 1.0, 1.0).unwrap();
    let d = OnlineDesign::new(2, 0.6).unwrap();
    for t_max in [60u64, 1000] {
        let t0 = std::time::Instant::now();
        let sw = beta_sweep(&sys, &ch, d, t_max, None).unwrap();
        println!(
            "t_max {t_max}: {} fractions in {:?}",
            sw.j.len(),
            t0.elapsed()
        );
    }
}

/// The search against a brute force over every mask (all rotations included) through the
/// engine, on small periods.
#[test]
fn worst_mask_is_the_brute_force_optimum() {
    let sys = paper();
    let d = OnlineDesign::new(2, 0.6).unwrap();
    for (name, ch) in channels() {
        for (t, blocked) in [(5usize, 2usize), (6, 3), (7, 1)] {
            let (mask, j, j_cons) = worst_mask(&sys, &ch, d, t, blocked, None).unwrap();
            assert_eq!(mask.iter().filter(|&&b| b).count(), blocked);
            let mut best = f64::NEG_INFINITY;
            for bits in 0u32..(1 << t) {
                if bits.count_ones() as usize == blocked {
                    let m: Vec<bool> = (0..t).map(|i| bits >> i & 1 == 1).collect();
                    best = best.max(engine_j(&sys, &ch, d, &m));
                }
            }
            close(j, best, 1e-11, name);
            let cons: Vec<bool> = (0..t).map(|i| i < blocked).collect();
            close(j_cons, engine_j(&sys, &ch, d, &cons), 1e-11, name);
        }
    }
    assert!(worst_mask(&sys, &channels()[0].1, d, 25, 3, None).is_err());
    assert!(worst_mask(&sys, &channels()[0].1, d, 5, 5, None).is_err());
}
