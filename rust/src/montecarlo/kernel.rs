//! The lock-step covariance kernels: the per-lane protocol ([`Proto`]), the flag-ACK channels,
//! the 16-lane reference kernel and the grouped four-lane kernels (portable and AVX2) built from
//! one body, `group_body!`.

use std::sync::atomic::{AtomicBool, Ordering};

use super::{CHUNK_STEPS, LANES, SLICES_PER_WORD, SLICE_BITS, SLICE_MASK};
use crate::error::{Error, Result};
use crate::rng::Xoshiro256pp;

type Lanes = [u64; LANES];

/// Per-kernel constants.
#[derive(Clone, Copy)]
pub(super) struct Params<'a> {
    pub(super) lam_hi: u64,
    pub(super) lam_lo: u64,
    pub(super) mu_hi: u64,
    pub(super) mu_lo: u64,
    pub(super) z0: u64,
    /// z0 + 1 (the reference kernel's long memory).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) z0p1: u64,
    pub(super) l_fixed: u64,
    pub(super) mask: &'a [u64],
    pub(super) mask_len: u64,
    pub(super) pattern: &'a [u8],
    /// Largest τ (the table's last index).
    pub(super) last: u64,
}

/// Resolves ties of the 16-bit Bernoulli slices with 48 more bits from the side streams.
#[cfg(test)]
#[cold]
#[inline(never)]
fn resolve_ties(mut hit: Lanes, tie: Lanes, side: &mut [Xoshiro256pp; LANES], lo: u64) -> Lanes {
    for l in 0..LANES {
        if tie[l] != 0 {
            hit[l] = u64::from((side[l].next_u64() >> SLICE_BITS) < lo);
        }
    }
    hit
}

#[cfg(test)]
/// Bit `i` of the blocking mask (`i < mask_len`).
#[inline(always)]
fn mask_bit(mask: &[u64], i: u64) -> u64 {
    let w = ((i >> 6) as usize).min(mask.len().saturating_sub(1));
    mask.get(w).map_or(0, |word| (word >> (i & 63)) & 1)
}

#[cfg(test)]
/// Protocol B: a flag packet exists only when a flag is due; the attacker drops it per its mask.
/// Returns 1 where the sensor receives a flag.
#[inline(always)]
fn channel_b(flag: &Lanes, counter: &mut Lanes, blocked: &mut Lanes, p: &Params) -> Lanes {
    let mut delivered = [0u64; LANES];
    for l in 0..LANES {
        let packet = flag[l] != 0;
        let drop = u64::from(packet) & mask_bit(p.mask, counter[l]);
        let next = if counter[l] + 1 == p.mask_len {
            0
        } else {
            counter[l] + 1
        };
        if packet {
            counter[l] = next;
        }
        blocked[l] += drop;
        delivered[l] = u64::from(packet) & (drop ^ 1);
    }
    delivered
}

#[cfg(test)]
/// Protocol A: one bit every step (1 = flag); the attacker looks at 1-bits only and flips them to
/// 0 per its mask. Returns the bit the sensor receives.
#[inline(always)]
fn channel_a(flag: &Lanes, counter: &mut Lanes, blocked: &mut Lanes, p: &Params) -> Lanes {
    let mut received = [0u64; LANES];
    for l in 0..LANES {
        let bit = flag[l]; // the detector's 1-bit ACK of this step
        let flip = if bit == 1 {
            let f = mask_bit(p.mask, counter[l]);
            let c = counter[l] + 1;
            counter[l] = if c >= p.mask_len { c - p.mask_len } else { c };
            f
        } else {
            0
        };
        blocked[l] += flip;
        received[l] = bit ^ flip;
    }
    received
}

/// The protocol state of LANES runs.
pub(super) struct Proto {
    s0: Lanes,
    s1: Lanes,
    s2: Lanes,
    s3: Lanes,
    bits: Lanes,
    avail: u32,
    tau: Lanes,
    zeros: Lanes,
    counter: Lanes,
    /// 1 where the sensor uses Δ at the next step (online).
    pub(super) hi: Lanes,
    pub(super) sent: Lanes,
    pub(super) blocked: Lanes,
    pat: usize,
}

impl Proto {
    pub(super) fn new(seeds: &[[u64; 4]; LANES]) -> Self {
        let mut p = Proto {
            s0: [0; LANES],
            s1: [0; LANES],
            s2: [0; LANES],
            s3: [0; LANES],
            bits: [0; LANES],
            avail: 0,
            tau: [0; LANES],
            zeros: [0; LANES],
            counter: [0; LANES],
            hi: [1; LANES], // k = 1 is a high-power step
            sent: [0; LANES],
            blocked: [0; LANES],
            pat: 0,
        };
        for (l, s) in seeds.iter().enumerate() {
            p.s0[l] = s[0];
            p.s1[l] = s[1];
            p.s2[l] = s[2];
            p.s3[l] = s[3];
        }
        p
    }

    /// One xoshiro256++ step in every lane.
    #[cfg(test)]
    #[inline(always)]
    fn refill(&mut self) {
        for l in 0..LANES {
            let (s0, s1, s2, s3) = (self.s0[l], self.s1[l], self.s2[l], self.s3[l]);
            self.bits[l] = s0.wrapping_add(s3).rotate_left(23).wrapping_add(s0);
            let t = s1 << 17;
            let s2 = s2 ^ s0;
            let s3 = s3 ^ s1;
            let s1 = s1 ^ s2;
            let s0 = s0 ^ s3;
            self.s0[l] = s0;
            self.s1[l] = s1;
            self.s2[l] = s2 ^ t;
            self.s3[l] = s3.rotate_left(45);
        }
        self.avail = SLICES_PER_WORD;
    }

    /// An exact Bernoulli(T / 2^64) draw per lane, T = hi·2^48 + lo.
    #[cfg(test)]
    #[inline(always)]
    fn bernoulli(&mut self, hi: u64, lo: u64, side: &mut [Xoshiro256pp; LANES]) -> Lanes {
        if self.avail == 0 {
            self.refill();
        }
        self.avail -= 1;
        let mut hit = [0u64; LANES];
        let mut tie = [0u64; LANES];
        let mut any_tie = 0u64;
        for l in 0..LANES {
            let u = self.bits[l] & SLICE_MASK;
            self.bits[l] >>= SLICE_BITS;
            hit[l] = u64::from(u < hi);
            tie[l] = u64::from(u == hi);
            any_tie |= tie[l];
        }
        if any_tie != 0 {
            hit = resolve_ties(hit, tie, side, lo);
        }
        hit
    }

    /// Step k: returns 1 where the packet arrives, and updates τ, the detector, the channel and
    /// the attacker (the per-lane reference the grouped kernels are tested against).
    #[cfg(test)]
    #[inline(always)]
    pub(super) fn step<
        const ONLINE: bool,
        const MU_DRAW: bool,
        const ATTACK: bool,
        const PROTO_A: bool,
    >(
        &mut self,
        p: &Params,
        side: &mut [Xoshiro256pp; LANES],
    ) -> Lanes {
        let lucky = self.bernoulli(p.lam_hi, p.lam_lo, side);
        let high = if ONLINE {
            self.hi
        } else {
            let g = u64::from(p.pattern.get(self.pat).copied().unwrap_or(1));
            self.pat += 1;
            if self.pat >= p.pattern.len() {
                self.pat = 0;
            }
            [g; LANES]
        };
        let mut arrive = [0u64; LANES];
        for l in 0..LANES {
            arrive[l] = high[l] | lucky[l];
            // τ <= p.last always holds (p.last is the largest reachable τ or >= horizon - 1);
            // lookups clamp their index anyway.
            self.tau[l] = if arrive[l] != 0 {
                0
            } else {
                (self.tau[l] + 1).min(p.last)
            };
        }
        if ONLINE {
            let memory: Lanes = if MU_DRAW {
                let short = self.bernoulli(p.mu_hi, p.mu_lo, side);
                let mut m = [0u64; LANES];
                for l in 0..LANES {
                    m[l] = if short[l] != 0 { p.z0 } else { p.z0p1 };
                }
                m
            } else {
                [p.l_fixed; LANES]
            };
            let mut flag = [0u64; LANES];
            if ATTACK {
                for l in 0..LANES {
                    let z = if arrive[l] != 0 { 0 } else { self.zeros[l] + 1 };
                    flag[l] = u64::from(z >= memory[l]);
                    self.zeros[l] = if flag[l] != 0 { 0 } else { z };
                }
                self.hi = if PROTO_A {
                    channel_a(&flag, &mut self.counter, &mut self.blocked, p)
                } else {
                    channel_b(&flag, &mut self.counter, &mut self.blocked, p)
                };
            } else {
                // Without an attacker every flag is delivered and followed by an arrival, so the
                // zero count equals τ whenever it matters.
                for l in 0..LANES {
                    flag[l] = u64::from(self.tau[l] >= memory[l]);
                }
                self.hi = flag;
            }
            for (s, f) in self.sent.iter_mut().zip(flag) {
                *s += f;
            }
        }
        arrive
    }
}

/// Fixed-order sum of the lanes (a tree that maps onto vector shuffles).
#[inline(always)]
pub(super) fn lane_sum(v: &[f64; LANES]) -> f64 {
    let mut h = [0.0; LANES / 2];
    for i in 0..LANES / 2 {
        h[i] = v[i] + v[i + LANES / 2];
    }
    let mut q = [0.0; LANES / 4];
    for i in 0..LANES / 4 {
        q[i] = h[i] + h[i + LANES / 4];
    }
    let mut e = [0.0; LANES / 8];
    for i in 0..LANES / 8 {
        e[i] = q[i] + q[i + LANES / 8];
    }
    e[0] + e[1]
}

/// What one tile reports per lane.
pub(super) struct TileOut {
    pub(super) sum: [f64; LANES],
    pub(super) sent: Lanes,
    pub(super) blocked: Lanes,
    pub(super) hi_last: Lanes,
}

/// Inputs of one tile.
pub(super) struct Tile<'a> {
    pub(super) seeds: [[u64; 4]; LANES],
    pub(super) side: [Xoshiro256pp; LANES],
    pub(super) noise: [Xoshiro256pp; LANES],
    /// All ones for runs of this tile, 0 for padding lanes.
    pub(super) active: Lanes,
    pub(super) acc: &'a mut [f64],
}

/// The 16-lane covariance kernel on [`Proto::step`] (the reference for the grouped kernels).
#[cfg(test)]
fn cov_tile_impl<
    const ONLINE: bool,
    const MU_DRAW: bool,
    const ATTACK: bool,
    const PROTO_A: bool,
>(
    p: &Params,
    tr: &[f64],
    tile: &mut Tile,
    cancel: &AtomicBool,
) -> Result<TileOut> {
    let mut proto = Proto::new(&tile.seeds);
    let side = &mut tile.side;
    if tr.is_empty() {
        return Err(Error::invalid("sys", "empty trace table"));
    }
    let last = tr.len() - 1;
    let mut sum = [0.0f64; LANES];
    for chunk in tile.acc.chunks_mut(CHUNK_STEPS) {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for acc in chunk.iter_mut() {
            proto.step::<ONLINE, MU_DRAW, ATTACK, PROTO_A>(p, side);
            let mut v = [0.0f64; LANES];
            for l in 0..LANES {
                let x = tr[(proto.tau[l] as usize).min(last)];
                sum[l] += x;
                v[l] = f64::from_bits(x.to_bits() & tile.active[l]);
            }
            *acc += lane_sum(&v);
        }
    }
    Ok(TileOut {
        sum,
        sent: proto.sent,
        blocked: proto.blocked,
        hi_last: proto.hi,
    })
}

/// Covariance-mode kernels. All give bit-identical results (tests check it): the per-lane
/// protocol is the same integer logic and the f64 additions happen in the same order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Isa {
    /// Grouped kernel on plain arrays (any target; auto-vectorised where possible).
    Portable,
    /// Grouped kernel on AVX2 registers (x86-64, chosen at run time).
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// The 16-lane [`Proto::step`] kernel: the reference in tests.
    #[cfg(test)]
    Reference,
}

pub(super) fn detect_isa() -> Isa {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            return Isa::Avx2;
        }
    }
    Isa::Portable
}

/// Steps per sub-chunk of the grouped kernels: each group of 4 lanes runs this many steps with
/// its state in registers and writes its masked per-step values to a buffer (16 KiB), which is
/// then reduced per step with [`lane_sum`] exactly as the 16-lane kernel does.
pub(super) const SUB_STEPS: usize = 128;

/// What a grouped kernel needs for lanes 4g..4g+4 over one sub-chunk.
struct GroupArgs<'a, 'p> {
    proto: &'a mut Proto,
    sum: &'a mut [f64; LANES],
    g: usize,
    p: &'a Params<'p>,
    tr: &'a [f64],
    side: &'a mut [Xoshiro256pp; LANES],
    active: &'a Lanes,
    buf: &'a mut [[f64; LANES]],
    /// Shared slice counter and pattern position at the start of the sub-chunk.
    avail: u32,
    pat: usize,
}

/// The grouped covariance kernel, written once over a four-lane operation set `$o` (a module
/// with the functions of [`lanes4`]); `$a` is a [`GroupArgs`]. Booleans are lane masks (all
/// ones / all zeros). Returns the slice counter and pattern position at the end.
macro_rules! group_body {
    ($o:ident, $a:ident, $online:ident, $mu_draw:ident, $attack:ident, $proto_a:ident) => {{
        let lo = 4 * $a.g;
        let p = $a.p;
        let proto = &mut *$a.proto;
        let side = &mut $a.side[lo..lo + 4];
        let one = $o::splat(1);
        let lam_hi = $o::splat(p.lam_hi);
        let mu_hi = $o::splat(p.mu_hi);
        // Memory lengths minus one, so "zeros >= L" is the single compare "zeros > L - 1"
        // (z0 >= 1, and the plan keeps every length below 2^63).
        let z0 = $o::splat(p.z0);
        let lfix_m1 = $o::splat(p.l_fixed.saturating_sub(1));
        let mlen = $o::splat(p.mask_len);
        let mlen_m1 = $o::splat(p.mask_len.saturating_sub(1));
        let table = $o::table($a.tr, p.last);
        let act = $o::load(&$a.active[lo..lo + 4]);
        let mut rng = $o::Stream::load(proto, lo, $a.avail);
        let mut tau = $o::load(&proto.tau[lo..lo + 4]);
        let mut zeros = $o::load(&proto.zeros[lo..lo + 4]);
        let mut counter = $o::load(&proto.counter[lo..lo + 4]);
        let mut hi = $o::sub($o::splat(0), $o::load(&proto.hi[lo..lo + 4])); // 0/1 -> mask
        let mut sent = $o::load(&proto.sent[lo..lo + 4]);
        let mut blocked = $o::load(&proto.blocked[lo..lo + 4]);
        let mut sum = $o::fload(&$a.sum[lo..lo + 4]);
        let mut pat = $a.pat;
        for row in $a.buf.iter_mut() {
            let lucky = rng.draw(lam_hi, p.lam_lo, side);
            let high = if $online {
                hi
            } else {
                let g = p.pattern.get(pat).copied().unwrap_or(1);
                pat += 1;
                if pat >= p.pattern.len() {
                    pat = 0;
                }
                $o::splat(0u64.wrapping_sub(u64::from(g)))
            };
            let arrive = $o::or(high, lucky);
            // τ <= p.last always (see `Plan::bound`); the lookup clamps its index anyway.
            tau = $o::andnot(arrive, $o::add(tau, one));
            let x = $o::lookup(&table, tau);
            sum = $o::fadd(sum, x);
            $o::fstore(&mut row[lo..lo + 4], $o::fmask(x, act));
            if $online {
                let memory_m1 = if $mu_draw {
                    // z0 bits with probability μ, else z0 + 1 (`short` is 0 or -1).
                    let short = rng.draw(mu_hi, p.mu_lo, side);
                    $o::add(z0, short)
                } else {
                    lfix_m1
                };
                let flag;
                if $attack {
                    let z = $o::andnot(arrive, $o::add(zeros, one));
                    flag = $o::gt(z, memory_m1); // zeros >= memory
                    zeros = $o::andnot(flag, z);
                    let bm = $o::eq($o::mask_bit(p.mask, counter), one);
                    if $proto_a {
                        // Integrity attack on the per-step bit: only 1-bits are touched.
                        let bit = flag;
                        let flip = $o::and(bit, bm);
                        let c = $o::add(counter, one);
                        let wrap = $o::gt(c, mlen_m1);
                        let c = $o::sub(c, $o::and(wrap, mlen));
                        counter = $o::blend(bit, c, counter);
                        blocked = $o::sub(blocked, flip);
                        hi = $o::xor(bit, flip);
                    } else {
                        // DoS on the flag packet, which exists only when a flag is due.
                        let drop = $o::and(flag, bm);
                        let next = $o::add(counter, one);
                        let next = $o::andnot($o::eq(next, mlen), next);
                        counter = $o::blend(flag, next, counter);
                        blocked = $o::sub(blocked, drop);
                        hi = $o::andnot(drop, flag);
                    }
                } else {
                    flag = $o::gt(tau, memory_m1); // τ >= memory
                    hi = flag;
                }
                sent = $o::sub(sent, flag);
            }
        }
        let avail = rng.store(proto, lo);
        $o::store(&mut proto.tau[lo..lo + 4], tau);
        $o::store(&mut proto.zeros[lo..lo + 4], zeros);
        $o::store(&mut proto.counter[lo..lo + 4], counter);
        $o::store(&mut proto.hi[lo..lo + 4], $o::shr::<63>(hi));
        $o::store(&mut proto.sent[lo..lo + 4], sent);
        $o::store(&mut proto.blocked[lo..lo + 4], blocked);
        $o::fstore(&mut $a.sum[lo..lo + 4], sum);
        (avail, pat)
    }};
}

/// Resolves the 16-bit slice ties of four lanes (all ones where the extended draw hits): the
/// 48 lower bits of the exact threshold are compared with 48 bits of the lane's side stream.
#[cold]
#[inline(never)]
fn resolve_ties4(hit: &mut [u64; 4], tie: &[u64; 4], side: &mut [Xoshiro256pp], lo: u64) {
    for ((h, &t), s) in hit.iter_mut().zip(tie).zip(side.iter_mut()) {
        if t != 0 {
            *h = if (s.next_u64() >> SLICE_BITS) < lo {
                u64::MAX
            } else {
                0
            };
        }
    }
}

/// Four-lane operations on plain arrays.
mod lanes4;

/// The same operations on AVX2 registers.
///
/// # Safety
/// Every function requires AVX2; callers run only after `is_x86_feature_detected!("avx2")`.
#[cfg(target_arch = "x86_64")]
mod lanes4_avx2;

fn group_portable<const O: bool, const M: bool, const A: bool, const P: bool>(
    a: GroupArgs,
) -> (u32, usize) {
    group_body!(lanes4, a, O, M, A, P)
}

/// # Safety
/// The CPU must support AVX2; `a.p.last < a.tr.len()`; `a.p.mask` holds `a.p.mask_len` bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn group_avx2<const O: bool, const M: bool, const A: bool, const P: bool>(
    a: GroupArgs,
) -> (u32, usize) {
    use lanes4_avx2 as simd;
    group_body!(simd, a, O, M, A, P)
}

/// Advances the tile's 16 runs by `rows.len()` (at most [`SUB_STEPS`]) steps with the grouped
/// kernels: row s, lane l receives `tr[τ]` of lane l after that step (0 where `active` is 0),
/// and `sum` each lane's running total. State mode passes the marker table [1, 0, 0, ...] to read
/// the arrivals off the rows.
#[allow(clippy::too_many_arguments)]
pub(super) fn group_rows<const O: bool, const M: bool, const A: bool, const P: bool>(
    isa: Isa,
    p: &Params,
    tr: &[f64],
    proto: &mut Proto,
    sum: &mut [f64; LANES],
    side: &mut [Xoshiro256pp; LANES],
    active: &Lanes,
    rows: &mut [[f64; LANES]],
) {
    let (avail, pat) = (proto.avail, proto.pat);
    let mut end = (avail, pat);
    for g in 0..LANES / 4 {
        let args = GroupArgs {
            proto: &mut *proto,
            sum: &mut *sum,
            g,
            p,
            tr,
            side: &mut *side,
            active,
            buf: &mut *rows,
            avail,
            pat,
        };
        end = match isa {
            // SAFETY: `detect_isa` chose Avx2 after checking the CPU at run time; callers check
            // the table and mask requirements (`check_tables`).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { group_avx2::<O, M, A, P>(args) },
            _ => group_portable::<O, M, A, P>(args),
        };
    }
    proto.avail = end.0;
    proto.pat = end.1;
}

/// The kernels' requirements on their tables: a non-empty trace table holding index `p.last`,
/// and a mask of `p.mask_len` bits.
pub(super) fn check_tables(p: &Params, tr: &[f64]) -> Result<()> {
    let words = p.mask_len.div_ceil(64);
    if tr.is_empty() || p.last as usize >= tr.len() || (p.mask.len() as u64) < words {
        return Err(Error::invalid("sys", "inconsistent kernel tables"));
    }
    Ok(())
}

pub(super) fn cov_tile<const O: bool, const M: bool, const A: bool, const P: bool>(
    isa: Isa,
    p: &Params,
    tr: &[f64],
    tile: &mut Tile,
    cancel: &AtomicBool,
) -> Result<TileOut> {
    check_tables(p, tr)?;
    #[cfg(test)]
    if isa == Isa::Reference {
        return cov_tile_impl::<O, M, A, P>(p, tr, tile, cancel);
    }
    let mut proto = Proto::new(&tile.seeds);
    let mut sum = [0.0f64; LANES];
    let mut buf = [[0.0f64; LANES]; SUB_STEPS];
    for chunk in tile.acc.chunks_mut(CHUNK_STEPS) {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for sub in chunk.chunks_mut(SUB_STEPS) {
            let rows = &mut buf[..sub.len()];
            group_rows::<O, M, A, P>(
                isa,
                p,
                tr,
                &mut proto,
                &mut sum,
                &mut tile.side,
                &tile.active,
                rows,
            );
            for (acc, row) in sub.iter_mut().zip(rows.iter()) {
                *acc += lane_sum(row);
            }
        }
    }
    Ok(TileOut {
        sum,
        sent: proto.sent,
        blocked: proto.blocked,
        hi_last: proto.hi,
    })
}
