//! The game kernel's block state and step loop: what one block of [`RUNS`] runs holds as
//! bit-planes and how a step, a flush of the counters and a window's end advance it. Kept apart
//! from the plan form the kernel takes ([`Sliced`], in the parent module), which decides whether
//! a plan fits before any block runs.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};

use super::{Blocking, Sliced, SlicedOut};
use crate::error::{Error, Result};
use crate::montecarlo::bitslice::body::{lane_sums, step_up, BetaPool};
use crate::montecarlo::bitslice::deep::DeepRuns;
use crate::montecarlo::bitslice::words::{
    and, andnot, equals, increment, less_than, not, or, LaneCounter, Rng4, StreamStepper, BATCH,
    ONES, RUNS, W, ZERO,
};
use crate::montecarlo::game::plan::Plan;
use crate::montecarlo::game::{Detector, Policy, CHECK_STEPS};

/// The offline lanes whose stretch began at a step ≡ `start` modulo the pattern's period.
struct Class {
    start: usize,
    lanes: W,
}

/// Adds the first `n` words of `batch` to `counter` (the rest are cleared first).
#[inline(always)]
fn feed(counter: &mut LaneCounter, batch: &mut [W; BATCH], n: usize) {
    batch[n..].fill(ZERO);
    counter.add16(batch);
}

/// Lanes whose count (binary planes) is at most `c`.
#[inline(always)]
fn at_most(planes: &[W], c: i64) -> W {
    if c < 0 {
        ZERO
    } else {
        less_than(planes, c as u64 + 1)
    }
}

/// Adds one to the per-lane totals `out` of the lanes in `lanes`.
fn bump(out: &mut [u64; RUNS], lanes: W) {
    for (w, word) in lanes.iter().enumerate() {
        let mut bits = *word;
        while bits != 0 {
            out[64 * w + bits.trailing_zeros() as usize] += 1;
            bits &= bits - 1;
        }
    }
}

/// Adds `n` to the per-lane totals `out` of the lanes in `lanes`.
fn add(out: &mut [u64; RUNS], lanes: W, n: u64) {
    for (l, o) in out.iter_mut().enumerate() {
        *o += n * ((lanes[l / 64] >> (l % 64)) & 1);
    }
}

/// The gap thermometer's step (`levels[j]`: gap ≥ j + 1): the gap is one more than after the
/// last step, which cleared it where `reset` (a flag-ACK reached the sensor).
#[inline(always)]
fn gap_step(levels: &mut [W], reset: W) {
    for j in (1..levels.len()).rev() {
        levels[j] = andnot(levels[j - 1], reset);
    }
    if let Some(first) = levels.first_mut() {
        *first = ONES;
    }
}

/// A block's mutable state.
struct State<const D: usize> {
    rng: Rng4,
    therm: [W; D],
    zeros: [W; D],
    sigma: Vec<W>,
    beta: BetaPool,
    pending: W,
    gap: Vec<W>,
    /// Online since their last flag-ACK (the run's start counts as one): the lanes whose next
    /// gap the support check reads.
    armed: W,
    /// A gap shorter than `min_gap` in the current window.
    short: W,
    online: W,
    classes: Vec<Class>,
    /// The lanes offline, by the index of the window at whose end they return online, in
    /// increasing order.
    returning: VecDeque<(u64, W)>,
    phase: usize,
    deep: DeepRuns,
    levels: Box<[LaneCounter; D]>,
    high: LaneCounter,
    delivered: LaneCounter,
    count: LaneCounter,
    bins: Vec<LaneCounter>,
    level_batch: Box<[[W; BATCH]; D]>,
    high_batch: [W; BATCH],
    delivered_batch: [W; BATCH],
    count_batch: [W; BATCH],
    bin_batch: Vec<[W; BATCH]>,
    /// Steps in the current batch.
    fill: usize,
    out: SlicedOut,
}

/// The kernel's body: one block of [`RUNS`] runs on thermometers of D levels, its draws made
/// by `stepper`.
#[inline(always)]
pub(super) fn block_body<const D: usize, S: StreamStepper>(
    s: &Sliced,
    plan: &Plan<'_>,
    block: u64,
    cancel: &AtomicBool,
    stepper: S,
) -> Result<SlicedOut> {
    let cfg = plan.cfg;
    if s.depth != D || s.z0 + 1 > D {
        return Err(Error::invalid(
            "sys",
            "plan too large for the bit-sliced kernel",
        ));
    }
    let offline = matches!(cfg.policy, Policy::Offline);
    let sigma_bits = match &s.blocking {
        Blocking::Mask { bits, .. } => *bits,
        _ => 0,
    };
    let bins = s.edges.len();
    let mut st = State::<D> {
        rng: Rng4::for_block(cfg.seed, block),
        therm: [ZERO; D],
        zeros: [ZERO; D],
        sigma: vec![ZERO; sigma_bits],
        beta: BetaPool::EMPTY,
        // The paper's initial condition: high power at k = 1, as after a flag-ACK.
        pending: ONES,
        gap: vec![ZERO; s.gap_levels()],
        armed: if offline { ZERO } else { ONES },
        short: ZERO,
        online: if offline { ZERO } else { ONES },
        classes: if offline {
            vec![Class {
                start: 0,
                lanes: ONES,
            }]
        } else {
            Vec::new()
        },
        returning: VecDeque::new(),
        phase: 0,
        deep: DeepRuns::new(D),
        levels: Box::new([LaneCounter::NEW; D]),
        high: LaneCounter::NEW,
        delivered: LaneCounter::NEW,
        count: LaneCounter::NEW,
        bins: vec![LaneCounter::NEW; bins],
        level_batch: Box::new([[ZERO; BATCH]; D]),
        high_batch: [ZERO; BATCH],
        delivered_batch: [ZERO; BATCH],
        count_batch: [ZERO; BATCH],
        bin_batch: vec![[ZERO; BATCH]; bins],
        fill: 0,
        out: SlicedOut::EMPTY,
    };
    // Windows run from the first step; the measurement starts after the burn-in, which may
    // end inside a window.
    let total = cfg.burn_in + cfg.horizon;
    let (mut at, mut measuring) = (0u64, cfg.burn_in == 0);
    let mut window_index = 0u64;
    while at < total {
        let end = (at + cfg.window).min(total);
        let mut from = at;
        if !measuring && end > cfg.burn_in {
            st.steps(s, plan, cfg.burn_in - at, cancel, stepper)?;
            st.flush();
            st.start_measuring();
            measuring = true;
            from = cfg.burn_in;
        }
        st.steps(s, plan, end - from, cancel, stepper)?;
        st.flush();
        if measuring {
            add(&mut st.out.online_steps, st.online, end - from);
        }
        if end - at == cfg.window {
            st.end_window(plan, window_index, end, end > cfg.burn_in);
            window_index += 1;
        }
        at = end;
    }
    let sums = lane_sums(
        &st.levels[..],
        cfg.horizon as usize,
        &s.tr,
        Some(&*st.deep.sum),
    );
    st.out.cost = sums;
    st.out.high = st.high.counts();
    st.out.delivered = st.delivered.counts();
    Ok(st.out)
}

impl<const D: usize> State<D> {
    /// `n` steps, polling `cancel` every [`CHECK_STEPS`].
    #[inline(always)]
    fn steps<S: StreamStepper>(
        &mut self,
        s: &Sliced,
        plan: &Plan<'_>,
        n: u64,
        cancel: &AtomicBool,
        stepper: S,
    ) -> Result<()> {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for k in 0..n {
            if k % CHECK_STEPS == CHECK_STEPS - 1 && cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            self.step(s, plan, stepper);
        }
        Ok(())
    }

    /// One step of every lane.
    #[inline(always)]
    fn step<S: StreamStepper>(&mut self, s: &Sliced, plan: &Plan<'_>, stepper: S) {
        let pattern = &plan.cfg.offline[..];
        // A flag-ACK reached the sensor at the last step (the paper's k = 1 counts as one).
        let last_delivered = self.pending;
        let mut high = and(self.online, last_delivered);
        for c in &self.classes {
            let pos = if self.phase >= c.start {
                self.phase - c.start
            } else {
                self.phase + pattern.len() - c.start
            };
            if pattern[pos] == 1 {
                high = or(high, c.lanes);
            }
        }
        self.phase += 1;
        if self.phase == pattern.len() {
            self.phase = 0;
        }
        let rng = &mut self.rng;
        let arrive = or(high, s.lam.hits(rng, stepper, not(high)));
        // τ and the zero count: 0 on arrival, else one more.
        step_up(&mut self.therm, arrive);
        let f = self.fill;
        for j in 0..D {
            self.level_batch[j][f] = self.therm[j];
        }
        self.deep.step(self.therm[D - 1], ZERO, &plan.traces);
        step_up(&mut self.zeros, arrive);
        // z0 bits with probability μ (drawn only where the count is exactly z0), else z0 + 1.
        let long = self.zeros[s.z0];
        let at_z0 = andnot(self.zeros[s.z0 - 1], long);
        let flag = or(long, s.mu.hits(rng, stepper, at_z0));
        // A flag resets the detector's memory.
        for z in self.zeros.iter_mut() {
            *z = andnot(*z, flag);
        }
        let blocked = match &s.blocking {
            Blocking::None => ZERO,
            Blocking::Mask { runs, len, .. } => {
                let mut inside = ZERO;
                for run in runs {
                    let below_end = less_than(&self.sigma, run.end);
                    inside = or(inside, andnot(below_end, less_than(&self.sigma, run.start)));
                }
                increment(&mut self.sigma, flag);
                let wrap = equals(&self.sigma, *len);
                for plane in self.sigma.iter_mut() {
                    *plane = andnot(*plane, wrap);
                }
                and(inside, flag)
            }
            Blocking::Random(beta) if beta.always => flag,
            Blocking::Random(beta) => self.beta.take(flag, rng, stepper, beta.thr),
        };
        let forged = s.gamma.hits(rng, stepper, not(flag));
        let delivered = or(andnot(flag, blocked), forged);
        self.pending = delivered;
        self.high_batch[f] = high;
        self.delivered_batch[f] = delivered;
        let counted = and(delivered, self.online);
        self.count_batch[f] = counted;
        if !self.gap.is_empty() {
            // The gap since the last flag-ACK that reached the sensor, one more each step.
            // A gap of 1 at the first step either way: the gap starts at 0, as after a flag-ACK.
            gap_step(&mut self.gap, last_delivered);
            for (i, &e) in s.edges.iter().enumerate() {
                let above = s.edges.get(i + 1).map_or(ZERO, |&next| self.gap[next]);
                self.bin_batch[i][f] = and(counted, andnot(self.gap[e], above));
            }
            if s.min_gap > 1 {
                // Short: the gap has not reached `min_gap`. Offline lanes are disarmed, so
                // `counted` alone re-arms them.
                let checked = and(counted, self.armed);
                self.short = or(self.short, andnot(checked, self.gap[s.min_gap - 1]));
                self.armed = or(self.armed, counted);
            }
        }
        self.fill += 1;
        if self.fill == BATCH {
            self.flush();
        }
    }

    /// Adds the current batch to the counters.
    fn flush(&mut self) {
        let n = self.fill;
        if n == 0 {
            return;
        }
        for (c, b) in self.levels.iter_mut().zip(self.level_batch.iter_mut()) {
            feed(c, b, n);
        }
        feed(&mut self.high, &mut self.high_batch, n);
        feed(&mut self.delivered, &mut self.delivered_batch, n);
        feed(&mut self.count, &mut self.count_batch, n);
        for (c, b) in self.bins.iter_mut().zip(self.bin_batch.iter_mut()) {
            feed(c, b, n);
        }
        self.fill = 0;
    }

    /// Forgets what the burn-in accumulated (the current window's flags stay: its test reads
    /// the whole window).
    fn start_measuring(&mut self) {
        *self.levels = [LaneCounter::NEW; D];
        self.high = LaneCounter::NEW;
        self.delivered = LaneCounter::NEW;
        self.deep.sum.fill(0.0);
    }

    /// The end of window `index` (its last step is `end` - 1): the online lanes' tests and the
    /// mode switches; the test counts in the results when `counted`.
    fn end_window(&mut self, plan: &Plan<'_>, index: u64, end: u64, counted: bool) {
        if let Policy::Test {
            detector,
            harmful_at_most,
            fallback,
            ..
        } = &plan.cfg.policy
        {
            let tested = self.online;
            let n = self.count.planes();
            let alarm = match detector {
                Detector::Count { lo, hi } => or(at_most(&n, *lo), not(at_most(&n, hi - 1))),
                Detector::Likelihood { .. } => unreachable!("the lane kernel runs it (Sliced::of)"),
                Detector::Interval {
                    expected, critical, ..
                } => {
                    let mut x2 = [0.0f64; RUNS];
                    for (e, c) in expected.iter().zip(&self.bins) {
                        for (x, o) in x2.iter_mut().zip(c.counts()) {
                            let d = o as f64 - e;
                            *x += d * d / e;
                        }
                    }
                    let mut alarm = ZERO;
                    for (l, x) in x2.iter().enumerate() {
                        alarm[l / 64] |= u64::from(*x > *critical) << (l % 64);
                    }
                    alarm
                }
            };
            let alarm = and(or(alarm, self.short), tested);
            let trigger = match harmful_at_most {
                None => alarm,
                Some(b) => and(alarm, at_most(&n, *b)),
            };
            if counted {
                bump(&mut self.out.tested, tested);
                bump(&mut self.out.alarms, alarm);
                bump(&mut self.out.fallbacks, trigger);
            }
            if *fallback > 0 {
                let back = match self.returning.front() {
                    Some(&(at, lanes)) if at == index => {
                        self.returning.pop_front();
                        lanes
                    }
                    _ => ZERO,
                };
                if trigger != ZERO {
                    self.returning
                        .push_back((index.saturating_add(*fallback), trigger));
                }
                self.online = or(andnot(self.online, trigger), back);
                // The first gap back online is not checked.
                self.armed = andnot(self.armed, trigger);
                self.classes.retain_mut(|c| {
                    c.lanes = andnot(c.lanes, back);
                    c.lanes != ZERO
                });
                if trigger != ZERO {
                    let start = (end % plan.cfg.offline.len() as u64) as usize;
                    match self.classes.iter_mut().find(|c| c.start == start) {
                        Some(c) => c.lanes = or(c.lanes, trigger),
                        None => self.classes.push(Class {
                            start,
                            lanes: trigger,
                        }),
                    }
                }
            }
        }
        self.count = LaneCounter::NEW;
        self.short = ZERO;
        for b in &mut self.bins {
            *b = LaneCounter::NEW;
        }
    }
}
