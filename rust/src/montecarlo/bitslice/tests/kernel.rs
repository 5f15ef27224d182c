//! The bit-sliced kernel against a plain per-lane simulation driven by the same random words,
//! and its AVX2 build against its portable one.

use super::*;

/// What the plain per-lane simulation reports.
#[derive(Debug, PartialEq)]
struct Plain {
    acc: Vec<f64>,
    sum: Vec<f64>,
    delivered: Vec<u64>,
    sent: u64,
    blocked: u64,
    hi_last: u64,
}

/// Σ_j tr[j] · count_j in increasing j, skipping empty bins (the kernel's summation order).
fn histogram_sum(tr: &[f64], counts: &[u64]) -> f64 {
    let mut v = 0.0;
    for (t, &c) in tr.iter().zip(counts) {
        if c != 0 {
            v += t * c as f64;
        }
    }
    v
}

/// The protocol with one integer state per lane, fed by the same Bernoulli words.
struct PlainRuns<'a> {
    case: &'a Case,
    rng: Rng4,
    tau: Vec<usize>,
    zeros: Vec<usize>,
    counter: Vec<usize>,
    hi: Vec<bool>,
    /// Each lane's histogram of τ over the steps so far.
    hist: Vec<Vec<u64>>,
}

impl<'a> PlainRuns<'a> {
    fn new(case: &'a Case, seed: u64, block: u64) -> Self {
        PlainRuns {
            case,
            rng: Rng4::for_block(seed, block),
            tau: vec![0; RUNS],
            zeros: vec![0; RUNS],
            counter: vec![0; RUNS],
            hi: vec![true; RUNS],
            hist: vec![vec![0; case.plan.depth() + 1]; RUNS],
        }
    }

    /// Step k's arrivals; updates τ and the histograms (`step_hist` over the `active` lanes).
    fn arrivals(&mut self, k: usize, active: usize, step_hist: &mut [u64]) -> Vec<bool> {
        let p = &self.case.plan;
        let high: Vec<bool> = (0..RUNS)
            .map(|l| {
                if self.case.flags.online {
                    self.hi[l]
                } else {
                    p.pattern[k % p.pattern.len()] == 1
                }
            })
            .collect();
        // Draws only for the low-power lanes.
        let lucky = self
            .rng
            .bernoulli(Portable, p.lam_thr, from_lanes(|l| !high[l]));
        let mut arrive = vec![false; RUNS];
        for l in 0..RUNS {
            arrive[l] = high[l] || lane(&lucky, l);
            self.tau[l] = if arrive[l] {
                0
            } else {
                (self.tau[l] + 1).min(p.depth())
            };
            self.hist[l][self.tau[l]] += 1;
            if l < active {
                step_hist[self.tau[l]] += 1;
            }
        }
        arrive
    }

    /// The detector and the attacker after the arrivals `arrive`, counted in `out` over the
    /// `active` lanes.
    fn detect_and_attack(&mut self, arrive: &[bool], active: usize, out: &mut Plain) {
        let (p, mask) = (&self.case.plan, self.case.mask.as_deref());
        let KernelFlags {
            mu_draw,
            protocol_a,
            ..
        } = self.case.flags;
        // The zero count the detector compares with its memory.
        let count: Vec<usize> = (0..RUNS)
            .map(|l| match mask {
                None => self.tau[l],
                Some(_) if arrive[l] => 0,
                Some(_) => self.zeros[l] + 1,
            })
            .collect();
        // μ is drawn only where the count is exactly z0.
        let short = if mu_draw {
            let at_z0 = from_lanes(|l| count[l] == p.z0);
            self.rng.bernoulli(Portable, p.mu_thr, at_z0)
        } else {
            ZERO
        };
        for l in 0..RUNS {
            let memory = match (mu_draw, lane(&short, l)) {
                (true, true) => p.z0,
                (true, false) => p.z0 + 1,
                (false, _) => p.fixed_memory,
            };
            let counted = u64::from(l < active);
            let flag = count[l] >= memory;
            let attacked = match mask {
                None => false,
                Some(mask) => {
                    self.zeros[l] = if flag { 0 } else { count[l] };
                    let attacked = flag && mask[self.counter[l]];
                    if flag {
                        self.counter[l] = (self.counter[l] + 1) % mask.len();
                    }
                    attacked
                }
            };
            self.hi[l] = if protocol_a {
                flag ^ attacked
            } else {
                flag && !attacked
            };
            out.sent += u64::from(flag) * counted;
            out.blocked += u64::from(attacked) * counted;
            out.delivered[l] += u64::from(self.hi[l]);
        }
    }
}

/// The plain per-lane simulation of one block of `case`.
fn plain(case: &Case, shape: Shape, seed: u64, block: u64) -> Plain {
    let Shape {
        horizon, active, ..
    } = shape;
    let tr = &case.plan.tr;
    let mut runs = PlainRuns::new(case, seed, block);
    let mut out = Plain {
        acc: Vec::new(),
        sum: Vec::new(),
        delivered: vec![0; RUNS],
        sent: 0,
        blocked: 0,
        hi_last: 0,
    };
    for k in 0..horizon {
        let mut step_hist = vec![0u64; case.plan.depth() + 1];
        let arrive = runs.arrivals(k, active, &mut step_hist);
        if case.flags.online {
            runs.detect_and_attack(&arrive, active, &mut out);
        }
        out.acc.push(histogram_sum(tr, &step_hist));
    }
    out.hi_last = if case.flags.online {
        runs.hi[..active].iter().filter(|&&h| h).count() as u64
    } else {
        0
    };
    out.sum = runs.hist.iter().map(|h| histogram_sum(tr, h)).collect();
    out
}

fn plan(
    lam: f64,
    mu: f64,
    z0: usize,
    fixed_memory: usize,
    pattern: Vec<u8>,
    mask: Option<&[bool]>,
    depth: usize,
) -> BsPlan {
    BsPlan {
        lam_thr: crate::rng::bernoulli_threshold(lam),
        mu_thr: crate::rng::bernoulli_threshold(mu),
        z0,
        fixed_memory,
        pattern,
        mask_runs: mask.map(mask_runs).unwrap_or_default(),
        mask_len: mask.map_or(1, |m| m.len() as u64),
        // Distinct, irregular values so a histogram bin in the wrong place changes the sums.
        tr: (0..=depth)
            .map(|j| 1.0 + 0.37 * j as f64 + 0.011 * (j * j) as f64)
            .collect(),
    }
}

/// One experiment of the comparison: the plan, its protocol paths and its blocking mask.
struct Case {
    plan: BsPlan,
    flags: KernelFlags,
    mask: Option<Vec<bool>>,
}

impl Case {
    fn offline(plan: BsPlan) -> Self {
        let flags = KernelFlags {
            online: false,
            mu_draw: false,
            attack: false,
            protocol_a: false,
        };
        Case {
            plan,
            flags,
            mask: None,
        }
    }

    /// Online, under protocol B (attacked if `mask` is given).
    fn online(plan: BsPlan, mu_draw: bool, mask: Option<&[bool]>) -> Self {
        let flags = KernelFlags {
            online: true,
            mu_draw,
            attack: mask.is_some(),
            protocol_a: false,
        };
        let mask = mask.map(<[bool]>::to_vec);
        Case { plan, flags, mask }
    }

    fn protocol_a(mut self) -> Self {
        self.flags.protocol_a = true;
        self
    }
}

/// Every protocol path, masks with up to four runs of ones and a counter of 5 bits (the wide
/// specialisation), offline patterns, and a depth below the reachable τ bound.
fn cases() -> Vec<Case> {
    let mask_a = [true, false, true, false, false];
    let mask_b: Vec<bool> = (0..13)
        .map(|i| i == 0 || i == 12 || (4..7).contains(&i))
        .collect();
    // 5 counter bits (the wide specialisation) and four runs of ones.
    let mask_c: Vec<bool> = (0..19).map(|i| [1, 2, 5, 9, 10, 17].contains(&i)).collect();
    let mut long_gap = vec![0u8; 21];
    long_gap[0] = 1;
    vec![
        Case::online(plan(0.45, 1.0, 2, 2, vec![1], None, 2), false, None),
        Case::online(plan(0.3, 0.4, 2, 3, vec![1], None, 3), true, None),
        Case::online(
            plan(0.45, 1.0, 2, 2, vec![1], Some(&mask_a), 6),
            false,
            Some(&mask_a),
        ),
        Case::online(
            plan(0.45, 1.0, 2, 2, vec![1], Some(&mask_a), 6),
            false,
            Some(&mask_a),
        )
        .protocol_a(),
        Case::online(
            plan(0.35, 0.4, 2, 3, vec![1], Some(&mask_b), 12),
            true,
            Some(&mask_b),
        ),
        Case::online(
            plan(0.35, 0.6, 1, 2, vec![1], Some(&mask_b), 8),
            true,
            Some(&mask_b),
        )
        .protocol_a(),
        Case::offline(plan(0.5, 1.0, 1, 1, vec![1, 0, 0, 1, 0, 0, 0], None, 3)),
        Case::offline(plan(
            0.2,
            1.0,
            1,
            1,
            vec![1, 0, 0, 0, 0, 0, 0, 0, 0],
            None,
            8,
        )),
        Case::online(
            plan(0.4, 1.0, 3, 3, vec![1], Some(&mask_c), 9),
            false,
            Some(&mask_c),
        ),
        Case::online(
            plan(0.3, 0.5, 3, 4, vec![1], Some(&mask_c), 12),
            true,
            Some(&mask_c),
        )
        .protocol_a(),
        Case::offline(plan(0.15, 1.0, 1, 1, long_gap.clone(), None, 20)),
        // A depth below the reachable τ bound (a short horizon caps it) and an all-ones pattern.
        Case::offline(plan(0.5, 1.0, 1, 1, vec![1], None, 0)),
    ]
}

/// One block of `case` on the bit-sliced kernel (AVX2 if given the token), with the
/// per-step sums it added to a zeroed buffer.
fn run_case(case: &Case, block: u64, shape: Shape, avx2: Option<Avx2>) -> (BsOut, Vec<f64>) {
    let mut acc = vec![0.0; shape.horizon];
    let mut b = BsBlock {
        seed: 3,
        block,
        active: shape.active,
        record: shape.record,
        acc: &mut acc,
    };
    let out = run_block(
        &case.plan,
        case.flags,
        avx2,
        &mut b,
        &AtomicBool::new(false),
    )
    .unwrap();
    (out, acc)
}

/// The size of a compared block.
#[derive(Debug, Clone, Copy)]
struct Shape {
    horizon: usize,
    /// Lanes 0..active are runs.
    active: usize,
    /// Whether the per-run record is kept.
    record: bool,
}

/// The blocks compared: a full one, partial ones, and a horizon that is not a multiple of the
/// batch.
const SHAPES: [Shape; 3] = [
    Shape {
        horizon: 333,
        active: RUNS,
        record: true,
    },
    Shape {
        horizon: 40,
        active: 77,
        record: true,
    },
    Shape {
        horizon: 17,
        active: 200,
        record: false,
    },
];

#[test]
fn matches_plain_per_lane_simulation() {
    for (i, case) in cases().iter().enumerate() {
        for shape in SHAPES {
            let (got, acc) = run_case(case, i as u64, shape, None);
            let want = plain(case, shape, 3, i as u64);
            assert_eq!(acc, want.acc, "case {i} {shape:?}");
            assert_eq!(got.sum, want.sum, "case {i}");
            assert_eq!(
                (got.sent, got.blocked, got.hi_last),
                (want.sent, want.blocked, want.hi_last),
                "case {i}"
            );
            if shape.record {
                assert_eq!(got.delivered, want.delivered, "case {i}");
            }
        }
    }
}

/// The vector build is the same computation as the portable one, bit for bit.
#[test]
fn avx2_matches_portable() {
    let Some(avx2) = Avx2::detect() else {
        eprintln!("SKIPPED: avx2_matches_portable: this CPU has no AVX2, so the AVX2 build was not checked");
        return;
    };
    for (i, case) in cases().iter().enumerate() {
        for shape in SHAPES {
            let (portable, acc) = run_case(case, i as u64, shape, None);
            let (again, acc2) = run_case(case, i as u64, shape, Some(avx2));
            assert_eq!((acc2, again.sum), (acc, portable.sum), "case {i} avx2");
            assert_eq!(
                (again.sent, again.blocked, again.hi_last, again.delivered),
                (
                    portable.sent,
                    portable.blocked,
                    portable.hi_last,
                    portable.delivered
                ),
                "case {i} avx2"
            );
        }
    }
}
