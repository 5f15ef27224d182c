//! The 16-lane reference kernel (tests only): the protocol written lane by lane, step by step,
//! against which the grouped kernels are checked bit for bit.

use std::sync::atomic::{AtomicBool, Ordering};

use super::{lane_sum, Lanes, Params, Proto, Tile, TileOut, LANES};
use crate::error::{Error, Result};
use crate::montecarlo::rng::Xoshiro256pp;
use crate::montecarlo::{CHUNK_STEPS, SLICES_PER_WORD, SLICE_BITS, SLICE_MASK};

/// Resolves ties of the 16-bit Bernoulli slices with 48 more bits from the side streams.
#[cold]
#[inline(never)]
fn resolve_ties(mut hit: Lanes, tie: Lanes, side: &mut [Xoshiro256pp; LANES], rest: u64) -> Lanes {
    for l in 0..LANES {
        if tie[l] != 0 {
            hit[l] = u64::from((side[l].next_u64() >> SLICE_BITS) < rest);
        }
    }
    hit
}

/// Bit `i` of the blocking mask (`i < mask_len`).
#[inline(always)]
fn mask_bit(mask: &[u64], i: u64) -> u64 {
    let w = ((i >> 6) as usize).min(mask.len().saturating_sub(1));
    mask.get(w).map_or(0, |word| (word >> (i & 63)) & 1)
}

/// What the attacker does to the genuine flag-ACK of each lane this step: block it where
/// `blocking` (per its mask, or its β draw).
struct Blocking<'a> {
    /// 1 where the attacker blocks this step's flag, if there is one.
    blocking: &'a Lanes,
    /// Whether blocking follows the mask over a counter (advanced on every genuine flag).
    counted: bool,
}

/// The lanes the attacker blocks, per its mask at each lane's counter (advancing nothing).
fn mask_blocking(counter: &Lanes, p: &Params) -> Lanes {
    std::array::from_fn(|l| mask_bit(p.mask, counter[l]))
}

/// Protocol B: a flag packet exists only when a flag is due; the attacker drops it where
/// `b.blocking`, and where no packet exists it forges one where `forge`. Returns 1 where the
/// sensor receives a flag.
#[inline(always)]
fn channel_b(
    flag: &Lanes,
    b: Blocking,
    forge: &Lanes,
    proto: &mut (Lanes, Lanes, Lanes),
    p: &Params,
) -> Lanes {
    let (counter, blocked, forged) = proto;
    let mut delivered = [0u64; LANES];
    for l in 0..LANES {
        let packet = flag[l] != 0;
        let drop = u64::from(packet) & b.blocking[l];
        if packet && b.counted {
            counter[l] = if counter[l] + 1 == p.mask_len {
                0
            } else {
                counter[l] + 1
            };
        }
        let fake = u64::from(!packet) & forge[l];
        blocked[l] += drop;
        forged[l] += fake;
        delivered[l] = (u64::from(packet) & (drop ^ 1)) | fake;
    }
    delivered
}

/// Protocol A: one bit every step (1 = flag); the attacker flips 1-bits to 0 where
/// `b.blocking` and 0-bits to 1 where `forge`. Returns the bit the sensor receives.
#[inline(always)]
fn channel_a(
    flag: &Lanes,
    b: Blocking,
    forge: &Lanes,
    proto: &mut (Lanes, Lanes, Lanes),
    p: &Params,
) -> Lanes {
    let (counter, blocked, forged) = proto;
    let mut received = [0u64; LANES];
    for l in 0..LANES {
        let bit = flag[l]; // the detector's 1-bit ACK of this step
        let flip = if bit == 1 {
            if b.counted {
                let c = counter[l] + 1;
                counter[l] = if c >= p.mask_len { c - p.mask_len } else { c };
            }
            blocked[l] += b.blocking[l];
            b.blocking[l]
        } else {
            forged[l] += forge[l];
            forge[l]
        };
        received[l] = bit ^ flip;
    }
    received
}

impl Proto {
    /// One xoshiro256++ step in every lane.
    #[inline(always)]
    fn refill(&mut self) {
        for l in 0..LANES {
            let (s0, s1, s2, s3) = (self.s0[l], self.s1[l], self.s2[l], self.s3[l]);
            self.slice_word[l] = s0.wrapping_add(s3).rotate_left(23).wrapping_add(s0);
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
        self.slices_left = SLICES_PER_WORD;
    }

    /// An exact Bernoulli(T / 2^64) draw per lane, T = top·2^48 + rest.
    #[inline(always)]
    fn bernoulli(&mut self, top: u64, rest: u64, side: &mut [Xoshiro256pp; LANES]) -> Lanes {
        if self.slices_left == 0 {
            self.refill();
        }
        self.slices_left -= 1;
        let mut hit = [0u64; LANES];
        let mut tie = [0u64; LANES];
        let mut any_tie = 0u64;
        for l in 0..LANES {
            let u = self.slice_word[l] & SLICE_MASK;
            self.slice_word[l] >>= SLICE_BITS;
            hit[l] = u64::from(u < top);
            tie[l] = u64::from(u == top);
            any_tie |= tie[l];
        }
        if any_tie != 0 {
            hit = resolve_ties(hit, tie, side, rest);
        }
        hit
    }

    /// The sensor's power this step: the flag-ACK decision online, else the offline pattern.
    #[inline(always)]
    fn high_now<const ONLINE: bool>(&mut self, p: &Params) -> Lanes {
        if ONLINE {
            return self.high_next;
        }
        let g = u64::from(p.pattern.get(self.pattern_pos).copied().unwrap_or(1));
        self.pattern_pos += 1;
        if self.pattern_pos >= p.pattern.len() {
            self.pattern_pos = 0;
        }
        [g; LANES]
    }

    /// Step k: returns 1 where the packet arrives, and updates τ, the detector, the channel and
    /// the attacker (the per-lane reference the grouped kernels are tested against). Draws, one
    /// slice in every lane each: λ, then μ (if drawn), β (independent blocking), γ (forging).
    #[inline(always)]
    pub(super) fn step<
        const ONLINE: bool,
        const MU_DRAW: bool,
        const ATTACK: bool,
        const PROTO_A: bool,
        const RANDOM_BLOCK: bool,
        const FORGE: bool,
    >(
        &mut self,
        p: &Params,
        side: &mut [Xoshiro256pp; LANES],
    ) -> Lanes {
        let lucky = self.bernoulli(p.lam.top, p.lam.rest, side);
        let high = self.high_now::<ONLINE>(p);
        let mut arrive = [0u64; LANES];
        for l in 0..LANES {
            arrive[l] = high[l] | lucky[l];
            // τ <= p.max_tau always holds (it is the largest reachable τ or >= horizon - 1);
            // lookups clamp their index anyway.
            self.tau[l] = if arrive[l] != 0 {
                0
            } else {
                (self.tau[l] + 1).min(p.max_tau)
            };
        }
        if ONLINE {
            let memory: Lanes = if MU_DRAW {
                let short = self.bernoulli(p.mu.top, p.mu.rest, side);
                std::array::from_fn(|l| if short[l] != 0 { p.z0 } else { p.long_memory })
            } else {
                [p.fixed_memory; LANES]
            };
            let random = if ATTACK && RANDOM_BLOCK {
                self.bernoulli(p.beta.top, p.beta.rest, side)
            } else {
                [0; LANES]
            };
            let forge = if FORGE {
                self.bernoulli(p.gamma.top, p.gamma.rest, side)
            } else {
                [0; LANES]
            };
            let flag = self.detect_and_attack::<ATTACK, PROTO_A, RANDOM_BLOCK, FORGE>(
                p, &arrive, &memory, &random, &forge,
            );
            for (s, f) in self.sent.iter_mut().zip(flag) {
                *s += f;
            }
        }
        arrive
    }

    /// The detector's flag-ACKs this step (1 = flag) given the arrivals and the memory lengths,
    /// and what reaches the sensor through the attacker (`high_next`): genuine flags not
    /// blocked (per the mask, or where `random`) and, where there is no genuine flag, forged
    /// ones (where `forge`).
    #[inline(always)]
    fn detect_and_attack<
        const ATTACK: bool,
        const PROTO_A: bool,
        const RANDOM_BLOCK: bool,
        const FORGE: bool,
    >(
        &mut self,
        p: &Params,
        arrive: &Lanes,
        memory: &Lanes,
        random: &Lanes,
        forge: &Lanes,
    ) -> Lanes {
        let mut flag = [0u64; LANES];
        if ATTACK || FORGE {
            if ATTACK {
                for l in 0..LANES {
                    let z = if arrive[l] != 0 { 0 } else { self.zeros[l] + 1 };
                    flag[l] = u64::from(z >= memory[l]);
                    self.zeros[l] = if flag[l] != 0 { 0 } else { z };
                }
            } else {
                // Every flag, genuine or forged, reaches the sensor and is followed by an
                // arrival, so the zero count equals τ whenever it matters.
                for l in 0..LANES {
                    flag[l] = u64::from(self.tau[l] >= memory[l]);
                }
            }
            let by_mask = if ATTACK && !RANDOM_BLOCK {
                mask_blocking(&self.counter, p)
            } else {
                [0; LANES]
            };
            let b = Blocking {
                blocking: if RANDOM_BLOCK { random } else { &by_mask },
                counted: ATTACK && !RANDOM_BLOCK,
            };
            let none = [0; LANES];
            let forge = if FORGE { forge } else { &none };
            let mut state = (self.counter, self.blocked, self.forged);
            self.high_next = if PROTO_A {
                channel_a(&flag, b, forge, &mut state, p)
            } else {
                channel_b(&flag, b, forge, &mut state, p)
            };
            (self.counter, self.blocked, self.forged) = state;
        } else {
            // Without an attacker every flag is delivered and followed by an arrival, so the
            // zero count equals τ whenever it matters.
            for l in 0..LANES {
                flag[l] = u64::from(self.tau[l] >= memory[l]);
            }
            self.high_next = flag;
        }
        flag
    }
}

/// The 16-lane covariance kernel on [`Proto::step`] (the reference for the grouped kernels).
pub(super) fn cov_tile_reference<
    const ONLINE: bool,
    const MU_DRAW: bool,
    const ATTACK: bool,
    const PROTO_A: bool,
    const RANDOM_BLOCK: bool,
    const FORGE: bool,
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
            proto.step::<ONLINE, MU_DRAW, ATTACK, PROTO_A, RANDOM_BLOCK, FORGE>(p, side);
            let mut v = [0.0f64; LANES];
            for l in 0..LANES {
                let x = tr[(proto.tau[l] as usize).min(last)];
                sum[l] += x;
                v[l] = f64::from_bits(x.to_bits() & tile.active[l]);
            }
            *acc += lane_sum(&v);
        }
    }
    Ok(proto.finish(sum))
}
