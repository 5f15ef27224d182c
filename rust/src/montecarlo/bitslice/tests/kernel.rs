//! The bit-sliced kernel against a plain per-lane simulation driven by the same random words,
//! and its AVX2 build against its portable one.
//!
//! (Over 450 lines: one plain reference simulation and the plans it is compared on, every attack
//! kind included; splitting it would split the reference from its cases.)

use super::*;

/// What the plain per-lane simulation reports.
#[derive(Debug, PartialEq)]
struct Plain {
    acc: Vec<f64>,
    sum: Vec<f64>,
    delivered: Vec<u64>,
    sent: u64,
    blocked: u64,
    forged: u64,
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
    /// Each lane's histogram of τ over the steps so far (the bins below a deep plan's level).
    hist: Vec<Vec<u64>>,
    /// Each lane's Σ tr[τ] over its steps with τ at or above a deep plan's level, in order.
    deep_sum: Vec<f64>,
    /// Each lane's β decisions for its next two flags, drawn and unused, the next first
    /// (independent blocking).
    beta_ahead: Vec<Vec<bool>>,
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
            deep_sum: vec![0.0; RUNS],
            beta_ahead: vec![Vec::new(); RUNS],
        }
    }

    /// Step k's arrivals; updates τ and the histograms (`step_hist` over the `active` lanes);
    /// returns them with the Σ of the deep lanes' tr[τ] over the active ones, in lane order.
    fn arrivals(
        &mut self,
        k: usize,
        active: usize,
        step_hist: &mut [u64],
    ) -> (Vec<bool>, Option<f64>) {
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
        let mut deep_step = None;
        for l in 0..RUNS {
            arrive[l] = high[l] || lane(&lucky, l);
            self.tau[l] = match (arrive[l], p.deep_level) {
                (true, _) => 0,
                // A deep plan tracks the exact τ (at most the horizon).
                (false, level) if level > 0 => self.tau[l] + 1,
                (false, _) => (self.tau[l] + 1).min(p.depth()),
            };
            if p.deep_level > 0 && self.tau[l] >= p.deep_level {
                let full = &self.case.full_tr;
                let x = full[self.tau[l].min(full.len() - 1)];
                self.deep_sum[l] += x;
                if l < active {
                    deep_step = Some(deep_step.map_or(x, |s: f64| s + x));
                }
                continue;
            }
            self.hist[l][self.tau[l]] += 1;
            if l < active {
                step_hist[self.tau[l]] += 1;
            }
        }
        (arrive, deep_step)
    }

    /// The detector and the attacker after the arrivals `arrive`, counted in `out` over the
    /// `active` lanes.
    fn detect_and_attack(&mut self, arrive: &[bool], active: usize, out: &mut Plain) {
        let (p, mask) = (&self.case.plan, self.case.mask.as_deref());
        let KernelFlags {
            mu_draw,
            attack,
            protocol_a,
            random_block,
            forge,
            ..
        } = self.case.flags;
        // The zero count the detector compares with its memory.
        let count: Vec<usize> = (0..RUNS)
            .map(|l| match (attack, arrive[l]) {
                (false, _) => self.tau[l],
                (true, true) => 0,
                (true, false) => self.zeros[l] + 1,
            })
            .collect();
        // μ is drawn only where the count is exactly z0.
        let short = if mu_draw {
            let at_z0 = from_lanes(|l| count[l] == p.z0);
            self.rng.bernoulli(Portable, p.mu_thr, at_z0)
        } else {
            ZERO
        };
        let memory = |l: usize| match (mu_draw, lane(&short, l)) {
            (true, true) => p.z0,
            (true, false) => p.z0 + 1,
            (false, _) => p.fixed_memory,
        };
        let flag: Vec<bool> = (0..RUNS).map(|l| count[l] >= memory(l)).collect();
        // β decisions are drawn ahead, two per lane: when a flag finds its lane without one,
        // every lane without its next decision gets one (a single draw), then every lane
        // without the one after gets that (a second draw); then γ for the lanes without a flag.
        let random = if random_block {
            if (0..RUNS).any(|l| flag[l] && self.beta_ahead[l].is_empty()) {
                for want in 1..=2 {
                    let short = from_lanes(|l| self.beta_ahead[l].len() < want);
                    let drawn = self.rng.bernoulli(Portable, p.beta_thr, short);
                    for (l, d) in self.beta_ahead.iter_mut().enumerate() {
                        if d.len() < want {
                            d.push(lane(&drawn, l));
                        }
                    }
                }
            }
            let blocked: Vec<bool> = (0..RUNS)
                .map(|l| flag[l] && self.beta_ahead[l].remove(0))
                .collect();
            from_lanes(|l| blocked[l])
        } else {
            ZERO
        };
        let forged = if forge {
            let none = from_lanes(|l| !flag[l]);
            self.rng.bernoulli(Portable, p.gamma_thr, none)
        } else {
            ZERO
        };
        for l in 0..RUNS {
            let counted = u64::from(l < active);
            let attacked = if attack {
                self.zeros[l] = if flag[l] { 0 } else { count[l] };
                match mask {
                    Some(mask) => {
                        let attacked = flag[l] && mask[self.counter[l]];
                        if flag[l] {
                            self.counter[l] = (self.counter[l] + 1) % mask.len();
                        }
                        attacked
                    }
                    None => flag[l] && lane(&random, l),
                }
            } else {
                false
            };
            let fake = !flag[l] && lane(&forged, l);
            self.hi[l] = if protocol_a {
                flag[l] ^ attacked ^ fake
            } else {
                (flag[l] && !attacked) || fake
            };
            out.sent += u64::from(flag[l]) * counted;
            out.blocked += u64::from(attacked) * counted;
            out.forged += u64::from(fake) * counted;
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
        forged: 0,
        hi_last: 0,
    };
    for k in 0..horizon {
        let mut step_hist = vec![0u64; case.plan.depth() + 1];
        let (arrive, deep_step) = runs.arrivals(k, active, &mut step_hist);
        if case.flags.online {
            runs.detect_and_attack(&arrive, active, &mut out);
        }
        let bins = histogram_sum(tr, &step_hist);
        out.acc.push(deep_step.map_or(bins, |x| bins + x));
    }
    out.hi_last = if case.flags.online {
        runs.hi[..active].iter().filter(|&&h| h).count() as u64
    } else {
        0
    };
    out.sum = runs
        .hist
        .iter()
        .zip(&runs.deep_sum)
        .map(|(h, &deep)| {
            let bins = histogram_sum(tr, h);
            // Lanes that never reached the level add nothing (not even +0.0).
            let steps: u64 = h.iter().sum();
            if steps < horizon as u64 {
                bins + deep
            } else {
                bins
            }
        })
        .collect();
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
        lam_thr: crate::montecarlo::rng::bernoulli_threshold(lam),
        mu_thr: crate::montecarlo::rng::bernoulli_threshold(mu),
        beta_thr: 0,
        gamma_thr: 0,
        z0,
        fixed_memory,
        pattern,
        mask_runs: mask.map(mask_runs).unwrap_or_default(),
        mask_len: mask.map_or(1, |m| m.len() as u64),
        deep_level: 0,
        tr: table(depth),
        channel: None,
    }
}

/// tr[0..=depth]: distinct, irregular values so a histogram bin in the wrong place changes
/// the sums.
fn table(depth: usize) -> Vec<f64> {
    (0..=depth)
        .map(|j| 1.0 + 0.37 * j as f64 + 0.011 * (j * j) as f64)
        .collect()
}

/// One experiment of the comparison: the plan, its protocol paths and its blocking mask.
struct Case {
    plan: BsPlan,
    flags: KernelFlags,
    mask: Option<Vec<bool>>,
    /// The full trace table of a deep plan (else empty).
    full_tr: Vec<f64>,
}

impl Case {
    fn offline(plan: BsPlan) -> Self {
        let flags = KernelFlags {
            online: false,
            mu_draw: false,
            attack: false,
            protocol_a: false,
            random_block: false,
            forge: false,
        };
        Case {
            plan,
            flags,
            mask: None,
            full_tr: Vec::new(),
        }
    }

    /// Online, under protocol B (attacked if `mask` is given).
    fn online(plan: BsPlan, mu_draw: bool, mask: Option<&[bool]>) -> Self {
        let flags = KernelFlags {
            online: true,
            mu_draw,
            attack: mask.is_some(),
            protocol_a: false,
            random_block: false,
            forge: false,
        };
        let mask = mask.map(<[bool]>::to_vec);
        Case {
            plan,
            flags,
            mask,
            full_tr: Vec::new(),
        }
    }

    fn protocol_a(mut self) -> Self {
        self.flags.protocol_a = true;
        self
    }

    /// Blocks each genuine flag independently with probability `beta` (no mask).
    fn random(mut self, beta: f64) -> Self {
        assert!(self.mask.is_none());
        self.plan.beta_thr = crate::montecarlo::rng::bernoulli_threshold(beta);
        self.flags.attack = true;
        self.flags.random_block = true;
        self
    }

    /// Forges a flag with probability `gamma` on each step without a genuine one.
    fn forge(mut self, gamma: f64) -> Self {
        self.plan.gamma_thr = crate::montecarlo::rng::bernoulli_threshold(gamma);
        self.flags.forge = true;
        self
    }

    /// Holds τ up to `level` in the thermometer and the lanes beyond one by one, with a full
    /// table long enough for every horizon compared.
    fn deep(mut self, level: usize) -> Self {
        self.plan.deep_level = level;
        self.plan.tr = table(level);
        self.full_tr = table(400);
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

/// Independent blocking and forging: alone and together, with a mask, both protocols, with
/// and without the μ draw, exact thermometers and deep plans (many lanes beyond the level).
fn other_attack_cases() -> Vec<Case> {
    let mask_a = [true, false, true, false, false];
    let on = |lam, mu, z0, fixed, depth| plan(lam, mu, z0, fixed, vec![1], None, depth);
    vec![
        // Forging alone (the zero count is τ).
        Case::online(on(0.45, 1.0, 2, 2, 2), false, None).forge(0.3),
        Case::online(on(0.3, 0.4, 2, 3, 3), true, None)
            .forge(0.05)
            .protocol_a(),
        // Forging beside mask blocking.
        Case::online(
            plan(0.4, 1.0, 2, 2, vec![1], Some(&mask_a), 6),
            false,
            Some(&mask_a),
        )
        .forge(0.2),
        Case::online(
            plan(0.4, 0.6, 2, 3, vec![1], Some(&mask_a), 9),
            true,
            Some(&mask_a),
        )
        .forge(0.1)
        .protocol_a(),
        // Independent blocking on deep plans (level = D on AVX2, a picked level portably).
        Case::online(on(0.3, 1.0, 2, 2, 4), false, None)
            .random(0.7)
            .deep(4),
        Case::online(on(0.2, 1.0, 2, 2, 4), false, None)
            .random(0.9)
            .deep(4)
            .protocol_a(),
        Case::online(on(0.35, 0.5, 2, 3, 8), true, None)
            .random(0.8)
            .deep(8),
        Case::online(on(0.4, 1.0, 1, 1, 2), false, None)
            .random(0.5)
            .forge(0.1)
            .deep(2),
        Case::online(on(0.25, 0.3, 3, 4, 4), true, None)
            .random(0.6)
            .forge(0.05)
            .deep(4)
            .protocol_a(),
        // Independent blocking with a bound the thermometer holds (β = 0: nothing blocked).
        Case::online(on(0.45, 1.0, 2, 2, 2), false, None).random(0.0),
        // Forging alone on a deep plan (few runs get there).
        Case::online(on(0.3, 1.0, 3, 3, 3), false, None)
            .forge(0.02)
            .deep(2),
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
        deep_tr: &case.full_tr,
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
    for (i, case) in cases().iter().chain(&other_attack_cases()).enumerate() {
        for shape in SHAPES {
            let (got, acc) = run_case(case, i as u64, shape, None);
            let want = plain(case, shape, 3, i as u64);
            assert_eq!(acc, want.acc, "case {i} {shape:?}");
            assert_eq!(got.sum, want.sum, "case {i}");
            assert_eq!(
                (got.sent, got.blocked, got.forged, got.hi_last),
                (want.sent, want.blocked, want.forged, want.hi_last),
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
    for (i, case) in cases().iter().chain(&other_attack_cases()).enumerate() {
        for shape in SHAPES {
            let (portable, acc) = run_case(case, i as u64, shape, None);
            let (again, acc2) = run_case(case, i as u64, shape, Some(avx2));
            assert_eq!((acc2, again.sum), (acc, portable.sum), "case {i} avx2");
            assert_eq!(
                (
                    again.sent,
                    again.blocked,
                    again.forged,
                    again.hi_last,
                    again.delivered
                ),
                (
                    portable.sent,
                    portable.blocked,
                    portable.forged,
                    portable.hi_last,
                    portable.delivered
                ),
                "case {i} avx2"
            );
        }
    }
}
