use super::grouped::resolve_ties4;
use super::Proto;
use crate::montecarlo::{SLICES_PER_WORD, SLICE_MASK};
use crate::rng::Xoshiro256pp;
use std::arch::x86_64::*;

pub(super) type U = __m256i;
pub(super) type F = __m256d;

#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn splat(x: u64) -> U {
    _mm256_set1_epi64x(x as i64)
}
/// Loads `a[0..4]` (a must hold at least 4 elements).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn load(a: &[u64]) -> U {
    let a = &a[..4];
    _mm256_loadu_si256(a.as_ptr() as *const __m256i)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn store(a: &mut [u64], v: U) {
    let a = &mut a[..4];
    _mm256_storeu_si256(a.as_mut_ptr() as *mut __m256i, v)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn fload(a: &[f64]) -> F {
    let a = &a[..4];
    _mm256_loadu_pd(a.as_ptr())
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn fstore(a: &mut [f64], v: F) {
    let a = &mut a[..4];
    _mm256_storeu_pd(a.as_mut_ptr(), v)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn add(a: U, b: U) -> U {
    _mm256_add_epi64(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn sub(a: U, b: U) -> U {
    _mm256_sub_epi64(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn and(a: U, b: U) -> U {
    _mm256_and_si256(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn or(a: U, b: U) -> U {
    _mm256_or_si256(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn xor(a: U, b: U) -> U {
    _mm256_xor_si256(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn andnot(a: U, b: U) -> U {
    _mm256_andnot_si256(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn shr<const N: i32>(a: U) -> U {
    _mm256_srli_epi64::<N>(a)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn gt(a: U, b: U) -> U {
    _mm256_cmpgt_epi64(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn eq(a: U, b: U) -> U {
    _mm256_cmpeq_epi64(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn blend(m: U, t: U, f: U) -> U {
    _mm256_blendv_epi8(f, t, m)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn fadd(a: F, b: F) -> F {
    _mm256_add_pd(a, b)
}
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn fmask(x: F, m: U) -> F {
    _mm256_and_pd(x, _mm256_castsi256_pd(m))
}
/// Bit `c` of the blocking mask, 0 or 1. Requires `c < 64 mask.len()`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn mask_bit(mask: &[u64], c: U) -> U {
    let word = if mask.len() == 1 {
        _mm256_set1_epi64x(mask[0] as i64)
    } else {
        _mm256_i64gather_epi64::<8>(mask.as_ptr() as *const i64, _mm256_srli_epi64::<6>(c))
    };
    let shift = _mm256_and_si256(c, _mm256_set1_epi64x(63));
    _mm256_and_si256(_mm256_srlv_epi64(word, shift), _mm256_set1_epi64x(1))
}

/// How `lookup` reads the table: in-register permutes for up to 8 entries, else a gather.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Perm4,
    Perm8,
    Gather,
}

pub(super) struct Table {
    kind: Kind,
    lo: U,
    hi: U,
    ptr: *const f64,
    last: U,
}

/// Requires `last < tr.len()`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn table(tr: &[f64], last: u64) -> Table {
    let entry = |i: usize| tr.get(i.min(last as usize)).copied().unwrap_or(0.0);
    Table {
        kind: match last {
            0..=3 => Kind::Perm4,
            4..=7 => Kind::Perm8,
            _ => Kind::Gather,
        },
        lo: _mm256_castpd_si256(_mm256_setr_pd(entry(0), entry(1), entry(2), entry(3))),
        hi: _mm256_castpd_si256(_mm256_setr_pd(entry(4), entry(5), entry(6), entry(7))),
        ptr: tr.as_ptr(),
        last: _mm256_set1_epi64x(last as i64),
    }
}
/// tr[min(τ, last)].
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn lookup(t: &Table, tau: U) -> F {
    let idx = _mm256_blendv_epi8(tau, t.last, _mm256_cmpgt_epi64(tau, t.last));
    match t.kind {
        Kind::Gather => _mm256_i64gather_pd::<8>(t.ptr, idx),
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

pub(super) struct Stream {
    s0: U,
    s1: U,
    s2: U,
    s3: U,
    slice_word: U,
    slices_left: u32,
}

impl Stream {
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn load(p: &Proto, lo: usize, slices_left: u32) -> Self {
        Stream {
            s0: load(&p.s0[lo..]),
            s1: load(&p.s1[lo..]),
            s2: load(&p.s2[lo..]),
            s3: load(&p.s3[lo..]),
            slice_word: load(&p.slice_word[lo..]),
            slices_left,
        }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn store(&self, p: &mut Proto, lo: usize) -> u32 {
        store(&mut p.s0[lo..], self.s0);
        store(&mut p.s1[lo..], self.s1);
        store(&mut p.s2[lo..], self.s2);
        store(&mut p.s3[lo..], self.s3);
        store(&mut p.slice_word[lo..], self.slice_word);
        self.slices_left
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn draw(&mut self, top: U, rest: u64, side: &mut [Xoshiro256pp]) -> U {
        if self.slices_left == 0 {
            let mut s = [self.s0, self.s1, self.s2, self.s3];
            self.slice_word = crate::rng::xoshiro256pp_x4_avx2(&mut s);
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
            _mm256_storeu_si256(h.as_mut_ptr() as *mut __m256i, hit);
            _mm256_storeu_si256(t.as_mut_ptr() as *mut __m256i, tie);
            resolve_ties4(&mut h, &t, side, rest);
            hit = _mm256_loadu_si256(h.as_ptr() as *const __m256i);
        }
        hit
    }
}
