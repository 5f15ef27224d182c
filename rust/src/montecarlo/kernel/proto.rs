//! The protocol state of a tile's [`LANES`] runs, which the grouped and the reference kernels
//! advance.

use super::{Lanes, TileOut, LANES};

/// The protocol state of LANES runs, one array entry per lane (structure of arrays).
pub(in crate::montecarlo) struct Proto {
    /// Word 0 of each lane's xoshiro256++ protocol stream.
    pub(super) s0: Lanes,
    /// Word 1 of the protocol streams.
    pub(super) s1: Lanes,
    /// Word 2 of the protocol streams.
    pub(super) s2: Lanes,
    /// Word 3 of the protocol streams.
    pub(super) s3: Lanes,
    /// Each lane's current random word, consumed one 16-bit slice per draw.
    pub(super) slice_word: Lanes,
    /// Slices left in `slice_word` (the same in every lane: the lanes draw in lock-step).
    pub(super) slices_left: u32,
    /// The holding time τ since the last arrival.
    pub(super) tau: Lanes,
    /// The detector's count of zero ACKs since its last reset or arrival (kept under attack).
    pub(super) zeros: Lanes,
    /// The attacker's flag counter σ, modulo the mask length (mask blocking only).
    pub(super) counter: Lanes,
    /// 1 where a flag-ACK, genuine or forged, reached the sensor: it uses Δ at the next step
    /// (online).
    pub(super) high_next: Lanes,
    /// Flag-ACKs sent by the detector.
    pub(super) sent: Lanes,
    /// Flag-ACKs blocked or flipped by the attacker.
    pub(super) blocked: Lanes,
    /// Flag-ACKs forged by the attacker.
    pub(super) forged: Lanes,
    /// The next step's position in the offline pattern (the same in every lane).
    pub(super) pattern_pos: usize,
}

impl Proto {
    /// The state at k = 1: lane l's protocol stream starts at `seeds[l]`, the sensor uses Δ, the
    /// detector and the attacker start from zero.
    pub(in crate::montecarlo) fn new(seeds: &[[u64; 4]; LANES]) -> Self {
        let mut p = Proto {
            s0: [0; LANES],
            s1: [0; LANES],
            s2: [0; LANES],
            s3: [0; LANES],
            slice_word: [0; LANES],
            slices_left: 0,
            tau: [0; LANES],
            zeros: [0; LANES],
            counter: [0; LANES],
            high_next: [1; LANES], // k = 1 is a high-power step
            sent: [0; LANES],
            blocked: [0; LANES],
            forged: [0; LANES],
            pattern_pos: 0,
        };
        for (l, s) in seeds.iter().enumerate() {
            p.s0[l] = s[0];
            p.s1[l] = s[1];
            p.s2[l] = s[2];
            p.s3[l] = s[3];
        }
        p
    }

    /// The tile's report once its runs are over, with each lane's total `sum`.
    pub(in crate::montecarlo) fn finish(self, sum: [f64; LANES]) -> TileOut {
        TileOut {
            sum,
            sent: self.sent,
            blocked: self.blocked,
            forged: self.forged,
            hi_last: self.high_next,
        }
    }
}
