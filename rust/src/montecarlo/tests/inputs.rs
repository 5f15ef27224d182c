//! Cancellation, refused inputs, edge cases and the τ bound.

use super::*;

/// (7) Cancellation: before the start, and from another thread while running.
#[test]
fn cancel_interrupts() {
    let sys = scalar_sys();
    let cfg = online(0.5, 2, 1.0, None);
    let cancel = AtomicBool::new(true);
    let progress = AtomicU64::new(0);
    assert_eq!(
        simulate(&sys, &cfg, &cancel, &progress),
        Err(Error::Interrupted)
    );
    assert_eq!(progress.load(Ordering::Relaxed), 0);
    // Too long to finish (2·10^10 steps): must stop on the flag.
    let long = McConfig {
        horizon: 2_000_000,
        runs: 10_000,
        ..cfg
    };
    let cancel = AtomicBool::new(false);
    let res = std::thread::scope(|s| {
        let h = s.spawn(|| simulate(&sys, &long, &cancel, &progress));
        std::thread::sleep(std::time::Duration::from_millis(50));
        cancel.store(true, Ordering::Relaxed);
        h.join().unwrap()
    });
    assert_eq!(res, Err(Error::Interrupted));
    let state = McConfig {
        mode: Mode::State,
        ..long
    };
    let cancel = AtomicBool::new(false);
    let res = std::thread::scope(|s| {
        let h = s.spawn(|| simulate(&sys, &state, &cancel, &progress));
        std::thread::sleep(std::time::Duration::from_millis(50));
        cancel.store(true, Ordering::Relaxed);
        h.join().unwrap()
    });
    assert_eq!(res, Err(Error::Interrupted));
}

/// (8) Bad inputs give errors that name the argument.
#[test]
fn bad_inputs_are_named() {
    let sys = scalar_sys();
    let base = online(0.5, 2, 1.0, None);
    let off = |pattern: Vec<u8>| McConfig {
        schedule: McSchedule::Offline { pattern },
        ..base.clone()
    };
    let cases: Vec<(McConfig, &str)> = vec![
        (
            McConfig {
                lam: 0.0,
                ..base.clone()
            },
            "lam",
        ),
        (
            McConfig {
                lam: 1.0,
                ..base.clone()
            },
            "lam",
        ),
        (
            McConfig {
                lam: f64::NAN,
                ..base.clone()
            },
            "lam",
        ),
        (online(0.5, 2, 1.5, None), "mu"),
        (online(0.5, 2, f64::NAN, None), "mu"),
        (online(0.5, 0, 1.0, None), "z0"),
        (online(0.5, 2, 1.0, Some(vec![])), "mask"),
        (
            McConfig {
                attack: Some(Attack::Periodic { r: 3, t: 3 }),
                ..base.clone()
            },
            "r",
        ),
        (off(vec![]), "pattern"),
        (off(vec![0, 1]), "pattern"),
        (off(vec![1, 2]), "pattern"),
        (
            McConfig {
                attack: Some(Attack::Mask(vec![true])),
                ..off(vec![1, 0])
            },
            "attack",
        ),
        (
            McConfig {
                horizon: 0,
                ..base.clone()
            },
            "horizon",
        ),
        (
            McConfig {
                runs: 0,
                ..base.clone()
            },
            "runs",
        ),
        (
            McConfig {
                horizon: MAX_HORIZON + 1,
                ..base.clone()
            },
            "horizon",
        ),
    ];
    for (cfg, arg) in cases {
        let e = run(&sys, &cfg).unwrap_err();
        assert!(
            e.to_string().starts_with(&format!("{arg}:")),
            "{e} (expected {arg})"
        );
    }
    let e = run(
        &sys,
        &McConfig {
            horizon: usize::MAX,
            ..base
        },
    )
    .unwrap_err();
    assert!(matches!(e, Error::TooLarge { .. }), "{e}");
}

#[test]
fn edge_cases() {
    let sys = scalar_sys();
    // One run: no spread can be estimated.
    let r = run(
        &sys,
        &McConfig {
            runs: 1,
            ..online(0.5, 2, 1.0, None)
        },
    )
    .unwrap();
    assert_eq!(r.stderr, f64::INFINITY);
    assert!(r.j.is_finite());
    // Always high power: P_k = P̄ every step, no spread at all.
    let cfg = McConfig {
        schedule: McSchedule::Offline { pattern: vec![1] },
        horizon: 50,
        runs: 40,
        ..online(0.5, 2, 1.0, None)
    };
    let progress = AtomicU64::new(0);
    let r = simulate(&sys, &cfg, &AtomicBool::new(false), &progress).unwrap();
    assert_eq!(progress.load(Ordering::Relaxed), 40);
    let pbar = sys.pbar()[(0, 0)];
    assert!(r.mean_trace.iter().all(|&x| x == pbar));
    assert_eq!((r.j, r.stderr, r.high_power_rate), (pbar, 0.0, 1.0));
    assert_eq!((r.runs, r.steps), (40, 50));
    // Horizon 1: only the initial high-power step.
    let r = run(
        &sys,
        &McConfig {
            horizon: 1,
            ..online(0.5, 2, 0.3, None)
        },
    )
    .unwrap();
    assert_eq!(r.mean_trace, vec![pbar]);
    assert_eq!(r.high_power_rate, 1.0);
    // Every flag blocked: τ is unbounded but the run stays finite (a ρ² = 0.72 < 1).
    let r = run(&sys, &online(0.5, 2, 1.0, Some(vec![true]))).unwrap();
    assert_eq!(r.high_power_rate, 1.0 / 1000.0);
    assert!(r.j.is_finite() && r.stderr.is_finite());
    // z0 beyond the horizon: no flag is ever due.
    let r = run(&sys, &online(0.5, u64::MAX, 0.5, None)).unwrap();
    assert_eq!(r.flags_sent, 0.0);
}

#[test]
fn reachable_tau() {
    let off = McSchedule::Offline {
        pattern: vec![1, 0, 1, 0, 0, 0],
    };
    assert_eq!(max_tau(&off, None), Some(3));
    let on = |mu| McSchedule::Online { z0: 2, mu };
    assert_eq!(max_tau(&on(1.0), None), Some(2));
    assert_eq!(max_tau(&on(0.5), None), Some(3));
    assert_eq!(max_tau(&on(1.0), Some(&[true, false, false])), Some(4));
    assert_eq!(max_tau(&on(0.0), Some(&[true, false, true])), Some(9));
    assert_eq!(max_tau(&on(1.0), Some(&[true, true])), None);
}
