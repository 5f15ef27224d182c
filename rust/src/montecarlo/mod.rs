//! Monte Carlo of the real protocol (not of the Markov chain of Sec. IV-B).
//!
//! Each run plays steps k = 1..=horizon of the sensor, the lossy channel, the remote estimator,
//! the event detector and the attacker:
//!
//! * the sensor uses high power Δ (the packet always arrives) or low power δ (it arrives with
//!   probability λ). Offline: `pattern[(k-1) % len]`. Online: Δ at step k iff a flag-ACK was
//!   delivered to the sensor at step k-1;
//! * the remote covariance is P̄ on arrival and h(P_{k-1}) otherwise, so Tr P_k = `tr[τ_k]` with τ_k
//!   the holding time since the last arrival;
//! * the event detector (online) counts the consecutive zero ACKs since the last reset or arrival.
//!   Each step it uses a z0-bit memory with probability μ, else z0+1 bits; when the last L bits are
//!   all zero it sends a flag-ACK and resets the memory to all ones;
//! * the attacker keeps a counter over flag-ACKs and blocks a flag iff `mask[counter]`, then
//!   advances the counter modulo the mask length; under independent blocking
//!   ([`Attack::Random`](crate::Attack::Random)) it keeps no counter and blocks each flag with
//!   probability β. A blocked flag still resets the detector's memory, but the sensor does not
//!   learn of it and stays on δ;
//! * an injecting attacker ([`Attack::Injection`](crate::Attack::Injection)) forges a flag-ACK
//!   with probability γ on each step on which the detector sends none (a step that carries a
//!   genuine flag, delivered or blocked, is never forged on), besides any blocking of the
//!   genuine flags. The sensor cannot tell it from a genuine one and uses Δ at the next step. A
//!   forged flag advances no counter and does not reset the detector's memory (the arrival it
//!   brings about does).
//!
//! Initial condition (the paper's): at k = 1 the sensor uses Δ (the packet arrives, τ = 0), the
//! memory is all ones and the attacker's counter is 0.
//!
//! Two channel protocols carry the flag-ACK, as two separate code paths with identical
//! statistics: in [`Protocol::B`] a flag packet exists only when a flag is due and the attacker
//! drops it (DoS) or, when none is due, sends a forged one; in [`Protocol::A`] the detector
//! sends one bit every step (1 = flag) and the attacker flips 1-bits to 0 (integrity attack) or
//! forges by flipping 0-bits to 1.
//!
//! Two fidelities: [`Mode::Covariance`] tracks τ and accumulates `tr[τ]`; [`Mode::State`] simulates
//! the estimation errors with Gaussian noise (see [`Mode::State`]).
//!
//! # Engineering
//!
//! Runs are split into fixed blocks of [`BLOCK_RUNS`]; block b draws all its randomness from
//! SplitMix64 sub-stream (seed, b) and blocks are combined in block order, so results depend only
//! on the seed, never on the number of threads or on the CPU's vector instructions. Blocks run in
//! parallel (rayon) in waves whose per-step sums are folded into the totals as each wave ends, so
//! memory does not grow with `runs` (except for the optional per-run record
//! [`McResult::delivered_per_run`], 8 bytes per run).
//!
//! Two kernel families simulate a block. In covariance mode, plans with a holding-time bound
//! ≤ 32, a memory ≤ 32 under attack and a mask with at most four runs of ones go to the
//! bit-sliced kernel (`bitslice`): the block's 256 runs are the bit lanes of four words, about
//! ten times faster. Under independent blocking or forging it also takes plans whose holding
//! time is unbounded (or deeper than 32): its thermometer then stops at a level few runs reach,
//! chosen from the stationary law of the attack chain, and the runs beyond it are tracked one
//! by one (`bitslice/deep.rs`). Every other plan, and state mode, uses the lane kernels below.
//! A two-state Markov channel ([`McConfig::channel`], high power always arriving) runs on the
//! bit-sliced kernel alone, its state one more bit-plane per block (a compile-time flag, so the
//! i.i.d. kernels are unchanged); its plans outside that kernel are refused
//! ([`simulate_if_supported`] says so without running), and so is state mode.
//! Each family
//! is deterministic in the seed and independent of threads and CPU features; the two consume
//! randomness differently, so one seed gives different, equally distributed samples on each
//! (tests check both against the exact values).
//!
//! In the lane kernels, tiles of [`LANES`] runs advance in lock-step (structure of arrays). In
//! covariance mode the tile is processed as four groups of four lanes, each running a sub-chunk
//! of steps with its whole state in registers: one kernel body (`group_body!`) instantiated on
//! plain arrays (any target) and on AVX2 registers (x86-64, picked at run time). Tables of up to
//! 8 traces are read with in-register permutes instead of gathers. Every kernel performs the same
//! integer logic and the same f64 additions in the same order, so all give bit-identical results
//! (the tests compare them with the plain 16-lane reference kernel, `Proto::step`). State mode
//! runs the protocol on the same grouped kernels, a sub-chunk ahead, and reads the arrivals off
//! their rows, so both modes see the same protocol randomness.
//!
//! Each step draws, in this order, the channel (λ), the memory (μ, when 0 < μ < 1), the
//! independent blocking (β) and the forging (γ), each only in the plans that have it: the lane
//! kernels draw in every lane, the bit-sliced kernel only in the lanes where the draw matters
//! (low power; a zero count of exactly z0; no genuine flag), and the β decisions ahead of the
//! flags they decide, many lanes at once.
//!
//! Bernoulli draws use 16-bit slices of 64-bit xoshiro256++ outputs (four draws per output),
//! compared with the top 16 bits of the exact threshold T = ⌊p 2^64⌋; a tie (probability 2^-16)
//! is resolved with 48 further bits from a per-run side stream, so every draw is exactly
//! Bernoulli(T / 2^64), within 2^-64 of p.
//!
//! The holding time never exceeds the plan's bound (the largest reachable τ, or the horizon):
//! τ resets at every arrival, a delivered or forged flag-ACK forces an arrival at the next step,
//! and at most (longest run of blocked flags) flags in a row are blocked; independent blocking
//! (β > 0) can block any number, and its bound is the horizon. Table lookups clamp their index to
//! the bound anyway, so the tables are never read out of range.
//!
//! The AVX2 kernels are compiled for AVX2 (`#[target_feature]`) and reached only through an
//! `Avx2` token (`cpu.rs`), which exists only where the CPU has been found to support AVX2.
//!
//! # Layout
//!
//! `config` holds the public types ([`McConfig`], [`McResult`] and their parts); `plan` the
//! validation and the precomputed `Plan`; `driver` the block driver behind [`simulate`]; `cpu`
//! the AVX2 token; `bitslice` the bit-sliced covariance kernel (its body in `bitslice/body.rs`,
//! its word operations in `bitslice/words.rs`); `kernel` the lane kernels' interface, with the
//! lanes' protocol state (`kernel/proto.rs`), the grouped kernel (`kernel/grouped.rs`, over the
//! four-lane operation sets `kernel/lanes4.rs` and `kernel/lanes4_avx2.rs`) and the test-only
//! reference kernel (`kernel/reference.rs`); `state` the state-mode model and kernel; `tests` the
//! unit tests (`tests/perf.rs`: the ignored throughput and memory checks).

/// Which protocol paths an experiment's kernel needs; each kernel is compiled once per
/// combination (const generics), and `by_flags!` picks the one matching these run-time values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct KernelFlags {
    /// The online schedule (a detector sends flag-ACKs); else the offline pattern.
    online: bool,
    /// A μ draw every step (0 < μ < 1); else the memory length is fixed.
    mu_draw: bool,
    /// An attacker that blocks genuine flag-ACKs (by its mask, or independently).
    attack: bool,
    /// Protocol A (a bit every step) rather than B (a packet when a flag is due).
    protocol_a: bool,
    /// The blocking is independent, probability β per flag, with no counter (needs `attack`);
    /// else it follows the mask over the attacker's counter.
    random_block: bool,
    /// The attacker forges a flag-ACK with probability γ on each step without a genuine one.
    forge: bool,
}

/// Calls `$go!(ONLINE, MU_DRAW, ATTACK, PROTO_A, RANDOM_BLOCK, FORGE)` with the const-generic
/// kernel flags matching the run-time [`KernelFlags`] `$flags` (an offline plan has no detector,
/// and an unattacked one without forging no channel, so those combinations share one kernel).
macro_rules! by_flags {
    ($flags:expr, $go:ident) => {{
        let $crate::montecarlo::KernelFlags {
            online,
            mu_draw,
            attack,
            protocol_a,
            random_block,
            forge,
        } = $flags;
        match (online, mu_draw, attack, protocol_a, random_block, forge) {
            (false, ..) => $go!(false, false, false, false, false, false),
            (true, false, false, _, _, false) => $go!(true, false, false, false, false, false),
            (true, true, false, _, _, false) => $go!(true, true, false, false, false, false),
            (true, false, true, false, false, false) => {
                $go!(true, false, true, false, false, false)
            }
            (true, false, true, true, false, false) => $go!(true, false, true, true, false, false),
            (true, true, true, false, false, false) => $go!(true, true, true, false, false, false),
            (true, true, true, true, false, false) => $go!(true, true, true, true, false, false),
            // Forging without blocking.
            (true, false, false, false, _, true) => $go!(true, false, false, false, false, true),
            (true, false, false, true, _, true) => $go!(true, false, false, true, false, true),
            (true, true, false, false, _, true) => $go!(true, true, false, false, false, true),
            (true, true, false, true, _, true) => $go!(true, true, false, true, false, true),
            // Mask blocking with forging.
            (true, false, true, false, false, true) => $go!(true, false, true, false, false, true),
            (true, false, true, true, false, true) => $go!(true, false, true, true, false, true),
            (true, true, true, false, false, true) => $go!(true, true, true, false, false, true),
            (true, true, true, true, false, true) => $go!(true, true, true, true, false, true),
            // Independent blocking, with or without forging.
            (true, false, true, false, true, false) => $go!(true, false, true, false, true, false),
            (true, false, true, true, true, false) => $go!(true, false, true, true, true, false),
            (true, true, true, false, true, false) => $go!(true, true, true, false, true, false),
            (true, true, true, true, true, false) => $go!(true, true, true, true, true, false),
            (true, false, true, false, true, true) => $go!(true, false, true, false, true, true),
            (true, false, true, true, true, true) => $go!(true, false, true, true, true, true),
            (true, true, true, false, true, true) => $go!(true, true, true, false, true, true),
            (true, true, true, true, true, true) => $go!(true, true, true, true, true, true),
        }
    }};
}

pub mod automaton;
mod bitslice;
mod config;
mod cpu;
mod driver;
pub mod game;
mod kernel;
mod plan;
pub mod rng;
mod state;
#[cfg(test)]
mod tests;

pub use config::{McConfig, McResult, McSchedule, Mode, Protocol, TwoStateChannel};
pub use driver::{simulate, simulate_if_supported};

/// Runs simulated in lock-step by one kernel call (the vector width of the kernels).
pub const LANES: usize = 16;
// `lane_sum` is a 16-lane tree and the grouped kernels take four lanes at a time.
const _: () = assert!(LANES == 16);
/// Runs per block; block b is seeded from (seed, b) alone.
pub const BLOCK_RUNS: u64 = 256;
// The bit-sliced kernel simulates exactly one block per call.
const _: () = assert!(BLOCK_RUNS as usize == bitslice::RUNS);
/// Largest horizon: one f64 per step and per in-flight block, at most 1 GiB per buffer.
pub const MAX_HORIZON: usize = 1 << 27;
/// Most runs whose delivered flag-ACKs can be recorded ([`McConfig::record_runs`]): 2 GiB.
const MAX_RECORDED_RUNS: u64 = 1 << 28;
/// Steps of one lock-step tile between two checks of the cancel flag (LANES × this many run-steps).
const CHUNK_STEPS: usize = 1 << 16;
/// Bits of a 64-bit random word used per Bernoulli draw.
const SLICE_BITS: u32 = 16;
/// Bernoulli draws per 64-bit random word.
const SLICES_PER_WORD: u32 = 64 / SLICE_BITS;
/// The low [`SLICE_BITS`] bits of a word.
const SLICE_MASK: u64 = (1 << SLICE_BITS) - 1;
