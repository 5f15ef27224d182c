//! The kernels agree: protocols A and B, the reference, portable and AVX2 kernels, thread
//! counts, an attack given as (r, t) or as its mask, and plans only the lane kernels take.

use super::*;

/// (4) Protocols A and B are separate code paths with identical statistics, draw for draw.
#[test]
fn protocols_agree() {
    let sys = scalar_sys();
    for mode in [Mode::Covariance, Mode::State] {
        for mu in [1.0, 0.4] {
            let b = McConfig {
                mode,
                horizon: 3_000,
                runs: scaled(300),
                seed: 41,
                ..online(0.4, 2, mu, Some(vec![true, false, true, true, false]))
            };
            let a = McConfig {
                protocol: Protocol::A,
                ..b.clone()
            };
            for ((kernel, ra), (_, rb)) in run_both(&sys, &a).into_iter().zip(run_both(&sys, &b)) {
                assert_eq!(ra, rb, "{mode:?}, mu = {mu}, {kernel}");
                assert!(rb.flags_blocked > 0.0);
            }
        }
    }
}

/// The experiments of the kernel-equality tests: every protocol path, the offline schedule and
/// the rarer kernel paths, each over several blocks and a partial tile.
fn kernel_cases() -> Vec<McConfig> {
    let offline = McSchedule::Offline {
        pattern: vec![1, 0, 0, 1, 0, 0, 0],
    };
    let attack = || Some(vec![true, false, true, false, false]);
    let mut cases = Vec::new();
    for mu in [1.0, 0.4, 0.0] {
        cases.push(online(0.45, 2, mu, None));
        for protocol in [Protocol::A, Protocol::B] {
            cases.push(McConfig {
                protocol,
                ..online(0.45, 2, mu, attack())
            });
        }
    }
    cases.push(McConfig {
        schedule: offline,
        ..online(0.45, 2, 1.0, None)
    });
    cases.extend(edge_kernel_cases());
    cases
        .into_iter()
        .map(|base| McConfig {
            horizon: if cfg!(debug_assertions) { 300 } else { 777 },
            runs: 2 * BLOCK_RUNS + 37, // several blocks and a partial tile
            seed: 61,
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

/// (6) Results depend on the seed only: 1 or 2 threads, portable or reference kernel (the AVX2
/// kernels: `avx2_kernels_match_portable`).
#[test]
fn independent_of_threads_and_kernel() {
    let sys = scalar_sys();
    let (one, two) = (pool(1), pool(2));
    for cfg in kernel_cases() {
        let go = |isa, bitslice| run_on(&sys, &cfg, isa, bitslice);
        // The lane kernels.
        let reference = one.install(|| go(Isa::Reference, false));
        assert_eq!(
            two.install(|| go(Isa::Portable, false)),
            reference,
            "{cfg:?}"
        );
        // The bit-sliced kernel (every plan here fits it).
        assert!(Plan::new(&sys, &cfg).unwrap().bitslice.is_some(), "{cfg:?}");
        let sliced = one.install(|| go(Isa::Portable, true));
        assert_eq!(two.install(|| go(Isa::Portable, true)), sliced, "{cfg:?}");
    }
    let state = McConfig {
        mode: Mode::State,
        horizon: 200,
        runs: BLOCK_RUNS + 5,
        ..online(0.45, 2, 0.4, Some(vec![true, false, true, false, false]))
    };
    assert_eq!(
        one.install(|| run(&sys, &state)),
        two.install(|| run(&sys, &state))
    );
}

/// (6b) The AVX2 kernels give the portable kernels' results bit for bit, on 1 or 2 threads:
/// the lane kernel against the reference, the bit-sliced kernel against its portable build.
#[test]
fn avx2_kernels_match_portable() {
    let Some(avx2) = avx2_or_skip("avx2_kernels_match_portable") else {
        return;
    };
    let sys = scalar_sys();
    let (one, two) = (pool(1), pool(2));
    for cfg in kernel_cases() {
        let go = |isa, bitslice| run_on(&sys, &cfg, isa, bitslice);
        let reference = one.install(|| go(Isa::Reference, false));
        assert_eq!(one.install(|| go(avx2, false)), reference, "{cfg:?}");
        assert_eq!(two.install(|| go(avx2, false)), reference, "{cfg:?}");
        let sliced = one.install(|| go(Isa::Portable, true));
        assert_eq!(two.install(|| go(avx2, true)), sliced, "{cfg:?}");
        assert_eq!(one.install(|| go(avx2, true)), sliced, "{cfg:?}");
    }
}

/// (6c) State mode gives the same results, bit for bit, on the AVX2 and the portable kernels
/// (the protocol runs on them; the errors are plain f64 code), for scalar and vector systems.
#[test]
fn avx2_state_mode_matches_portable() {
    let Some(avx2) = avx2_or_skip("avx2_state_mode_matches_portable") else {
        return;
    };
    let offline = McSchedule::Offline {
        pattern: vec![1, 0, 0, 1, 0],
    };
    let attack = || Some(vec![true, false, true, false, false]);
    let mut cases = vec![
        (scalar_sys(), online(0.45, 2, 1.0, None)),
        (scalar_sys(), online(0.45, 2, 0.4, attack())),
        (
            scalar_sys(),
            McConfig {
                protocol: Protocol::A,
                ..online(0.45, 2, 0.0, attack())
            },
        ),
        (
            two_state_sys(),
            McConfig {
                schedule: offline,
                ..online(0.4, 2, 1.0, None)
            },
        ),
        (two_state_sys(), online(0.4, 3, 0.5, attack())),
        (three_state_sys(), online(0.3, 2, 1.0, None)),
    ];
    cases.extend(edge_kernel_cases().into_iter().map(|c| (scalar_sys(), c)));
    let (one, two) = (pool(1), pool(2));
    for (sys, base) in cases {
        let cfg = McConfig {
            mode: Mode::State,
            horizon: 300,
            runs: BLOCK_RUNS + 37,
            seed: 63,
            record_runs: true,
            ..base
        };
        let portable = one.install(|| run_on(&sys, &cfg, Isa::Portable, false));
        assert_eq!(
            two.install(|| run_on(&sys, &cfg, avx2, false)),
            portable,
            "{cfg:?}"
        );
        assert_eq!(
            one.install(|| run_on(&sys, &cfg, avx2, false)),
            portable,
            "{cfg:?}"
        );
    }
}

/// An attack given as (r, t) is the mask 1^r 0^(t-r): the same experiment, draw for draw, on
/// every kernel family and in both modes.
#[test]
fn periodic_attack_is_its_mask() {
    let sys = scalar_sys();
    for mode in [Mode::Covariance, Mode::State] {
        let mask = McConfig {
            mode,
            horizon: 500,
            runs: BLOCK_RUNS + 9,
            seed: 91,
            ..online(0.45, 2, 0.4, Some(vec![true, true, false, false, false]))
        };
        let periodic = McConfig {
            attack: Some(Attack::periodic(2, 5).unwrap()),
            ..mask.clone()
        };
        for ((kernel, rm), (_, rp)) in run_both(&sys, &mask)
            .into_iter()
            .zip(run_both(&sys, &periodic))
        {
            assert_eq!(rm, rp, "{mode:?}, {kernel}");
            assert!(rp.flags_blocked > 0.0);
        }
    }
}

/// Plans the bit-sliced kernel does not take run on the lane kernels, through the same entry.
#[test]
fn deep_plans_use_the_lane_kernels() {
    let sys = scalar_sys();
    let mut gap = vec![0u8; 41];
    gap[0] = 1;
    let five_runs: Vec<bool> = (0..10).map(|i| i % 2 == 0).collect();
    let cases = [
        // τ bound 40 > MAX_DEPTH.
        McConfig {
            schedule: McSchedule::Offline { pattern: gap },
            ..online(0.5, 2, 1.0, None)
        },
        // Five runs of ones in the mask.
        online(0.5, 2, 1.0, Some(five_runs)),
        // A 40-bit memory under attack.
        online(0.5, 40, 1.0, Some(vec![true, false])),
        McConfig {
            mode: Mode::State,
            ..online(0.5, 2, 1.0, None)
        },
    ];
    for base in cases {
        let cfg = McConfig {
            horizon: 200,
            runs: BLOCK_RUNS + 3,
            ..base
        };
        assert!(Plan::new(&sys, &cfg).unwrap().bitslice.is_none(), "{cfg:?}");
        let [(_, auto), (_, lanes)] = run_both(&sys, &cfg);
        assert_eq!(auto, lanes, "{cfg:?}");
    }
}
