//! Independent blocking and forged flag-ACKs: the kernels agree bit for bit (reference,
//! portable, AVX2, threads, protocols), the plans pick their kernels, and both kernel families
//! agree with the exact costs and flag rates (the renewal forms of `analysis`, which share no
//! code with the simulation).

use super::*;
use crate::schedule::OnlineDesign;

/// An online experiment under `attack`.
fn attacked(lam: f64, z0: u64, mu: f64, attack: Attack) -> McConfig {
    McConfig {
        attack: Some(attack),
        ..online(lam, z0, mu, None)
    }
}

fn random(beta: f64) -> Attack {
    Attack::random(beta).unwrap()
}

fn inject(gamma: f64, block: Option<Attack>) -> Attack {
    Attack::injection(gamma, block).unwrap()
}

/// Every new protocol path (forging alone, independent blocking alone and with forging,
/// forging beside a mask), with and without the μ draw, under both protocols; several blocks
/// and a partial tile each.
fn cases() -> Vec<McConfig> {
    let mask = || Attack::mask(vec![true, false, true, false, false]).unwrap();
    let mut cases = Vec::new();
    for mu in [1.0, 0.4] {
        for attack in [
            inject(0.2, None),
            random(0.6),
            inject(0.1, Some(random(0.5))),
            inject(0.15, Some(mask())),
        ] {
            for protocol in [Protocol::A, Protocol::B] {
                cases.push(McConfig {
                    protocol,
                    ..attacked(0.3, 2, mu, attack.clone())
                });
            }
        }
    }
    cases
        .into_iter()
        .map(|base| McConfig {
            horizon: if cfg!(debug_assertions) { 200 } else { 777 },
            runs: 2 * BLOCK_RUNS + 37,
            seed: 161,
            ..base
        })
        .collect()
}

/// Runs `cfg` on the given kernels.
fn run_on(sys: &LinearSystem, cfg: &McConfig, isa: Isa, bitslice: bool) -> McResult {
    let kernels = Kernels { isa, bitslice };
    simulate_with(
        sys,
        cfg,
        &AtomicBool::new(false),
        &AtomicU64::new(0),
        kernels,
    )
    .unwrap()
}

/// The lane kernels give the reference kernel's results on 1 or 2 threads (portable, and AVX2
/// where the CPU has it); the bit-sliced kernel gives its own on 1 or 2 threads, portable or
/// AVX2; protocol A gives protocol B's results on each.
#[test]
fn kernels_threads_and_protocols_agree() {
    let sys = scalar_sys();
    let avx2 = avx2_or_skip("kernels_threads_and_protocols_agree (AVX2 part)");
    let (one, two) = (pool(1), pool(2));
    let mut seen_forged = false;
    for cfg in cases() {
        let cfg = McConfig {
            record_runs: true,
            ..cfg
        };
        let go = |isa, bitslice| run_on(&sys, &cfg, isa, bitslice);
        let reference = one.install(|| go(Isa::Reference, false));
        assert_eq!(
            two.install(|| go(Isa::Portable, false)),
            reference,
            "{cfg:?}"
        );
        assert!(Plan::new(&sys, &cfg).unwrap().bitslice.is_some(), "{cfg:?}");
        let sliced = one.install(|| go(Isa::Portable, true));
        assert_eq!(two.install(|| go(Isa::Portable, true)), sliced, "{cfg:?}");
        if let Some(avx2) = avx2 {
            assert_eq!(one.install(|| go(avx2, false)), reference, "{cfg:?}");
            assert_eq!(two.install(|| go(avx2, true)), sliced, "{cfg:?}");
        }
        let other = McConfig {
            protocol: match cfg.protocol {
                Protocol::A => Protocol::B,
                Protocol::B => Protocol::A,
            },
            ..cfg.clone()
        };
        let run_other = |isa, bitslice| run_on(&sys, &other, isa, bitslice);
        assert_eq!(two.install(|| run_other(Isa::Portable, false)), reference);
        assert_eq!(two.install(|| run_other(Isa::Portable, true)), sliced);
        for r in [&reference, &sliced] {
            // The per-run record counts forged flags as delivered.
            let total: u64 = r.delivered_per_run.iter().sum();
            let steps = cfg.runs as f64 * cfg.horizon as f64;
            let reached = r.flags_sent - r.flags_blocked + r.flags_forged;
            assert!((total as f64 / steps - reached).abs() <= 1e-12 * reached.max(1.0));
            seen_forged |= r.flags_forged > 0.0;
        }
    }
    assert!(seen_forged);
}

/// State mode runs the protocol on the lane kernels: AVX2 and portable agree bit for bit,
/// the protocols agree, and the power decisions are those of covariance mode's lane kernels.
#[test]
fn state_mode_agrees() {
    let sys = two_state_sys();
    let (one, two) = (pool(1), pool(2));
    let avx2 = avx2_or_skip("state_mode_agrees (AVX2 part)");
    for base in [
        attacked(0.4, 2, 0.5, inject(0.1, Some(random(0.5)))),
        attacked(0.4, 2, 1.0, inject(0.2, None)),
    ] {
        let cfg = McConfig {
            mode: Mode::State,
            horizon: 200,
            runs: BLOCK_RUNS + 37,
            seed: 163,
            ..base
        };
        let portable = one.install(|| run_on(&sys, &cfg, Isa::Portable, false));
        if let Some(avx2) = avx2 {
            assert_eq!(two.install(|| run_on(&sys, &cfg, avx2, false)), portable);
        }
        let a = McConfig {
            protocol: Protocol::A,
            ..cfg.clone()
        };
        assert_eq!(
            two.install(|| run_on(&sys, &a, Isa::Portable, false)),
            portable
        );
        let cov = McConfig {
            mode: Mode::Covariance,
            ..cfg.clone()
        };
        let lanes = run_on(&sys, &cov, Isa::Portable, false);
        assert_eq!(
            (lanes.high_power_rate, lanes.flags_sent, lanes.flags_forged),
            (
                portable.high_power_rate,
                portable.flags_sent,
                portable.flags_forged
            )
        );
    }
}

/// The plans: independent blocking leaves τ unbounded (the table runs to the horizon) and the
/// bit-sliced kernel holds it in a shallow thermometer; forging alone keeps the unattacked
/// bound; where most steps would sit beyond 32 levels, the lane kernels take the plan.
#[test]
fn plans_pick_their_kernels() {
    let sys = scalar_sys();
    let plan = |cfg: &McConfig| Plan::new(&sys, cfg).unwrap();
    let p = plan(&attacked(0.5, 2, 1.0, random(0.2)));
    assert_eq!(p.bound, 1000);
    let bs = p.bitslice.as_ref().unwrap();
    assert!((2..=8).contains(&bs.deep_level), "{}", bs.deep_level);
    let p = plan(&attacked(0.5, 2, 1.0, inject(0.05, None)));
    assert_eq!(p.bound, 2);
    assert_eq!(p.bitslice.as_ref().unwrap().deep_level, 0);
    let p = plan(&attacked(
        0.5,
        2,
        0.4,
        inject(0.05, Some(Attack::periodic(1, 3).unwrap())),
    ));
    assert_eq!(p.bound, 6);
    // Nearly every flag blocked and a lossy channel: τ mostly beyond 32.
    let p = plan(&attacked(0.05, 2, 1.0, random(0.99)));
    assert!(p.bitslice.is_none());
    // Either kernel simulates it exactly; the bound is the horizon.
    assert_eq!(p.bound, 1000);
}

/// The long-run J and flag rates of the exact analysis, for checks against the runs.
fn exact(sys: &LinearSystem, cfg: &McConfig) -> (f64, crate::FlagRates) {
    let McSchedule::Online { z0, mu } = cfg.schedule else {
        unreachable!()
    };
    let design = OnlineDesign::new(z0, mu).unwrap();
    let attack = cfg.attack.as_ref().unwrap();
    let j = sys.j_attack(cfg.lam, design, attack).unwrap();
    let rates = crate::flag_rates(cfg.lam, design, Some(attack)).unwrap();
    (j, rates)
}

/// Both kernel families against the exact J (renewal form) and the exact rates of flags sent,
/// blocked and forged and of high-power steps (forged flags raise the power too).
#[test]
fn both_kernels_match_the_exact_costs() {
    let sys = scalar_sys();
    let cases = [
        (attacked(0.5, 2, 1.0, random(0.7)), 171u64),
        (attacked(0.5, 2, 0.4, inject(0.3, None)), 172),
        (attacked(0.5, 2, 1.0, inject(0.05, Some(random(0.2)))), 173),
    ];
    for (base, seed) in cases {
        let cfg = McConfig {
            horizon: scaled(50_000) as usize,
            runs: scaled(512),
            seed,
            ..base
        };
        let (j, rates) = exact(&sys, &cfg);
        let steps = cfg.runs as f64 * cfg.horizon as f64;
        for (kernel, r) in run_both(&sys, &cfg) {
            let what = format!("{} ({kernel})", cfg.attack.as_ref().unwrap());
            assert_close(&format!("J, {what}"), r.j, j, r.stderr, 4.0);
            let reached = rates.delivered;
            let tol = |p: f64| binomial_tol(p, &cfg);
            assert!((r.high_power_rate - reached).abs() < tol(reached), "{what}");
            assert!(
                (r.flags_sent - rates.sent).abs() < tol(rates.sent),
                "{what}"
            );
            let blocked = rates.blocked().max(0.0); // no blocking: 0 up to rounding
            assert!((r.flags_blocked - blocked).abs() < tol(blocked), "{what}");
            assert!(
                (r.flags_forged - rates.forged).abs() < tol(rates.forged),
                "{what}"
            );
            // Every high-power step but the first follows a flag that reached the sensor.
            let reached_sim = r.flags_sent - r.flags_blocked + r.flags_forged;
            let diff = (r.high_power_rate - reached_sim) * steps;
            assert!(diff.abs() <= cfg.runs as f64, "{what}: {diff}");
        }
    }
}
