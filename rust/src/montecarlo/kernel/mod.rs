//! The lock-step lane kernels: tiles of [`LANES`] runs advance together, with each run's protocol
//! state in [`Proto`]. Covariance mode runs on the grouped four-lane kernels (`grouped`, over the
//! operation sets `lanes4` and `lanes4_avx2`); tests compare them with the plain 16-lane
//! reference kernel (`reference`).

use std::sync::atomic::{AtomicBool, Ordering};

use super::cpu::Avx2;
use super::{CHUNK_STEPS, LANES, SLICE_BITS};
use crate::error::{Error, Result};
use crate::montecarlo::rng::Xoshiro256pp;

mod grouped;
mod lanes4;
#[cfg(target_arch = "x86_64")]
mod lanes4_avx2;
mod proto;
#[cfg(test)]
mod reference;

pub(super) use grouped::{group_rows, KernelTables, SUB_STEPS};
pub(super) use proto::Proto;

/// One value per lane of a tile.
type Lanes = [u64; LANES];

/// A Bernoulli threshold T = ⌊p 2^64⌋ cut for the lane kernels' draws: a draw compares a 16-bit
/// slice of a random word with `top` and settles a tie with 48 more bits against `rest`.
#[derive(Debug, Clone, Copy)]
pub(super) struct SlicedThreshold {
    /// The top [`SLICE_BITS`] bits of T.
    pub(super) top: u64,
    /// The other 64 - [`SLICE_BITS`] bits of T.
    pub(super) rest: u64,
}

impl SlicedThreshold {
    /// Cuts the threshold `thr` (see [`crate::montecarlo::rng::bernoulli_threshold`]).
    pub(super) fn new(thr: u64) -> Self {
        let low = 64 - SLICE_BITS;
        SlicedThreshold {
            top: thr >> low,
            rest: thr & ((1u64 << low) - 1),
        }
    }
}

/// Resolves the 16-bit slice ties of four lanes (all ones where the extended draw hits): the
/// 48 lower bits of the exact threshold are compared with 48 bits of the lane's side stream.
/// It lives with [`SlicedThreshold`] so that both four-lane operation sets share it without
/// importing the grouped kernel that uses them.
#[cold]
#[inline(never)]
fn resolve_ties4(hit: &mut [u64; 4], tie: &[u64; 4], side: &mut [Xoshiro256pp], rest: u64) {
    for ((h, &t), s) in hit.iter_mut().zip(tie).zip(side.iter_mut()) {
        if t != 0 {
            *h = if (s.next_u64() >> SLICE_BITS) < rest {
                u64::MAX
            } else {
                0
            };
        }
    }
}

/// Per-kernel constants.
#[derive(Clone, Copy)]
pub(super) struct Params<'a> {
    /// The channel's arrival probability λ on low power.
    pub(super) lam: SlicedThreshold,
    /// The probability μ of using the z0-bit memory at a step.
    pub(super) mu: SlicedThreshold,
    /// The probability β of blocking a genuine flag-ACK (independent blocking).
    pub(super) beta: SlicedThreshold,
    /// The probability γ of forging a flag-ACK on a step without a genuine one.
    pub(super) gamma: SlicedThreshold,
    /// The short memory length z0 (with probability μ).
    pub(super) z0: u64,
    /// The long memory length z0 + 1 (with probability 1 - μ; the reference kernel's form).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) long_memory: u64,
    /// The memory length when there is no μ draw: z0 for μ = 1, z0 + 1 for μ = 0.
    pub(super) fixed_memory: u64,
    /// The blocking mask, flag-ACK i at bit i % 64 of word i / 64.
    pub(super) mask: &'a [u64],
    /// Flag-ACKs per period of the mask (the attacker's counter runs modulo this).
    pub(super) mask_len: u64,
    /// The offline pattern (1 = high power).
    pub(super) pattern: &'a [u8],
    /// Largest τ (the trace table's last index).
    pub(super) max_tau: u64,
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
    /// Σ_k of the lane's per-step value (Tr P_k or ||e_k||²).
    pub(super) sum: [f64; LANES],
    /// Flag-ACKs sent by the detector.
    pub(super) sent: Lanes,
    /// Flag-ACKs blocked or flipped by the attacker.
    pub(super) blocked: Lanes,
    /// Flag-ACKs forged by the attacker.
    pub(super) forged: Lanes,
    /// 1 where a flag-ACK (genuine or forged) reached the sensor at the last step (the Δ step
    /// it announces is beyond the horizon).
    pub(super) hi_last: Lanes,
}

/// Inputs of one tile.
pub(super) struct Tile<'a> {
    /// Each lane's protocol stream (xoshiro256++ state).
    pub(super) seeds: [[u64; 4]; LANES],
    /// Each lane's side stream, which settles the rare ties of the 16-bit Bernoulli slices.
    pub(super) side: [Xoshiro256pp; LANES],
    /// Each lane's Gaussian noise stream (state mode).
    pub(super) noise: [Xoshiro256pp; LANES],
    /// All ones for runs of this tile, 0 for padding lanes.
    pub(super) active: Lanes,
    /// Per-step sums over the active lanes are added here (length = horizon).
    pub(super) acc: &'a mut [f64],
}

/// Which lane kernel runs. All give bit-identical results (tests check it): the per-lane
/// protocol is the same integer logic and the f64 additions happen in the same order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Isa {
    /// Grouped kernel on plain arrays (any target; auto-vectorised where possible).
    Portable,
    /// Grouped kernel on AVX2 registers (x86-64, chosen at run time), with the token that
    /// proves the CPU supports AVX2.
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    /// The 16-lane [`Proto::step`] kernel: the reference in tests.
    #[cfg(test)]
    Reference,
}

impl Isa {
    /// The AVX2 token, if this is the AVX2 kernel (the bit-sliced kernel's choice follows it).
    pub(super) fn avx2(self) -> Option<Avx2> {
        #[cfg(target_arch = "x86_64")]
        if let Isa::Avx2(token) = self {
            return Some(token);
        }
        None
    }

    /// The kernel's name: `Portable`, `Avx2` or `Reference`.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) fn name(self) -> &'static str {
        match self {
            Isa::Portable => "Portable",
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(_) => "Avx2",
            #[cfg(test)]
            Isa::Reference => "Reference",
        }
    }
}

/// The fastest kernel this CPU runs.
pub(super) fn detect_isa() -> Isa {
    #[cfg(target_arch = "x86_64")]
    if let Some(token) = Avx2::detect() {
        return Isa::Avx2(token);
    }
    Isa::Portable
}

/// Runs one covariance-mode tile on the kernel `isa`: lane l's per-step Tr P_k is `tr[τ_k]`.
pub(super) fn cov_tile<
    const O: bool,
    const M: bool,
    const A: bool,
    const P: bool,
    const RB: bool,
    const FG: bool,
>(
    isa: Isa,
    p: &Params,
    tr: &[f64],
    tile: &mut Tile,
    cancel: &AtomicBool,
) -> Result<TileOut> {
    let tables = KernelTables::new(p, tr)?;
    #[cfg(test)]
    if isa == Isa::Reference {
        return reference::cov_tile_reference::<O, M, A, P, RB, FG>(p, tr, tile, cancel);
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
            group_rows::<O, M, A, P, RB, FG>(
                isa,
                &tables,
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
    Ok(proto.finish(sum))
}
