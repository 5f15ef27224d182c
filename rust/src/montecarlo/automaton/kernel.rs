//! The automaton kernel: [`WIDTH`] runs of a block at a time, each on its own random stream,
//! stepped through the protocol of the [module docs](super), in covariance mode (a step costs
//! Tr P_k = `tr[τ_k]`) or in state mode (it costs ||e_k||², the errors simulated by the lane
//! kernels' state-mode recursions, [`TileErrors`]).

use std::sync::atomic::{AtomicBool, Ordering};

use super::tables::Plan;
use super::{Moments, WIDTH};
use crate::error::{Error, Result};
use crate::montecarlo::cpu::Avx2;
use crate::montecarlo::rng::{xoshiro256pp_x4, SplitMix64, Xoshiro256pp};
use crate::montecarlo::state::TileErrors;
use crate::montecarlo::{BLOCK_RUNS, CHUNK_STEPS};

/// What one block of runs reports.
pub(super) struct BlockOut {
    /// Per-step sums of Tr P_k over the block's runs.
    pub(super) acc: Vec<f64>,
    /// The moments of the runs' time averages.
    pub(super) moments: Moments,
    /// Flag-ACKs sent.
    pub(super) sent: u128,
    /// Genuine flag-ACKs not delivered.
    pub(super) blocked: u128,
    /// Flag-ACKs delivered on quiet steps.
    pub(super) forged: u128,
    /// High-power steps.
    pub(super) high: u128,
    /// Runs in the block.
    pub(super) runs: u64,
    /// Delivered flag-ACKs of each run, in run order (empty unless recording).
    pub(super) delivered: Vec<u64>,
}

/// Bit position of the blocked count in a packed flag-ACK counter.
const BLOCKED_SHIFT: u32 = 21;
/// Bit position of the forged count.
const FORGED_SHIFT: u32 = 42;
/// One field of a packed counter.
const FIELD: u64 = (1 << BLOCKED_SHIFT) - 1;
// A chunk's counts fit in a field.
const _: () = assert!(CHUNK_STEPS as u64 <= FIELD);
/// The packed counter increment of a step, by `flag << 1 | deliver`: sent in bits 0..21,
/// blocked in 21..42, forged from 42.
const INCREMENT: [u64; 4] = [0, 1 << FORGED_SHIFT, 1 | (1 << BLOCKED_SHIFT), 1];

/// What a step costs a run.
trait Cost {
    /// Run l's value at a step whose holding time is `tau` (the packet arrived iff `arrive`).
    fn cost(&mut self, l: usize, arrive: bool, tau: usize) -> f64;
}

/// Covariance mode: Tr P_k = `tr[τ_k]`.
struct Traces<'a>(&'a [f64]);

impl Cost for Traces<'_> {
    #[inline(always)]
    fn cost(&mut self, _l: usize, _arrive: bool, tau: usize) -> f64 {
        self.0[tau]
    }
}

/// State mode: ||e_k||², each run's errors on its own Gaussian noise stream.
struct Errors<'m> {
    /// The sensor's and the remote errors of the runs.
    errors: TileErrors<'m>,
    /// The runs' noise streams.
    noise: [Xoshiro256pp; WIDTH],
}

impl Cost for Errors<'_> {
    #[inline(always)]
    fn cost(&mut self, l: usize, arrive: bool, _tau: usize) -> f64 {
        let x = self.errors.step(l, arrive, &mut self.noise[l]);
        // As in the lane kernels' state mode: only an overflowed error gives NaN (inf - inf);
        // report it as +inf.
        if x.is_nan() {
            f64::INFINITY
        } else {
            x
        }
    }
}

/// The state of [`WIDTH`] runs advancing together.
struct Runs {
    /// The runs' xoshiro256++ streams, transposed: `rng[w][l]` is word w of run l's state.
    rng: [[u64; WIDTH]; 4],
    /// The channel state of the current step.
    c: [usize; WIDTH],
    /// The holding time τ.
    tau: [usize; WIDTH],
    /// The detector's zero count.
    z: [u64; WIDTH],
    /// The attacker's state.
    a: [usize; WIDTH],
    /// 1 where a flag-ACK reached the sensor at the last step (high power next).
    hi: [u64; WIDTH],
    /// Σ_k of the step's cost.
    sum: [f64; WIDTH],
    /// Flag-ACKs sent.
    sent: [u64; WIDTH],
    /// Genuine flag-ACKs not delivered.
    blocked: [u64; WIDTH],
    /// Flag-ACKs delivered on quiet steps.
    forged: [u64; WIDTH],
    /// This chunk's counts, packed (see [`INCREMENT`]).
    packed: [u64; WIDTH],
}

impl Runs {
    /// The runs at k = 1, each from the next seed of the block's stream: c_1 from the
    /// stationary law (the run's first draw), high power, zero count 0, the attacker at start.
    /// Also returns each run's noise stream (state mode), seeded after its protocol stream from
    /// the same SplitMix64, so that both modes see the same protocol randomness.
    fn start(plan: &Plan, stream: &mut SplitMix64) -> (Self, [Xoshiro256pp; WIDTH]) {
        let mut noise = [Xoshiro256pp::seed_from_u64(0); WIDTH];
        let mut streams: [Xoshiro256pp; WIDTH] = std::array::from_fn(|l| {
            let mut run = SplitMix64::new(stream.next_u64());
            let protocol = Xoshiro256pp::from_splitmix(&mut run);
            noise[l] = Xoshiro256pp::from_splitmix(&mut run);
            protocol
        });
        let k = plan.k;
        let c = std::array::from_fn(|l| {
            if k == 1 {
                0
            } else {
                plan.channel.draw(k, streams[l].next_u64()) as usize
            }
        });
        let rng = std::array::from_fn(|w| std::array::from_fn(|l| streams[l].state()[w]));
        let runs = Runs {
            rng,
            c,
            tau: [0; WIDTH],
            z: [0; WIDTH],
            a: [plan.start as usize; WIDTH],
            hi: [1; WIDTH],
            sum: [0.0; WIDTH],
            sent: [0; WIDTH],
            blocked: [0; WIDTH],
            forged: [0; WIDTH],
            packed: [0; WIDTH],
        };
        (runs, noise)
    }

    /// Adds the chunk's packed counts to the totals.
    fn flush(&mut self) {
        for l in 0..WIDTH {
            let p = self.packed[l];
            self.sent[l] += p & FIELD;
            self.blocked[l] += (p >> BLOCKED_SHIFT) & FIELD;
            self.forged[l] += p >> FORGED_SHIFT;
            self.packed[l] = 0;
        }
    }

    /// Runs every step, adding the active runs' costs to `acc` (`mask`: all ones for an active
    /// run, 0 for padding) and checking `cancel` every `chunk_steps` steps.
    #[inline(always)]
    fn run<const ONLINE: bool, const MU_DRAW: bool, const MARKOV: bool, C: Cost>(
        &mut self,
        plan: &Plan,
        mask: &[u64; WIDTH],
        acc: &mut [f64],
        cost: &mut C,
        chunk_steps: usize,
        cancel: &AtomicBool,
    ) -> Result<()> {
        let last = plan.tr.len() - 1;
        let (z0, mu_thr, memory) = (plan.z0, plan.mu_thr, plan.fixed_memory);
        let pattern = &plan.pattern[..];
        let arrive_thr = &plan.arrive[..];
        // One channel state: its two thresholds stay in registers.
        let (low0, high0) = (arrive_thr[0], arrive_thr[1]);
        let attacker = &plan.attacker;
        let mut pos = 0usize;
        for chunk in acc.chunks_mut(chunk_steps) {
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            for slot in chunk.iter_mut() {
                let mut row = [0.0f64; WIDTH];
                let pattern_high = if ONLINE { 0 } else { pattern[pos] };
                // Every run draws the same words each step: the arrival, the memory (μ), the
                // attacker, the channel, each only where the plan has it.
                let u_arrive = xoshiro256pp_x4(&mut self.rng);
                let u_mu = if ONLINE && MU_DRAW {
                    xoshiro256pp_x4(&mut self.rng)
                } else {
                    [0; WIDTH]
                };
                let u_attack = if ONLINE {
                    xoshiro256pp_x4(&mut self.rng)
                } else {
                    [0; WIDTH]
                };
                let u_channel = if MARKOV {
                    xoshiro256pp_x4(&mut self.rng)
                } else {
                    [0; WIDTH]
                };
                for l in 0..WIDTH {
                    let high = if ONLINE { self.hi[l] } else { pattern_high };
                    let c = self.c[l];
                    let thr = if MARKOV {
                        arrive_thr[2 * c + high as usize]
                    } else if high != 0 {
                        high0
                    } else {
                        low0
                    };
                    let arrive = (u_arrive[l] >> 1) < thr;
                    let tau = if arrive {
                        0
                    } else {
                        (self.tau[l] + 1).min(last)
                    };
                    self.tau[l] = tau;
                    let x = cost.cost(l, arrive, tau);
                    self.sum[l] += x;
                    row[l] = f64::from_bits(x.to_bits() & mask[l]);
                    if ONLINE {
                        let z = if arrive { 0 } else { self.z[l] + 1 };
                        let flag = if MU_DRAW {
                            let v = u_mu[l] >> 1;
                            u64::from(z > z0) | (u64::from(z == z0) & u64::from(v < mu_thr))
                        } else {
                            u64::from(z >= memory)
                        };
                        self.z[l] = if flag != 0 { 0 } else { z };
                        let dist = 2 * self.a[l] + flag as usize;
                        let o = attacker.draw(dist, u_attack[l]);
                        let deliver = o & 1;
                        self.a[l] = (o >> 1) as usize;
                        self.packed[l] += INCREMENT[((flag << 1) | deliver) as usize];
                        self.hi[l] = deliver;
                    }
                    if MARKOV {
                        self.c[l] = plan.channel.draw(c, u_channel[l]) as usize;
                    }
                }
                *slot += lane_sum(&row);
                if !ONLINE {
                    pos += 1;
                    if pos == pattern.len() {
                        pos = 0;
                    }
                }
            }
            self.flush();
        }
        Ok(())
    }
}

/// [`Runs::run`] compiled for AVX2, where the streams' xoshiro256++ steps vectorise. The
/// integer logic and the f64 arithmetic are those of the plain build, so both give the same
/// results bit for bit.
///
/// # Safety
/// The CPU must support AVX2 (callers hold an [`Avx2`] token).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2<const ONLINE: bool, const MU_DRAW: bool, const MARKOV: bool, C: Cost>(
    runs: &mut Runs,
    plan: &Plan,
    mask: &[u64; WIDTH],
    acc: &mut [f64],
    cost: &mut C,
    chunk_steps: usize,
    cancel: &AtomicBool,
) -> Result<()> {
    runs.run::<ONLINE, MU_DRAW, MARKOV, C>(plan, mask, acc, cost, chunk_steps, cancel)
}

/// The arguments of one group's run.
struct Group<'a, C> {
    /// The runs.
    runs: &'a mut Runs,
    /// All ones for an active run, 0 for padding.
    mask: &'a [u64; WIDTH],
    /// The block's per-step sums.
    acc: &'a mut [f64],
    /// What a step costs.
    cost: &'a mut C,
    /// Steps between checks of the cancel flag.
    chunk_steps: usize,
}

/// Runs the group's steps on the AVX2 build where `avx2` holds the token, else the plain one.
fn run_on<const ONLINE: bool, const MU_DRAW: bool, const MARKOV: bool, C: Cost>(
    avx2: Option<Avx2>,
    plan: &Plan,
    g: Group<'_, C>,
    cancel: &AtomicBool,
) -> Result<()> {
    let Group {
        runs,
        mask,
        acc,
        cost,
        chunk_steps,
    } = g;
    #[cfg(target_arch = "x86_64")]
    if let Some(_token) = avx2 {
        // SAFETY: an Avx2 token exists only where `Avx2::detect` found AVX2 on this CPU.
        return unsafe {
            run_avx2::<ONLINE, MU_DRAW, MARKOV, C>(runs, plan, mask, acc, cost, chunk_steps, cancel)
        };
    }
    let _ = avx2;
    runs.run::<ONLINE, MU_DRAW, MARKOV, C>(plan, mask, acc, cost, chunk_steps, cancel)
}

/// Runs the group on the instantiation that fits the plan.
fn run_group<C: Cost>(
    avx2: Option<Avx2>,
    plan: &Plan,
    g: Group<'_, C>,
    cancel: &AtomicBool,
) -> Result<()> {
    match (plan.online, plan.mu_draw, plan.k > 1) {
        (false, _, false) => run_on::<false, false, false, C>(avx2, plan, g, cancel),
        (false, _, true) => run_on::<false, false, true, C>(avx2, plan, g, cancel),
        (true, false, false) => run_on::<true, false, false, C>(avx2, plan, g, cancel),
        (true, false, true) => run_on::<true, false, true, C>(avx2, plan, g, cancel),
        (true, true, false) => run_on::<true, true, false, C>(avx2, plan, g, cancel),
        (true, true, true) => run_on::<true, true, true, C>(avx2, plan, g, cancel),
    }
}

/// Fixed-order sum of the runs' values (four runs a group: the streams' xoshiro256++ steps are
/// [`xoshiro256pp_x4`]'s, which vectorise on AVX2).
#[inline(always)]
fn lane_sum(v: &[f64; WIDTH]) -> f64 {
    (v[0] + v[1]) + (v[2] + v[3])
}
const _: () = assert!(WIDTH == 4);

/// Runs block `block` of the plan.
pub(super) fn run_block(
    plan: &Plan,
    avx2: Option<Avx2>,
    block: u64,
    cancel: &AtomicBool,
) -> Result<BlockOut> {
    let first = block * BLOCK_RUNS;
    let runs = BLOCK_RUNS.min(plan.runs - first);
    let mut stream = SplitMix64::stream(plan.seed, block);
    let mut out = BlockOut {
        acc: vec![0.0; plan.horizon],
        moments: Moments::default(),
        sent: 0,
        blocked: 0,
        forged: 0,
        high: 0,
        runs,
        delivered: Vec::new(),
    };
    let horizon = plan.horizon as f64;
    for g in 0..runs.div_ceil(WIDTH as u64) {
        let active = (runs - g * WIDTH as u64).min(WIDTH as u64) as usize;
        let mask: [u64; WIDTH] = std::array::from_fn(|l| if l < active { u64::MAX } else { 0 });
        let (mut r, mut noise) = Runs::start(plan, &mut stream);
        let acc = &mut out.acc;
        match &plan.state {
            None => {
                let cost = &mut Traces(&plan.tr);
                let group = Group {
                    runs: &mut r,
                    mask: &mask,
                    acc,
                    cost,
                    chunk_steps: CHUNK_STEPS,
                };
                run_group(avx2, plan, group, cancel)?;
            }
            Some(model) => {
                let mut errors = TileErrors::start(model, &mut noise);
                // τ_0 = 0: the remote estimate starts at the sensor's.
                errors.remote_from_sensor();
                let cost = &mut Errors { errors, noise };
                // A step costs about n² multiply-adds per run: check the cancel flag as often.
                let n = model.states();
                let group = Group {
                    runs: &mut r,
                    mask: &mask,
                    acc,
                    cost,
                    chunk_steps: (CHUNK_STEPS / (n * n).max(1)).max(1),
                };
                run_group(avx2, plan, group, cancel)?;
            }
        }
        for l in 0..active {
            out.moments.push(r.sum[l] / horizon);
            out.sent += u128::from(r.sent[l]);
            out.blocked += u128::from(r.blocked[l]);
            out.forged += u128::from(r.forged[l]);
            let delivered = r.sent[l] - r.blocked[l] + r.forged[l];
            out.high += if plan.online {
                // High power at k = 1 and after every flag-ACK received, except one received
                // at the last step.
                u128::from(1 + delivered - r.hi[l])
            } else {
                u128::from(plan.offline_high)
            };
            if plan.record_runs {
                out.delivered.push(delivered);
            }
        }
    }
    Ok(out)
}
