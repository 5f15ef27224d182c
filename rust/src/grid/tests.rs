//! The batch against the single calls, bit for bit: scalar and vector systems, fixed and mixed
//! memories, designs that fail, an infinite J_max, both families and listed attacks.

use nalgebra::DMatrix;

use super::*;
use crate::schedule::design_online;

fn paper() -> LinearSystem {
    LinearSystem::scalar(1.2, 0.7, 0.8, 0.8).unwrap()
}

fn two_state() -> LinearSystem {
    let a = DMatrix::from_row_slice(2, 2, &[1.1, 0.3, -0.2, 0.8]);
    let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.5]);
    let q = DMatrix::from_row_slice(2, 2, &[0.5, 0.1, 0.1, 0.3]);
    let r = DMatrix::from_row_slice(1, 1, &[0.4]);
    LinearSystem::new(a, c, q, r).unwrap()
}

fn same(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// Every (system, λ, ratio) of a small grid, with design_online's design where it exists.
fn cells(n_systems: usize) -> Vec<Cell> {
    let mut out = vec![];
    for system in 0..n_systems {
        for &lam in &[0.15, 0.3, 0.45, 0.5, 0.62, 0.8] {
            for &(p, q) in &[(1u64, 7u64), (1, 5), (2, 9), (1, 30), (3, 10), (1, 3)] {
                let ratio = Ratio::new(p, q).unwrap();
                out.push(Cell {
                    system,
                    lam,
                    ratio,
                    design: design_online(lam, ratio).ok(),
                });
            }
        }
    }
    out
}

fn check_cell(sys: &LinearSystem, c: &Cell, study: &Study, got: &CellResult) {
    let ctx = format!("lam={} ratio={} design={:?}", c.lam, c.ratio, c.design);
    let j_off = sys.j_offline(c.lam, c.ratio).unwrap();
    assert!(same(got.j_offline, j_off), "{ctx}: j_offline");
    assert!(same(got.j_max, sys.j_max(c.lam).unwrap()), "{ctx}: j_max");
    let Some(d) = c.design else {
        assert!(
            got.j_online.is_nan() && got.beta_bar_limit.is_nan(),
            "{ctx}"
        );
        assert!(got.j_attack.iter().all(|j| j.is_nan()), "{ctx}");
        assert!(got.error.is_none(), "{ctx}");
        return;
    };
    assert!(same(got.j_online, sys.j_online(c.lam, d).unwrap()), "{ctx}");
    let bar = sys.beta_bar(c.lam, c.ratio, d, study.t_max).unwrap();
    assert!(same(got.beta_bar_limit, bar.limit), "{ctx}: limit");
    assert_eq!(got.beta_bar_finite, bar.finite, "{ctx}: finite");
    for (i, &beta) in study.betas.iter().enumerate() {
        let single = match study.family {
            Family::Periodic => {
                let j = sys.j_attack_limit(c.lam, d, beta).unwrap();
                let choice = sys.choose_schedule(c.lam, c.ratio, d, beta).unwrap();
                assert_eq!(choice.online, got.j_attack[i] < got.j_offline, "{ctx}");
                j
            }
            Family::Random => sys
                .j_attack(c.lam, d, &Attack::random(beta).unwrap())
                .unwrap(),
        };
        assert!(same(got.j_attack[i], single), "{ctx}: beta {beta}");
    }
    if study.family == Family::Random {
        let b = sys.beta_bar_random(c.lam, c.ratio, d).unwrap();
        assert!(same(got.beta_bar_random, b), "{ctx}: beta_bar_random");
    }
    for (i, a) in study.attacks.iter().enumerate() {
        let single = if a.blocks_every_flag() {
            sys.j_max(c.lam).unwrap()
        } else {
            sys.j_attack(c.lam, d, a).unwrap()
        };
        assert!(same(got.j_listed[i], single), "{ctx}: attack {a}");
    }
    assert!(got.error.is_none(), "{ctx}: {:?}", got.error);
}

#[test]
fn periodic_cells_equal_the_single_calls() {
    let systems = [paper(), two_state()];
    let refs: Vec<&LinearSystem> = systems.iter().collect();
    let cells = cells(2);
    let study = Study {
        betas: vec![0.0, 0.2, 0.5, 1.0],
        family: Family::Periodic,
        t_max: 60,
        attacks: vec![
            Attack::periodic(1, 5).unwrap(),
            Attack::periodic(0, 1).unwrap(),
            Attack::mask(vec![true]).unwrap(),
        ],
    };
    let out = evaluate(&refs, &cells, &study).unwrap();
    assert!(cells.iter().any(|c| c.design.is_none()));
    assert!(cells.iter().any(|c| c.design.is_some_and(|d| d.mu < 1.0)));
    // λ = 0.15 and 0.3 leave J_max infinite for A = 1.2.
    assert!(out.iter().any(|r| r.j_max.is_infinite()));
    for (c, r) in cells.iter().zip(&out) {
        check_cell(&systems[c.system], c, &study, r);
    }
}

#[test]
fn random_cells_equal_the_single_calls() {
    let systems = [paper(), two_state()];
    let refs: Vec<&LinearSystem> = systems.iter().collect();
    let cells: Vec<Cell> = cells(2).into_iter().filter(|c| c.lam > 0.4).collect();
    let study = Study {
        betas: vec![0.0, 0.3, 0.9],
        family: Family::Random,
        t_max: 20,
        attacks: vec![],
    };
    let out = evaluate(&refs, &cells, &study).unwrap();
    for (c, r) in cells.iter().zip(&out) {
        check_cell(&systems[c.system], c, &study, r);
    }
}

#[test]
fn order_and_grouping_do_not_change_a_cell() {
    let sys = paper();
    let all = cells(1);
    let study = Study {
        betas: vec![0.25],
        family: Family::Periodic,
        t_max: 30,
        attacks: vec![],
    };
    let together = evaluate(&[&sys], &all, &study).unwrap();
    for (c, r) in all.iter().zip(&together).step_by(5) {
        let alone = evaluate(&[&sys], std::slice::from_ref(c), &study).unwrap();
        // Debug prints each float's shortest round-trip form: equal strings, equal bits (NaN too).
        assert_eq!(format!("{:?}", alone[0]), format!("{r:?}"));
    }
}

#[test]
fn a_failing_cell_carries_the_single_calls_error() {
    // μ < 1 with t_max - 1 above the mixed-memory segment limit: beta_bar refuses.
    let sys = paper();
    let ratio = Ratio::new(1, 6).unwrap();
    let design = OnlineDesign::new(2, 0.5).unwrap();
    let cell = Cell {
        system: 0,
        lam: 0.5,
        ratio,
        design: Some(design),
    };
    let t_max = MAX_SEGMENTS_MIXED + 2;
    let study = Study {
        betas: vec![0.2],
        family: Family::Periodic,
        t_max,
        attacks: vec![],
    };
    let out = evaluate(&[&sys], &[cell], &study).unwrap();
    let single = sys.beta_bar(0.5, ratio, design, t_max).unwrap_err();
    assert_eq!(out[0].error.as_ref(), Some(&single));
    assert!(out[0].beta_bar_limit.is_nan() && out[0].beta_bar_finite.is_none());
    // What does not need the deep segments is still there.
    assert!(same(out[0].j_offline, sys.j_offline(0.5, ratio).unwrap()));
    let j = sys.j_attack_limit(0.5, design, 0.2).unwrap();
    assert!(same(out[0].j_attack[0], j));
}

#[test]
fn a_malformed_study_is_refused() {
    let sys = paper();
    let ratio = Ratio::new(1, 7).unwrap();
    let cell = Cell {
        system: 1,
        lam: 0.5,
        ratio,
        design: None,
    };
    let study = Study {
        betas: vec![0.2],
        family: Family::Periodic,
        t_max: 60,
        attacks: vec![],
    };
    let e = evaluate(&[&sys], &[cell], &study).unwrap_err();
    assert!(e.to_string().starts_with("system:"), "{e}");
    let bad = Study {
        betas: vec![1.5],
        ..study.clone()
    };
    let cell0 = Cell { system: 0, ..cell };
    let e = evaluate(&[&sys], &[cell0], &bad).unwrap_err();
    assert!(e.to_string().starts_with("beta:"), "{e}");
    let bad = Study { t_max: 1, ..study };
    assert!(evaluate(&[&sys], &[cell0], &bad).is_err());
}

/// Cells per second of the batch against the single calls, on the paper's system over a
/// 100 × 100 (λ, ratio) grid with t_max = 60 (`cargo test --release --lib grid_speed --
/// --ignored --nocapture`).
#[test]
#[ignore]
fn grid_speed() {
    let sys = paper();
    let mut cells = vec![];
    for i in 0..100 {
        let lam = 0.2 + 0.6 * i as f64 / 99.0;
        for k in 0..100u64 {
            let ratio = Ratio::new(1000 + 30 * k, 20_000).unwrap();
            cells.push(Cell {
                system: 0,
                lam,
                ratio,
                design: design_online(lam, ratio).ok(),
            });
        }
    }
    let study = Study {
        betas: vec![0.2, 0.5],
        family: Family::Periodic,
        t_max: 60,
        attacks: vec![],
    };
    let t = std::time::Instant::now();
    let out = evaluate(&[&sys], &cells, &study).unwrap();
    let batch = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    for c in &cells {
        let _ = sys.j_offline(c.lam, c.ratio);
        if let Some(d) = c.design {
            let _ = sys.j_online(c.lam, d);
            let _ = sys.beta_bar(c.lam, c.ratio, d, 60);
            for &b in &study.betas {
                let _ = sys.j_attack_limit(c.lam, d, b);
                let _ = sys.choose_schedule(c.lam, c.ratio, d, b);
            }
        }
    }
    let single = t.elapsed().as_secs_f64();
    let n = out.len() as f64;
    println!(
        "batch {:.0} cells/s, single calls (one thread) {:.0} cells/s",
        n / batch,
        n / single
    );
}
