//! The grouped covariance kernel: a tile's 16 lanes as four groups of four, each running a
//! sub-chunk of steps with its whole state in registers. One body, `group_body!`, is
//! instantiated on plain arrays (`lanes4`, any target) and on AVX2 registers (`lanes4_avx2`).

use super::{lanes4, Isa, Lanes, Params, Proto, LANES};
use crate::error::{Error, Result};
use crate::montecarlo::rng::Xoshiro256pp;

/// Steps per sub-chunk of the grouped kernels: each group of 4 lanes runs this many steps with
/// its state in registers and writes its masked per-step values to a buffer (16 KiB), which is
/// then reduced per step with [`lane_sum`](super::lane_sum) exactly as the 16-lane kernel does.
pub(in crate::montecarlo) const SUB_STEPS: usize = 128;

/// A kernel's parameters with its value table (the traces, or state mode's arrival marker),
/// checked once for what the grouped kernels need: the table holds index `params.max_tau`, and
/// the mask has `mask_len >= 1` bits. [`group_rows`] takes only checked tables.
#[derive(Clone, Copy)]
pub(in crate::montecarlo) struct KernelTables<'a> {
    /// The kernel's constants.
    params: Params<'a>,
    /// The per-τ values written to the rows.
    table: &'a [f64],
}

impl<'a> KernelTables<'a> {
    /// Checks `params` and `table` (an error names `sys`: the tables come from the system).
    pub(in crate::montecarlo) fn new(params: &Params<'a>, table: &'a [f64]) -> Result<Self> {
        let words = params.mask_len.div_ceil(64);
        if table.is_empty()
            || params.max_tau as usize >= table.len()
            || params.mask_len == 0
            || (params.mask.len() as u64) < words
        {
            return Err(Error::invalid("sys", "inconsistent kernel tables"));
        }
        Ok(KernelTables {
            params: *params,
            table,
        })
    }
}

/// The slice counter and the offline pattern position, which every lane of a tile shares.
#[derive(Clone, Copy)]
struct SharedCursor {
    /// Slices left in the lanes' random words.
    slices_left: u32,
    /// The next step's position in the offline pattern.
    pattern_pos: usize,
}

/// Loop constants of a group's four lanes, as lane vectors `U` of the operation set.
struct GroupConsts<'a, U> {
    /// 1 in every lane.
    one: U,
    /// The mask length (the attacker's counter wraps to 0 there).
    mask_len: U,
    /// The mask length minus one.
    mask_len_m1: U,
    /// The blocking mask, as in [`Params::mask`].
    mask: &'a [u64],
}

/// What a grouped kernel needs for lanes 4g..4g+4 over one sub-chunk.
struct GroupArgs<'a, 'p> {
    /// The tile's protocol state.
    proto: &'a mut Proto,
    /// Each lane's running total.
    sum: &'a mut [f64; LANES],
    /// The group g (lanes 4g..4g+4).
    group: usize,
    /// The kernel's constants.
    p: &'a Params<'p>,
    /// The per-τ values written to the rows (checked by [`KernelTables::new`]).
    table: &'a [f64],
    /// The lanes' side streams (ties of the Bernoulli slices).
    side: &'a mut [Xoshiro256pp; LANES],
    /// All ones for runs, 0 for padding lanes.
    active: &'a Lanes,
    /// One row per step: each lane's value after the step.
    rows: &'a mut [[f64; LANES]],
    /// Where the tile's shared cursor stood at the start of the sub-chunk.
    start: SharedCursor,
}

/// The detector under attack and the attacker's channel, for one step of a group: updates the
/// zero counts `$zeros`, the attacker's counters `$counter` (mask blocking) and blocked counts
/// `$blocked`, and `$high_next` (what reaches the sensor), and evaluates to the detector's
/// flags. `$k` holds the loop's constants; `$random_draw` is this step's β draw, evaluated (one
/// slice in every lane) only under independent blocking (`$random`), which keeps no counter.
/// Booleans are lane masks (all ones / all zeros).
macro_rules! attacked_flag {
    ($o:ident, $k:ident, $proto_a:ident, $random:ident, $random_draw:expr, $arrive:ident,
     $memory_m1:ident, $zeros:ident, $counter:ident, $blocked:ident, $high_next:ident) => {{
        let z = $o::andnot($arrive, $o::add($zeros, $k.one));
        let flag = $o::gt(z, $memory_m1); // zeros >= memory
        $zeros = $o::andnot(flag, z);
        let blocking = if $random {
            $random_draw
        } else {
            $o::eq($o::mask_bit($k.mask, $counter), $k.one)
        };
        if $proto_a {
            // Integrity attack on the per-step bit: only 1-bits are touched.
            let bit = flag;
            let flip = $o::and(bit, blocking);
            if !$random {
                let c = $o::add($counter, $k.one);
                let wrap = $o::gt(c, $k.mask_len_m1);
                let c = $o::sub(c, $o::and(wrap, $k.mask_len));
                $counter = $o::blend(bit, c, $counter);
            }
            $blocked = $o::sub($blocked, flip);
            $high_next = $o::xor(bit, flip);
        } else {
            // DoS on the flag packet, which exists only when a flag is due.
            let drop = $o::and(flag, blocking);
            if !$random {
                let next = $o::add($counter, $k.one);
                let next = $o::andnot($o::eq(next, $k.mask_len), next);
                $counter = $o::blend(flag, next, $counter);
            }
            $blocked = $o::sub($blocked, drop);
            $high_next = $o::andnot(drop, flag);
        }
        flag
    }};
}

/// The attacker's forgeries for one step of a group, after the genuine flags `$flag` and what
/// the channel let through of them (`$high_next`): where no genuine flag was sent, `$forge`
/// (this step's γ draw) adds a flag-ACK that reaches the sensor, counted in `$forged`.
macro_rules! forged_flag {
    ($o:ident, $proto_a:ident, $flag:ident, $forge:expr, $high_next:ident, $forged:ident) => {{
        let forged = $o::andnot($flag, $forge);
        if $proto_a {
            // The detector's 0-bit of this step flipped to 1.
            $high_next = $o::xor($high_next, forged);
        } else {
            // A flag packet where the detector sent none.
            $high_next = $o::or($high_next, forged);
        }
        $forged = $o::sub($forged, forged);
    }};
}

/// The grouped covariance kernel, written once over a four-lane operation set `$o` (a module
/// with the functions of [`lanes4`]); `$a` is a [`GroupArgs`]. Booleans are lane masks (all
/// ones / all zeros). Evaluates to the [`SharedCursor`] at the end.
macro_rules! group_body {
    ($o:ident, $a:ident, $online:ident, $mu_draw:ident, $attack:ident, $proto_a:ident,
     $random:ident, $forge:ident) => {{
        let lo = 4 * $a.group;
        let p = $a.p;
        let proto = &mut *$a.proto;
        let side = &mut $a.side[lo..lo + 4];
        let k = GroupConsts {
            one: $o::splat(1),
            mask_len: $o::splat(p.mask_len),
            mask_len_m1: $o::splat(p.mask_len.saturating_sub(1)),
            mask: p.mask,
        };
        let lam_top = $o::splat(p.lam.top);
        let mu_top = $o::splat(p.mu.top);
        let beta_top = $o::splat(p.beta.top);
        let gamma_top = $o::splat(p.gamma.top);
        // Memory lengths minus one, so "zeros >= L" is the single compare "zeros > L - 1"
        // (z0 >= 1, and the plan keeps every length below 2^63).
        let z0 = $o::splat(p.z0);
        let fixed_memory_m1 = $o::splat(p.fixed_memory.saturating_sub(1));
        let table = $o::table($a.table, p.max_tau);
        let active = $o::load(&$a.active[lo..lo + 4]);
        let mut rng = $o::Stream::load(proto, lo, $a.start.slices_left);
        let mut tau = $o::load(&proto.tau[lo..lo + 4]);
        let mut zeros = $o::load(&proto.zeros[lo..lo + 4]);
        let mut counter = $o::load(&proto.counter[lo..lo + 4]);
        let mut high_next = $o::sub($o::splat(0), $o::load(&proto.high_next[lo..lo + 4])); // 0/1 -> mask
        let mut sent = $o::load(&proto.sent[lo..lo + 4]);
        let mut blocked = $o::load(&proto.blocked[lo..lo + 4]);
        let mut forged = $o::load(&proto.forged[lo..lo + 4]);
        let mut sum = $o::fload(&$a.sum[lo..lo + 4]);
        let mut pattern_pos = $a.start.pattern_pos;
        for row in $a.rows.iter_mut() {
            let lucky = rng.draw(lam_top, p.lam.rest, side);
            let high = if $online {
                high_next
            } else {
                let g = p.pattern.get(pattern_pos).copied().unwrap_or(1);
                pattern_pos += 1;
                if pattern_pos >= p.pattern.len() {
                    pattern_pos = 0;
                }
                $o::splat(0u64.wrapping_sub(u64::from(g)))
            };
            let arrive = $o::or(high, lucky);
            // τ <= p.max_tau always (see `Plan::bound`); the lookup clamps its index anyway.
            tau = $o::andnot(arrive, $o::add(tau, k.one));
            let x = $o::lookup(&table, tau);
            sum = $o::fadd(sum, x);
            $o::fstore(&mut row[lo..lo + 4], $o::fmask(x, active));
            if $online {
                let memory_m1 = if $mu_draw {
                    // z0 bits with probability μ, else z0 + 1 (`short` is 0 or -1).
                    let short = rng.draw(mu_top, p.mu.rest, side);
                    $o::add(z0, short)
                } else {
                    fixed_memory_m1
                };
                let flag;
                if $attack {
                    flag = attacked_flag!(
                        $o,
                        k,
                        $proto_a,
                        $random,
                        rng.draw(beta_top, p.beta.rest, side),
                        arrive,
                        memory_m1,
                        zeros,
                        counter,
                        blocked,
                        high_next
                    );
                } else {
                    // Every genuine flag and every forged one is followed by an arrival, so
                    // the zero count equals τ whenever it matters.
                    flag = $o::gt(tau, memory_m1); // τ >= memory
                    high_next = flag;
                }
                if $forge {
                    forged_flag!(
                        $o,
                        $proto_a,
                        flag,
                        rng.draw(gamma_top, p.gamma.rest, side),
                        high_next,
                        forged
                    );
                }
                sent = $o::sub(sent, flag);
            }
        }
        let slices_left = rng.store(proto, lo);
        $o::store(&mut proto.tau[lo..lo + 4], tau);
        $o::store(&mut proto.zeros[lo..lo + 4], zeros);
        $o::store(&mut proto.counter[lo..lo + 4], counter);
        $o::store(&mut proto.high_next[lo..lo + 4], $o::shr::<63>(high_next));
        $o::store(&mut proto.sent[lo..lo + 4], sent);
        $o::store(&mut proto.blocked[lo..lo + 4], blocked);
        if $forge {
            $o::store(&mut proto.forged[lo..lo + 4], forged);
        }
        $o::fstore(&mut $a.sum[lo..lo + 4], sum);
        SharedCursor {
            slices_left,
            pattern_pos,
        }
    }};
}

/// The grouped kernel on plain arrays.
fn group_portable<
    const O: bool,
    const M: bool,
    const A: bool,
    const P: bool,
    const RB: bool,
    const FG: bool,
>(
    a: GroupArgs,
) -> SharedCursor {
    group_body!(lanes4, a, O, M, A, P, RB, FG)
}

/// The grouped kernel on AVX2 registers. Compiled for AVX2, so calling it is `unsafe` except
/// from AVX2 code; [`group_rows`] calls it with an [`Isa::Avx2`], whose token proves the CPU's
/// support. It reads the tables only at clamped indices, so no argument makes it read out of
/// bounds.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn group_avx2<
    const O: bool,
    const M: bool,
    const A: bool,
    const P: bool,
    const RB: bool,
    const FG: bool,
>(
    a: GroupArgs,
) -> SharedCursor {
    use super::lanes4_avx2 as simd;
    group_body!(simd, a, O, M, A, P, RB, FG)
}

/// Advances the tile's 16 runs by `rows.len()` (at most [`SUB_STEPS`]) steps with the grouped
/// kernels: row s, lane l receives `table[τ]` of lane l after that step (0 where `active` is 0),
/// and `sum` each lane's running total. State mode passes the marker table [1, 0, 0, ...] to read
/// the arrivals off the rows.
pub(in crate::montecarlo) fn group_rows<
    const O: bool,
    const M: bool,
    const A: bool,
    const P: bool,
    const RB: bool,
    const FG: bool,
>(
    isa: Isa,
    tables: &KernelTables,
    proto: &mut Proto,
    sum: &mut [f64; LANES],
    side: &mut [Xoshiro256pp; LANES],
    active: &Lanes,
    rows: &mut [[f64; LANES]],
) {
    let start = SharedCursor {
        slices_left: proto.slices_left,
        pattern_pos: proto.pattern_pos,
    };
    let mut end = start;
    for group in 0..LANES / 4 {
        let args = GroupArgs {
            proto: &mut *proto,
            sum: &mut *sum,
            group,
            p: &tables.params,
            table: tables.table,
            side: &mut *side,
            active,
            rows: &mut *rows,
            start,
        };
        end = match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(_token) => {
                // SAFETY: the Avx2 token exists only where `Avx2::detect` found AVX2 on this
                // CPU, the one feature `group_avx2` is compiled for.
                unsafe { group_avx2::<O, M, A, P, RB, FG>(args) }
            }
            _ => group_portable::<O, M, A, P, RB, FG>(args),
        };
    }
    proto.slices_left = end.slices_left;
    proto.pattern_pos = end.pattern_pos;
}
