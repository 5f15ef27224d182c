//! Runs whose holding time reaches the thermometer's top level, tracked one by one.
//!
//! Under independent blocking τ has no bound, so the thermometer cannot hold it; the plan picks
//! a top level L (`BsPlan::deep_level`) that few runs reach. Level L - 1 of the thermometer then
//! holds "τ ≥ L" and stays set while τ grows beyond L (a thermometer's levels are exact at
//! every depth: level j is set iff the last j + 1 steps had no arrival). Each lane at or above L
//! keeps its exact τ here: L on the step it gets there (τ grows by one per step), one more on
//! each later step, until an arrival clears it from the level. Its value `tr[τ]` comes from the
//! plan's full trace table.

use super::words::{any, RUNS, W, WORDS};

/// The exact holding times of the lanes at or above the top level, and their sums.
pub(in crate::montecarlo) struct DeepRuns {
    /// The top level L.
    level: u64,
    /// Lanes at or above L after the previous step.
    prev: W,
    /// Each lane's τ while at or above L.
    tau: Box<[u64; RUNS]>,
    /// Each lane's Σ `tr[τ]` over its steps at or above L.
    pub(in crate::montecarlo) sum: Box<[f64; RUNS]>,
}

impl DeepRuns {
    /// No lane at or above `level` yet (`level` >= 1).
    pub(in crate::montecarlo) fn new(level: usize) -> Self {
        DeepRuns {
            level: level as u64,
            prev: [0; WORDS],
            tau: Box::new([0; RUNS]),
            sum: Box::new([0.0; RUNS]),
        }
    }

    /// The step's lanes at or above the level are `now`: advances their τ and sums, and returns
    /// the Σ of `tr[τ]` over those in `active`, in lane order (`None` if there are none).
    /// `tr` must not be empty.
    #[inline(always)]
    pub(in crate::montecarlo) fn step(&mut self, now: W, active: W, tr: &[f64]) -> Option<f64> {
        let prev = self.prev;
        self.prev = now;
        if !any(now) {
            return None;
        }
        self.advance(now, prev, active, tr)
    }

    /// [`DeepRuns::step`] for a step with some lane at or above the level (branch-free per lane:
    /// which lanes are deep varies from step to step).
    #[inline(never)]
    fn advance(&mut self, now: W, prev: W, active: W, tr: &[f64]) -> Option<f64> {
        let last = tr.len() - 1;
        let (mut total, mut counted) = (0.0, false);
        for w in 0..WORDS {
            let (mut bits, old, act) = (now[w], prev[w], active[w]);
            while bits != 0 {
                let i = bits.trailing_zeros();
                bits &= bits - 1;
                let l = (64 * w + i as usize) % RUNS;
                // L on the step a lane gets there (τ grows by one per step), then one more.
                let tau = if (old >> i) & 1 == 1 {
                    self.tau[l] + 1
                } else {
                    self.level
                };
                self.tau[l] = tau;
                let x = tr[(tau as usize).min(last)];
                self.sum[l] += x;
                // Adding +0.0 for a padding lane leaves the (non-negative) total as it is.
                let is_active = (act >> i) & 1 == 1;
                total += if is_active { x } else { 0.0 };
                counted |= is_active;
            }
        }
        counted.then_some(total)
    }
}
