//! The four-lane operations of `lanes4` on AVX2 registers.
//!
//! Every function is compiled for AVX2 (`#[target_feature]`): other AVX2 functions call them
//! safely, and code elsewhere only through an `unsafe` call justified by an
//! [`Avx2`](crate::montecarlo::cpu::Avx2) token (`grouped::group_rows`). Memory is read and
//! written only through bounds-checked slices or with indices clamped into their table, so no
//! argument makes them touch memory out of bounds.

use std::arch::x86_64::*;

use super::resolve_ties4;
use super::Proto;
use crate::montecarlo::rng::Xoshiro256pp;
use crate::montecarlo::{SLICES_PER_WORD, SLICE_MASK};

/// Four u64 lanes.
pub(super) type U = __m256i;
/// Four f64 lanes.
pub(super) type F = __m256d;

/// `x` in every lane.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn splat(x: u64) -> U {
    _mm256_set1_epi64x(x as i64)
}
/// Loads `a[0..4]` (panics if `a` holds fewer than 4 elements).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn load(a: &[u64]) -> U {
    let a = &a[..4];
    // SAFETY: `a` holds the 4 u64s (32 bytes) read; the unaligned load takes any address.
    unsafe { _mm256_loadu_si256(a.as_ptr().cast::<__m256i>()) }
}
/// Stores `v` to `a[0..4]` (panics if `a` holds fewer than 4 elements).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn store(a: &mut [u64], v: U) {
    let a = &mut a[..4];
    // SAFETY: `a` holds the 4 u64s (32 bytes) written; the unaligned store takes any address.
    unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast::<__m256i>(), v) }
}
/// Loads `a[0..4]` (panics if `a` holds fewer than 4 elements).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn fload(a: &[f64]) -> F {
    let a = &a[..4];
    // SAFETY: `a` holds the 4 f64s (32 bytes) read; the unaligned load takes any address.
    unsafe { _mm256_loadu_pd(a.as_ptr()) }
}
/// Stores `v` to `a[0..4]` (panics if `a` holds fewer than 4 elements).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn fstore(a: &mut [f64], v: F) {
    let a = &mut a[..4];
    // SAFETY: `a` holds the 4 f64s (32 bytes) written; the unaligned store takes any address.
    unsafe { _mm256_storeu_pd(a.as_mut_ptr(), v) }
}
/// Wrapping `a + b`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn add(a: U, b: U) -> U {
    _mm256_add_epi64(a, b)
}
/// Wrapping `a - b`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn sub(a: U, b: U) -> U {
    _mm256_sub_epi64(a, b)
}
/// `a & b`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn and(a: U, b: U) -> U {
    _mm256_and_si256(a, b)
}
/// `a | b`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn or(a: U, b: U) -> U {
    _mm256_or_si256(a, b)
}
/// `a ^ b`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn xor(a: U, b: U) -> U {
    _mm256_xor_si256(a, b)
}
/// `!a & b`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn andnot(a: U, b: U) -> U {
    _mm256_andnot_si256(a, b)
}
/// `a >> N` (logical).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn shr<const N: i32>(a: U) -> U {
    _mm256_srli_epi64::<N>(a)
}
/// Signed a > b as a lane mask.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn gt(a: U, b: U) -> U {
    _mm256_cmpgt_epi64(a, b)
}
/// a == b as a lane mask.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn eq(a: U, b: U) -> U {
    _mm256_cmpeq_epi64(a, b)
}
/// `m ? t : f` per lane (m a lane mask).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn blend(m: U, t: U, f: U) -> U {
    _mm256_blendv_epi8(f, t, m)
}
/// `a + b`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn fadd(a: F, b: F) -> F {
    _mm256_add_pd(a, b)
}
/// Bitwise `x & m` (keeps x where m is all ones, +0.0 where it is zero).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn fmask(x: F, m: U) -> F {
    _mm256_and_pd(x, _mm256_castsi256_pd(m))
}
/// Bit `c` of the blocking mask, 0 or 1. A counter beyond the mask reads the mask's last word
/// and an empty mask reads zeros, as in the portable version (the kernels keep c below
/// `mask_len`).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn mask_bit(mask: &[u64], c: U) -> U {
    let word = if mask.len() == 1 {
        _mm256_set1_epi64x(mask[0] as i64)
    } else if mask.is_empty() {
        _mm256_setzero_si256()
    } else {
        let last = _mm256_set1_epi64x(mask.len() as i64 - 1);
        // c >> 6 is below 2^58, so the signed compare is exact.
        let index = _mm256_srli_epi64::<6>(c);
        let index = _mm256_blendv_epi8(index, last, _mm256_cmpgt_epi64(index, last));
        // SAFETY: every lane's index is in 0..mask.len() (clamped just above), and the gather
        // reads one u64 of `mask` at each.
        unsafe { _mm256_i64gather_epi64::<8>(mask.as_ptr().cast::<i64>(), index) }
    };
    let shift = _mm256_and_si256(c, _mm256_set1_epi64x(63));
    _mm256_and_si256(_mm256_srlv_epi64(word, shift), _mm256_set1_epi64x(1))
}

/// How `lookup` reads the table: in-register permutes for up to 8 entries, else a gather.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// At most 4 entries: one permute.
    Perm4,
    /// At most 8 entries: two permutes and a blend.
    Perm8,
    /// More: a gather from memory.
    Gather,
}

/// A value table prepared for [`lookup`].
pub(super) struct Table<'a> {
    /// How [`lookup`] reads it.
    kind: Kind,
    /// Entries 0..4 (clamped to `last`), for the permutes.
    lo: U,
    /// Entries 4..8 (clamped to `last`).
    hi: U,
    /// The table, for the gather; never empty.
    tr: &'a [f64],
    /// The last index read, below `tr.len()`, in every lane.
    last: U,
}

/// Prepares `tr` for lookups up to index `last`, clamped to the table (an empty table reads
/// +inf, as in the portable version).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn table(tr: &[f64], last: u64) -> Table<'_> {
    let tr: &[f64] = if tr.is_empty() { &[f64::INFINITY] } else { tr };
    let last = last.min(tr.len() as u64 - 1);
    let entry = |i: usize| tr[i.min(last as usize)];
    Table {
        kind: match last {
            0..=3 => Kind::Perm4,
            4..=7 => Kind::Perm8,
            _ => Kind::Gather,
        },
        lo: _mm256_castpd_si256(_mm256_setr_pd(entry(0), entry(1), entry(2), entry(3))),
        hi: _mm256_castpd_si256(_mm256_setr_pd(entry(4), entry(5), entry(6), entry(7))),
        tr,
        last: _mm256_set1_epi64x(last as i64),
    }
}
/// tr[min(τ, last)].
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn lookup(t: &Table, tau: U) -> F {
    let idx = _mm256_blendv_epi8(tau, t.last, _mm256_cmpgt_epi64(tau, t.last));
    match t.kind {
        Kind::Gather => {
            // τ >= 2^63 is negative as a signed lane and escaped the clamp: clamp it too.
            let negative = _mm256_cmpgt_epi64(_mm256_setzero_si256(), idx);
            let idx = _mm256_blendv_epi8(idx, t.last, negative);
            // SAFETY: every lane's index is in 0..=last, and last < t.tr.len() (`table`); the
            // gather reads one f64 of `t.tr` at each.
            unsafe { _mm256_i64gather_pd::<8>(t.tr.as_ptr(), idx) }
        }
        kind => {
            // Index pairs (2i, 2i+1) of 32-bit halves select the doubles in-register.
            let twice = _mm256_slli_epi64::<1>(idx);
            let pairs = _mm256_add_epi32(
                _mm256_shuffle_epi32::<0b10_10_00_00>(twice),
                _mm256_setr_epi32(0, 1, 0, 1, 0, 1, 0, 1),
            );
            let low = _mm256_permutevar8x32_epi32(t.lo, pairs);
            if kind == Kind::Perm4 {
                _mm256_castsi256_pd(low)
            } else {
                let high = _mm256_permutevar8x32_epi32(t.hi, pairs);
                let upper = _mm256_cmpgt_epi64(idx, _mm256_set1_epi64x(3));
                _mm256_castsi256_pd(_mm256_blendv_epi8(low, high, upper))
            }
        }
    }
}

/// Four xoshiro256++ lanes and their current word of 16-bit slices.
pub(super) struct Stream {
    /// xoshiro256++ state word 0 of the four lanes.
    s0: U,
    /// State word 1.
    s1: U,
    /// State word 2.
    s2: U,
    /// State word 3.
    s3: U,
    /// Each lane's current random word.
    slice_word: U,
    /// Slices left in `slice_word`.
    slices_left: u32,
}

impl Stream {
    /// The streams of lanes lo..lo+4 of `p`, with `slices_left` slices left in their words.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn load(p: &Proto, lo: usize, slices_left: u32) -> Self {
        Stream {
            s0: load(&p.s0[lo..]),
            s1: load(&p.s1[lo..]),
            s2: load(&p.s2[lo..]),
            s3: load(&p.s3[lo..]),
            slice_word: load(&p.slice_word[lo..]),
            slices_left,
        }
    }
    /// Writes the streams back to lanes lo..lo+4 of `p`; returns the slices left.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn store(&self, p: &mut Proto, lo: usize) -> u32 {
        store(&mut p.s0[lo..], self.s0);
        store(&mut p.s1[lo..], self.s1);
        store(&mut p.s2[lo..], self.s2);
        store(&mut p.s3[lo..], self.s3);
        store(&mut p.slice_word[lo..], self.slice_word);
        self.slices_left
    }
    /// An exact Bernoulli(T / 2^64) draw per lane, T = top·2^48 + rest, as a lane mask.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn draw(&mut self, top: U, rest: u64, side: &mut [Xoshiro256pp]) -> U {
        if self.slices_left == 0 {
            let mut s = [self.s0, self.s1, self.s2, self.s3];
            self.slice_word = crate::montecarlo::rng::xoshiro256pp_x4_avx2(&mut s);
            [self.s0, self.s1, self.s2, self.s3] = s;
            self.slices_left = SLICES_PER_WORD;
        }
        self.slices_left -= 1;
        let u = _mm256_and_si256(self.slice_word, _mm256_set1_epi64x(SLICE_MASK as i64));
        self.slice_word = _mm256_srli_epi64::<16>(self.slice_word);
        // Slices are below 2^16, so the signed compare is exact.
        let mut hit = _mm256_cmpgt_epi64(top, u);
        let tie = _mm256_cmpeq_epi64(u, top);
        if _mm256_movemask_pd(_mm256_castsi256_pd(tie)) != 0 {
            let (mut h, mut t) = ([0u64; 4], [0u64; 4]);
            store(&mut h, hit);
            store(&mut t, tie);
            resolve_ties4(&mut h, &t, side, rest);
            hit = load(&h);
        }
        hit
    }
}
