//! Four-lane operations on plain arrays: the portable instantiation of the grouped kernel.

use super::resolve_ties4;
use super::Proto;
use crate::montecarlo::rng::Xoshiro256pp;
use crate::montecarlo::{SLICES_PER_WORD, SLICE_BITS, SLICE_MASK};

/// Four u64 lanes.
pub(super) type U = [u64; 4];
/// Four f64 lanes.
pub(super) type F = [f64; 4];

/// `[f(0), f(1), f(2), f(3)]` for the body `|i| f(i)`.
macro_rules! map {
    (|$i:ident| $e:expr) => {{
        let mut out = [Default::default(); 4];
        for ($i, o) in out.iter_mut().enumerate() {
            *o = $e;
        }
        out
    }};
}

/// `x` in every lane.
#[inline(always)]
pub(super) fn splat(x: u64) -> U {
    [x; 4]
}
/// Loads `a[0..4]`.
#[inline(always)]
pub(super) fn load(a: &[u64]) -> U {
    [a[0], a[1], a[2], a[3]]
}
/// Stores `v` to `a[0..4]`.
#[inline(always)]
pub(super) fn store(a: &mut [u64], v: U) {
    a[..4].copy_from_slice(&v);
}
/// Loads `a[0..4]`.
#[inline(always)]
pub(super) fn fload(a: &[f64]) -> F {
    [a[0], a[1], a[2], a[3]]
}
/// Stores `v` to `a[0..4]`.
#[inline(always)]
pub(super) fn fstore(a: &mut [f64], v: F) {
    a[..4].copy_from_slice(&v);
}
/// Wrapping `a + b`.
#[inline(always)]
pub(super) fn add(a: U, b: U) -> U {
    map!(|i| a[i].wrapping_add(b[i]))
}
/// Wrapping `a - b`.
#[inline(always)]
pub(super) fn sub(a: U, b: U) -> U {
    map!(|i| a[i].wrapping_sub(b[i]))
}
/// `a & b`.
#[inline(always)]
pub(super) fn and(a: U, b: U) -> U {
    map!(|i| a[i] & b[i])
}
/// `a | b`.
#[inline(always)]
pub(super) fn or(a: U, b: U) -> U {
    map!(|i| a[i] | b[i])
}
/// `a ^ b`.
#[inline(always)]
pub(super) fn xor(a: U, b: U) -> U {
    map!(|i| a[i] ^ b[i])
}
/// `!a & b`.
#[inline(always)]
pub(super) fn andnot(a: U, b: U) -> U {
    map!(|i| !a[i] & b[i])
}
/// `a >> N`.
#[inline(always)]
pub(super) fn shr<const N: u32>(a: U) -> U {
    map!(|i| a[i] >> N)
}
/// Signed a > b as a lane mask (lane values stay below 2^63).
#[inline(always)]
pub(super) fn gt(a: U, b: U) -> U {
    map!(|i| if (a[i] as i64) > (b[i] as i64) {
        u64::MAX
    } else {
        0
    })
}
/// a == b as a lane mask.
#[inline(always)]
pub(super) fn eq(a: U, b: U) -> U {
    map!(|i| if a[i] == b[i] { u64::MAX } else { 0 })
}
/// `m ? t : f` per lane.
#[inline(always)]
pub(super) fn blend(m: U, t: U, f: U) -> U {
    map!(|i| if m[i] != 0 { t[i] } else { f[i] })
}
/// `a + b`.
#[inline(always)]
pub(super) fn fadd(a: F, b: F) -> F {
    map!(|i| a[i] + b[i])
}
/// Bitwise `x & m` (keeps x where m is all ones, +0.0 where it is zero).
#[inline(always)]
pub(super) fn fmask(x: F, m: U) -> F {
    map!(|i| f64::from_bits(x[i].to_bits() & m[i]))
}
/// Bit `c` of the blocking mask, 0 or 1 (`c < 64 mask.len()`).
#[inline(always)]
pub(super) fn mask_bit(mask: &[u64], c: U) -> U {
    let last = mask.len().saturating_sub(1);
    map!(|i| mask
        .get(((c[i] >> 6) as usize).min(last))
        .map_or(0, |w| (w >> (c[i] & 63)) & 1))
}

/// A value table prepared for [`lookup`].
pub(super) struct Table<'a> {
    /// The values.
    tr: &'a [f64],
    /// The last index read.
    last: usize,
}
/// Prepares `tr` for lookups up to index `last` (clamped to the table).
#[inline(always)]
pub(super) fn table(tr: &[f64], last: u64) -> Table<'_> {
    Table {
        tr,
        last: (last as usize).min(tr.len().saturating_sub(1)),
    }
}
/// tr[min(τ, last)].
#[inline(always)]
pub(super) fn lookup(t: &Table, idx: U) -> F {
    map!(|i| t
        .tr
        .get((idx[i] as usize).min(t.last))
        .copied()
        .unwrap_or(f64::INFINITY))
}

/// Four xoshiro256++ lanes and their current word of 16-bit slices.
pub(super) struct Stream {
    /// The xoshiro256++ state words, each over the four lanes.
    s: [U; 4],
    /// Each lane's current random word.
    slice_word: U,
    /// Slices left in `slice_word`.
    slices_left: u32,
}

impl Stream {
    /// The streams of lanes lo..lo+4 of `p`, with `slices_left` slices left in their words.
    #[inline(always)]
    pub(super) fn load(p: &Proto, lo: usize, slices_left: u32) -> Self {
        Stream {
            s: [
                load(&p.s0[lo..]),
                load(&p.s1[lo..]),
                load(&p.s2[lo..]),
                load(&p.s3[lo..]),
            ],
            slice_word: load(&p.slice_word[lo..]),
            slices_left,
        }
    }
    /// Writes the streams back to lanes lo..lo+4 of `p`; returns the slices left.
    #[inline(always)]
    pub(super) fn store(&self, p: &mut Proto, lo: usize) -> u32 {
        store(&mut p.s0[lo..], self.s[0]);
        store(&mut p.s1[lo..], self.s[1]);
        store(&mut p.s2[lo..], self.s[2]);
        store(&mut p.s3[lo..], self.s[3]);
        store(&mut p.slice_word[lo..], self.slice_word);
        self.slices_left
    }
    /// An exact Bernoulli(T / 2^64) draw per lane, T = top·2^48 + rest, as a lane mask.
    #[inline(always)]
    pub(super) fn draw(&mut self, top: U, rest: u64, side: &mut [Xoshiro256pp]) -> U {
        if self.slices_left == 0 {
            self.slice_word = crate::montecarlo::rng::xoshiro256pp_x4(&mut self.s);
            self.slices_left = SLICES_PER_WORD;
        }
        self.slices_left -= 1;
        let u = and(self.slice_word, splat(SLICE_MASK));
        self.slice_word = shr::<SLICE_BITS>(self.slice_word);
        let mut hit = gt(top, u);
        let tie = eq(u, top);
        if tie.iter().any(|&t| t != 0) {
            resolve_ties4(&mut hit, &tie, side, rest);
        }
        hit
    }
}
