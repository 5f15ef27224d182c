//! Word-parallel building blocks of the bit-sliced kernel: lane words of 256 runs, their random
//! source, comparisons of binary counters with constants, and per-lane counters.

#[cfg(target_arch = "x86_64")]
use crate::montecarlo::cpu::Avx2;
use crate::montecarlo::rng::{bernoulli_threshold, xoshiro256pp_x4, SplitMix64, Xoshiro256pp};

/// Words per block; 64 runs per word.
pub(crate) const WORDS: usize = 4;
/// Runs per block.
pub(crate) const RUNS: usize = 64 * WORDS;
/// Steps per carry-save batch of [`LaneCounter::add16`].
pub(crate) const BATCH: usize = 16;

/// One bit per run.
pub(crate) type W = [u64; WORDS];
/// No run.
pub(crate) const ZERO: W = [0; WORDS];
/// Every run.
pub(crate) const ONES: W = [u64::MAX; WORDS];

/// a & b
#[inline(always)]
pub(crate) fn and(a: W, b: W) -> W {
    std::array::from_fn(|i| a[i] & b[i])
}
/// a | b
#[inline(always)]
pub(crate) fn or(a: W, b: W) -> W {
    std::array::from_fn(|i| a[i] | b[i])
}
/// a ^ b
#[inline(always)]
pub(crate) fn xor(a: W, b: W) -> W {
    std::array::from_fn(|i| a[i] ^ b[i])
}
/// a & !b
#[inline(always)]
pub(crate) fn andnot(a: W, b: W) -> W {
    std::array::from_fn(|i| a[i] & !b[i])
}
/// !a
#[inline(always)]
pub(crate) fn not(a: W) -> W {
    std::array::from_fn(|i| !a[i])
}
/// Whether any run's bit is set.
#[inline(always)]
pub(crate) fn any(a: W) -> bool {
    (a[0] | a[1] | a[2] | a[3]) != 0
}
/// The number of runs whose bit is set.
#[inline(always)]
pub(crate) fn popcount(a: W) -> u32 {
    a.iter().map(|w| w.count_ones()).sum()
}
/// All ones if `b`, else all zeros.
#[inline(always)]
pub(crate) fn splat(b: bool) -> W {
    [0u64.wrapping_sub(u64::from(b)); WORDS]
}

/// A Bernoulli probability as the kernel draws it: the exact threshold T = ⌊p 2^64⌋ (a draw
/// hits with probability T / 2^64), or certainty for p = 1, where 2^64 does not fit (T is then
/// 0 and unused).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Prob {
    /// ⌊p 2^64⌋ (0 when `one`).
    pub(crate) thr: u64,
    /// p = 1: every draw hits, no random word is read.
    pub(crate) one: bool,
}

impl Prob {
    /// The draw of probability `p` in [0, 1].
    pub(crate) fn new(p: f64) -> Self {
        let one = p >= 1.0;
        Prob {
            thr: if one { 0 } else { bernoulli_threshold(p) },
            one,
        }
    }
}

/// Bit `l` of a lane word.
#[cfg(test)]
pub(crate) fn lane(w: &W, l: usize) -> bool {
    (w[l / 64] >> (l % 64)) & 1 == 1
}

/// The lane word whose bit l is `f(l)`.
#[cfg(test)]
pub(crate) fn from_lanes(f: impl Fn(usize) -> bool) -> W {
    let mut w = ZERO;
    for l in 0..RUNS {
        w[l / 64] |= u64::from(f(l)) << (l % 64);
    }
    w
}

/// How [`Rng4`] steps its four streams: [`Portable`] on any CPU, or [`Avx2`] in AVX2 registers
/// (the token proves the CPU's support). Both give the same words.
pub(crate) trait StreamStepper: Copy {
    /// One xoshiro256++ step of the four streams `s` (transposed, as [`xoshiro256pp_x4`] takes
    /// them); returns their outputs.
    fn step(self, s: &mut [W; 4]) -> W;
}

/// Steps the streams with plain u64 arithmetic (LLVM keeps it scalar: AVX2 has no 64-bit
/// rotate).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

impl StreamStepper for Portable {
    #[inline(always)]
    fn step(self, s: &mut [W; 4]) -> W {
        xoshiro256pp_x4(s)
    }
}

#[cfg(target_arch = "x86_64")]
impl StreamStepper for Avx2 {
    #[inline(always)]
    fn step(self, s: &mut [W; 4]) -> W {
        // SAFETY: `self` is a token that only `Avx2::detect` makes, on a CPU with AVX2, the one
        // feature `next_avx2` is compiled for.
        unsafe { next_avx2(s) }
    }
}

/// Four xoshiro256++ streams, one per word: bit l of a word is run (64 w + l)'s random bit.
pub(crate) struct Rng4 {
    /// The streams' state, transposed: `s[k][w]` is state word k of word w's stream.
    pub(crate) s: [W; 4],
}

impl Rng4 {
    /// The streams of block `block`: SplitMix64 sub-stream (seed, block), one xoshiro256++ per
    /// word, so a block's randomness depends on (seed, block) alone.
    pub(crate) fn for_block(seed: u64, block: u64) -> Self {
        let mut stream = SplitMix64::stream(seed, block);
        let seeds: [[u64; 4]; WORDS] =
            std::array::from_fn(|_| Xoshiro256pp::from_splitmix(&mut stream).state());
        const { assert!(WORDS == 4) };
        Rng4 {
            s: std::array::from_fn(|k| std::array::from_fn(|w| seeds[w][k])),
        }
    }

    /// The next word of each stream, stepped by `stepper`.
    #[inline(always)]
    pub(crate) fn next<S: StreamStepper>(&mut self, stepper: S) -> W {
        stepper.step(&mut self.s)
    }

    /// One Bernoulli(thr / 2^64) draw for each lane of `need` (0 elsewhere): lane l hits iff
    /// its uniform U (bit i of U is bit l of the i-th word drawn, most significant first) is
    /// below thr. Stops once every needed lane is decided, or when thr has no one bit left (the
    /// undecided lanes then have U >= thr); draws no word when no lane needs one.
    #[inline(always)]
    pub(crate) fn bernoulli<S: StreamStepper>(&mut self, stepper: S, thr: u64, need: W) -> W {
        let mut hit = ZERO;
        if thr == 0 || !any(need) {
            return hit;
        }
        let mut undecided = need;
        let mut bit = 63u32;
        loop {
            let r = self.next(stepper);
            if (thr >> bit) & 1 == 1 {
                hit = or(hit, andnot(undecided, r));
                undecided = and(undecided, r);
            } else {
                undecided = andnot(undecided, r);
            }
            if bit == 0 || thr & ((1u64 << bit) - 1) == 0 || !any(undecided) {
                return hit;
            }
            bit -= 1;
        }
    }

    /// One draw for each lane of `need` (0 elsewhere) of probability `b` in the lanes of `sel`
    /// and `a` in the others: the lanes of a certain probability hit without a draw, and the
    /// others compare their uniform U (built as in [`Rng4::bernoulli`]) with their own threshold,
    /// bit by bit, the threshold's bit picked per lane by `sel`. Each lane hits iff U < T of its
    /// probability, exactly; stops once every needed lane is decided (a lane whose threshold has
    /// no one bit left is decided: U >= T). With `a == b` it is [`Rng4::bernoulli`] itself.
    #[inline(always)]
    pub(crate) fn bernoulli_sel<S: StreamStepper>(
        &mut self,
        stepper: S,
        (a, b): (Prob, Prob),
        sel: W,
        need: W,
    ) -> W {
        if a == b {
            return if a.one {
                need
            } else {
                self.bernoulli(stepper, a.thr, need)
            };
        }
        let certain = or(and(sel, splat(b.one)), andnot(splat(a.one), sel));
        let mut hit = and(need, certain);
        let mut undecided = andnot(need, certain);
        // Remaining threshold bits, per probability; a lane whose threshold has none left is a
        // miss (a certain probability's threshold is 0: its lanes are already decided).
        let (ta, tb) = (a.thr, b.thr);
        let mut bit = 63u32;
        let mut rest = u64::MAX;
        loop {
            if ta & rest == 0 {
                undecided = and(undecided, sel);
            }
            if tb & rest == 0 {
                undecided = andnot(undecided, sel);
            }
            if !any(undecided) {
                return hit;
            }
            let r = self.next(stepper);
            // Each lane's threshold bit: `b`'s where `sel`, else `a`'s.
            let t = or(
                and(sel, splat((tb >> bit) & 1 == 1)),
                andnot(splat((ta >> bit) & 1 == 1), sel),
            );
            // Threshold bit 1 and U's bit 0: U < T. Unequal bits decide the lane.
            hit = or(hit, and(undecided, andnot(t, r)));
            undecided = andnot(undecided, xor(t, r));
            if bit == 0 {
                return hit;
            }
            rest = (1u64 << bit) - 1;
            bit -= 1;
        }
    }
}

/// [`xoshiro256pp_x4`] on AVX2 registers, for [`Rng4`]'s transposed state. Compiled for AVX2:
/// calling it is `unsafe` except from AVX2 code.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
fn next_avx2(s: &mut [W; 4]) -> W {
    use std::arch::x86_64::{__m256i, _mm256_loadu_si256, _mm256_storeu_si256};
    let mut v: [__m256i; 4] = std::array::from_fn(|k| {
        // SAFETY: `s[k]` holds the 4 u64s (32 bytes) read; the unaligned load takes any address.
        unsafe { _mm256_loadu_si256(s[k].as_ptr().cast::<__m256i>()) }
    });
    let out = crate::montecarlo::rng::xoshiro256pp_x4_avx2(&mut v);
    for (k, w) in s.iter_mut().enumerate() {
        // SAFETY: `w` holds the 4 u64s (32 bytes) written; the unaligned store takes any address.
        unsafe { _mm256_storeu_si256(w.as_mut_ptr().cast::<__m256i>(), v[k]) };
    }
    let mut r = ZERO;
    // SAFETY: `r` holds the 4 u64s (32 bytes) written; the unaligned store takes any address.
    unsafe { _mm256_storeu_si256(r.as_mut_ptr().cast::<__m256i>(), out) };
    r
}

/// Lanes whose binary counter (planes `s`, least significant first) is below `c`.
#[inline(always)]
pub(crate) fn less_than(s: &[W], c: u64) -> W {
    if s.len() < 64 && c >> s.len() != 0 {
        return ONES;
    }
    let (mut lt, mut eq) = (ZERO, ONES);
    for (i, plane) in s.iter().enumerate().rev() {
        if (c >> i) & 1 == 1 {
            lt = or(lt, andnot(eq, *plane));
            eq = and(eq, *plane);
        } else {
            eq = andnot(eq, *plane);
        }
    }
    lt
}

/// Lanes whose binary counter equals `c`.
#[inline(always)]
pub(crate) fn equals(s: &[W], c: u64) -> W {
    if s.len() < 64 && c >> s.len() != 0 {
        return ZERO;
    }
    let mut eq = ONES;
    for (i, plane) in s.iter().enumerate() {
        eq = if (c >> i) & 1 == 1 {
            and(eq, *plane)
        } else {
            andnot(eq, *plane)
        };
    }
    eq
}

/// Adds one to the binary counters of the lanes in `inc`.
#[inline(always)]
pub(crate) fn increment(s: &mut [W], inc: W) {
    let mut carry = inc;
    for plane in s.iter_mut() {
        let next = and(*plane, carry);
        *plane = xor(*plane, carry);
        carry = next;
    }
}

/// Carry-save adder: (carry, sum) of a + b + c per bit.
#[inline(always)]
fn csa(a: W, b: W, c: W) -> (W, W) {
    let u = xor(a, b);
    (or(and(a, b), and(u, c)), xor(u, c))
}

/// Per-lane counts of set bits over a stream of words: Harley-Seal carry-save adders over
/// batches of 16 words, the sixteens rippled into a vertical binary counter.
#[derive(Clone, Copy)]
pub(crate) struct LaneCounter {
    /// Bit 0 of each lane's count within the current sixteen.
    ones: W,
    /// Bit 1.
    twos: W,
    /// Bit 2.
    fours: W,
    /// Bit 3.
    eights: W,
    /// Planes of the count of sixteens (2^32 · 16 exceeds any horizon).
    sixteens: [W; 32],
}

impl LaneCounter {
    /// All counts zero.
    pub(crate) const NEW: LaneCounter = LaneCounter {
        ones: ZERO,
        twos: ZERO,
        fours: ZERO,
        eights: ZERO,
        sixteens: [ZERO; 32],
    };

    /// Adds the bits of a batch of [`BATCH`] words to each lane's count.
    #[inline(always)]
    pub(crate) fn add16(&mut self, d: &[W; BATCH]) {
        let (twos_a, ones) = csa(self.ones, d[0], d[1]);
        let (twos_b, ones) = csa(ones, d[2], d[3]);
        let (fours_a, twos) = csa(self.twos, twos_a, twos_b);
        let (twos_a, ones) = csa(ones, d[4], d[5]);
        let (twos_b, ones) = csa(ones, d[6], d[7]);
        let (fours_b, twos) = csa(twos, twos_a, twos_b);
        let (eights_a, fours) = csa(self.fours, fours_a, fours_b);
        let (twos_a, ones) = csa(ones, d[8], d[9]);
        let (twos_b, ones) = csa(ones, d[10], d[11]);
        let (fours_a, twos) = csa(twos, twos_a, twos_b);
        let (twos_a, ones) = csa(ones, d[12], d[13]);
        let (twos_b, ones) = csa(ones, d[14], d[15]);
        let (fours_b, twos) = csa(twos, twos_a, twos_b);
        let (eights_b, fours) = csa(fours, fours_a, fours_b);
        let (mut carry, eights) = csa(self.eights, eights_a, eights_b);
        (self.ones, self.twos, self.fours, self.eights) = (ones, twos, fours, eights);
        for plane in self.sixteens.iter_mut() {
            if !any(carry) {
                break;
            }
            let next = and(*plane, carry);
            *plane = xor(*plane, carry);
            carry = next;
        }
    }

    /// The sum of the counts of the lanes in `lanes`.
    pub(crate) fn total(&self, lanes: W) -> u64 {
        let planes = [self.ones, self.twos, self.fours, self.eights];
        planes
            .iter()
            .chain(self.sixteens.iter())
            .enumerate()
            .map(|(weight, plane)| u64::from(popcount(and(*plane, lanes))) << weight)
            .sum()
    }

    /// Each lane's count as binary planes, least significant first (after a whole batch).
    pub(crate) fn planes(&self) -> [W; 36] {
        let mut out = [ZERO; 36];
        out[..4].copy_from_slice(&[self.ones, self.twos, self.fours, self.eights]);
        out[4..].copy_from_slice(&self.sixteens);
        out
    }

    /// Every lane's count.
    #[inline(always)]
    pub(crate) fn counts(&self) -> [u64; RUNS] {
        let mut out = [0u64; RUNS];
        let planes = [self.ones, self.twos, self.fours, self.eights];
        for (weight, plane) in planes.iter().chain(self.sixteens.iter()).enumerate() {
            if !any(*plane) {
                continue;
            }
            for (l, n) in out.iter_mut().enumerate() {
                *n += ((plane[l / 64] >> (l % 64)) & 1) << weight;
            }
        }
        out
    }
}
