//! The bit-sliced kernel's word operations (Bernoulli draws, counters, comparisons) against plain
//! integer arithmetic; `kernel` checks the whole kernel.

use super::words::*;
use super::*;
use crate::montecarlo::cpu::Avx2;

pub(crate) use super::words::{from_lanes, lane};

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
        let thr = crate::montecarlo::rng::bernoulli_threshold(p);
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

mod kernel;
