//! The bit-sliced kernel against a plain per-lane simulation driven by the same random words.

use super::words::*;
use super::*;
use crate::montecarlo::cpu::Avx2;

/// Bit `l` of a lane word.
fn lane(w: &W, l: usize) -> bool {
    (w[l / 64] >> (l % 64)) & 1 == 1
}

fn from_lanes(f: impl Fn(usize) -> bool) -> W {
    let mut w = ZERO;
    for l in 0..RUNS {
        w[l / 64] |= u64::from(f(l)) << (l % 64);
    }
    w
}

/// A Rng4 that records every word it hands out.
struct Recorder {
    rng: Rng4,
    words: Vec<W>,
}

impl Recorder {
    fn bernoulli(&mut self, thr: u64, need: W) -> W {
        // Replay: draw with a clone, count how many words it used, then record them.
        let mut probe = Rng4 { s: self.rng.s };
        let before = probe.s;
        let hit = probe.bernoulli(Portable, thr, need);
        let mut replay = Rng4 { s: before };
        while replay.s != probe.s {
            self.words.push(replay.next(Portable));
        }
        self.rng = probe;
        hit
    }
}

#[test]
fn bernoulli_is_the_prefix_comparison() {
    // Each lane hits iff its uniform, read MSB first from the words used, is below T; lanes
    // still undecided when the draw stops have U >= T.
    for thr in [
        1u64 << 63,
        0x5555_5555_5555_5555,
        3,
        u64::MAX,
        0x8000_0000_0000_0001,
        0,
    ] {
        let mut rec = Recorder {
            rng: Rng4::for_block(9, thr % 1000),
            words: Vec::new(),
        };
        let sparse = from_lanes(|l| l % 37 == 5);
        for draw in 0..60 {
            // All lanes, a few lanes (fewer words), or none (no word at all).
            let need = [ONES, sparse, ZERO][draw % 3];
            rec.words.clear();
            let hit = rec.bernoulli(thr, need);
            let used = rec.words.len();
            assert!(used <= 64);
            for l in 0..RUNS {
                let mut u: u128 = 0;
                for w in &rec.words {
                    u = (u << 1) | u128::from(lane(w, l));
                }
                let t_prefix = if used == 0 {
                    0
                } else {
                    u128::from(thr >> (64 - used))
                };
                let expect = lane(&need, l) && used > 0 && u < t_prefix;
                assert_eq!(lane(&hit, l), expect, "thr {thr:#x} lane {l} used {used}");
                if thr == 1 << 63 && need == ONES {
                    assert_eq!(used, 1, "p = 1/2 takes one word");
                }
                if need == ZERO {
                    assert_eq!(used, 0);
                }
            }
        }
    }
}

#[test]
fn bernoulli_frequency() {
    for p in [0.3f64, 0.5, 0.9, 0.01] {
        let thr = crate::rng::bernoulli_threshold(p);
        let mut rng = Rng4::for_block(4, 1);
        let draws = 4000u32;
        let hits: u64 = (0..draws)
            .map(|_| u64::from(popcount(rng.bernoulli(Portable, thr, ONES))))
            .sum();
        let n = f64::from(draws) * RUNS as f64;
        let se = (p * (1.0 - p) / n).sqrt();
        assert!(
            (hits as f64 / n - p).abs() < 5.0 * se,
            "p = {p}: {}",
            hits as f64 / n
        );
    }
}

#[test]
fn counters_and_comparisons() {
    let mut rng = Rng4::for_block(5, 5);
    // Per-lane counts over a few hundred words, batch by batch.
    let mut c = LaneCounter::NEW;
    let mut naive = vec![0u64; RUNS];
    for _ in 0..37 {
        let batch: [W; BATCH] =
            std::array::from_fn(|_| and(rng.next(Portable), rng.next(Portable)));
        for w in &batch {
            for (l, n) in naive.iter_mut().enumerate() {
                *n += u64::from(lane(w, l));
            }
        }
        c.add16(&batch);
    }
    assert_eq!(c.counts().to_vec(), naive);
    // Binary planes against plain integers.
    for bits in [1usize, 3, 5, 64] {
        let planes: Vec<W> = (0..bits).map(|_| rng.next(Portable)).collect();
        let value =
            |l: usize| -> u64 { (0..bits).map(|i| u64::from(lane(&planes[i], l)) << i).sum() };
        let mut consts: Vec<u64> = vec![0, 1, 2, 5, 31, 32, 33, u64::MAX];
        consts.push(value(7));
        for &k in &consts {
            let lt = less_than(&planes, k);
            let eq = equals(&planes, k);
            for l in 0..RUNS {
                assert_eq!(lane(&lt, l), value(l) < k, "bits {bits} k {k} lane {l}");
                let expect_eq = bits == 64 || k >> bits == 0;
                assert_eq!(lane(&eq, l), expect_eq && value(l) == k);
            }
        }
    }
    assert_eq!(mask_runs(&[true, true, false, true]), vec![0..2, 3..4]);
    assert_eq!(mask_runs(&[false, false]), vec![]);
    assert_eq!(mask_runs(&[true]), vec![0..1]);
}

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
fn plain(case: &Case, horizon: usize, active: usize, seed: u64, block: u64) -> Plain {
    let (p, mask) = (&case.plan, case.mask.as_deref());
    let KernelFlags {
        online,
        mu_draw,
        protocol_a,
        ..
    } = case.flags;
    let depth = p.depth();
    let mut rng = Rng4::for_block(seed, block);
    let mut tau = vec![0usize; RUNS];
    let mut zeros = vec![0usize; RUNS];
    let mut counter = vec![0usize; RUNS];
    let mut hi = vec![true; RUNS];
    let mut hist = vec![vec![0u64; depth + 1]; RUNS];
    let mut out = Plain {
        acc: Vec::new(),
        sum: Vec::new(),
        delivered: vec![0; RUNS],
        sent: 0,
        blocked: 0,
        hi_last: 0,
    };
    for k in 0..horizon {
        let high: Vec<bool> = (0..RUNS)
            .map(|l| {
                if online {
                    hi[l]
                } else {
                    p.pattern[k % p.pattern.len()] == 1
                }
            })
            .collect();
        // Draws only for the low-power lanes.
        let lucky = rng.bernoulli(Portable, p.lam_thr, from_lanes(|l| !high[l]));
        let mut step_hist = vec![0u64; depth + 1];
        let mut arrive = vec![false; RUNS];
        for l in 0..RUNS {
            arrive[l] = high[l] || lane(&lucky, l);
            tau[l] = if arrive[l] {
                0
            } else {
                (tau[l] + 1).min(depth)
            };
            hist[l][tau[l]] += 1;
            if l < active {
                step_hist[tau[l]] += 1;
            }
        }
        if online {
            // The zero count the detector compares with its memory.
            let count: Vec<usize> = (0..RUNS)
                .map(|l| match mask {
                    None => tau[l],
                    Some(_) if arrive[l] => 0,
                    Some(_) => zeros[l] + 1,
                })
                .collect();
            // μ is drawn only where the count is exactly z0.
            let short = if mu_draw {
                rng.bernoulli(Portable, p.mu_thr, from_lanes(|l| count[l] == p.z0))
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
                        zeros[l] = if flag { 0 } else { count[l] };
                        let attacked = flag && mask[counter[l]];
                        if flag {
                            counter[l] = (counter[l] + 1) % mask.len();
                        }
                        attacked
                    }
                };
                hi[l] = if protocol_a {
                    flag ^ attacked
                } else {
                    flag && !attacked
                };
                out.sent += u64::from(flag) * counted;
                out.blocked += u64::from(attacked) * counted;
                out.delivered[l] += u64::from(hi[l]);
            }
        }
        out.acc.push(histogram_sum(&p.tr, &step_hist));
    }
    out.hi_last = if online {
        hi[..active].iter().filter(|&&h| h).count() as u64
    } else {
        0
    };
    out.sum = hist.iter().map(|h| histogram_sum(&p.tr, h)).collect();
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
fn run_case(
    case: &Case,
    block: u64,
    (horizon, active, record): (usize, usize, bool),
    avx2: Option<Avx2>,
) -> (BsOut, Vec<f64>) {
    let mut acc = vec![0.0; horizon];
    let mut b = BsBlock {
        seed: 3,
        block,
        active,
        record,
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

/// (horizon, active lanes, record) of the comparisons: a full block, partial ones, and a
/// horizon that is not a multiple of the batch.
const SHAPES: [(usize, usize, bool); 3] = [(333, RUNS, true), (40, 77, true), (17, 200, false)];

#[test]
fn matches_plain_per_lane_simulation() {
    for (i, case) in cases().iter().enumerate() {
        for shape in SHAPES {
            let (horizon, active, record) = shape;
            let (got, acc) = run_case(case, i as u64, shape, None);
            let want = plain(case, horizon, active, 3, i as u64);
            assert_eq!(acc, want.acc, "case {i} horizon {horizon}");
            assert_eq!(got.sum, want.sum, "case {i}");
            assert_eq!(
                (got.sent, got.blocked, got.hi_last),
                (want.sent, want.blocked, want.hi_last),
                "case {i}"
            );
            if record {
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
