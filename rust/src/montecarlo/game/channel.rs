//! The lane kernel's form of a Markov channel: exact arrival draws per (state, power) and
//! inverse-CDF draws of the next state on exact 64-bit thresholds.

use super::plan::Bern;
use crate::montecarlo::automaton::MarkovChannel;
use crate::montecarlo::rng::bernoulli_threshold;

/// A distribution over 0..K drawn from one 64-bit uniform word u: the first j with
/// u < `cum[j]`, else `last`. `cum[j]` = ⌊F_j 2^64⌋ for the cumulative law F_j (the row
/// normalised to sum 1) and `last` is the last state of positive probability, so state j has
/// probability exactly (cum[j] - cum[j-1]) / 2^64 and a state of probability 0 is never drawn.
#[derive(Debug, Clone)]
pub(super) struct Cdf {
    cum: Vec<u64>,
    last: usize,
}

impl Cdf {
    /// The draw of the law `p` (non-negative, positive sum).
    pub(super) fn new(p: &[f64]) -> Self {
        let total: f64 = p.iter().sum();
        let last = p.iter().rposition(|&x| x > 0.0).unwrap_or(0);
        let mut acc = 0.0;
        // Partial sums of non-negative terms never decrease in floating point, nor do their
        // quotients by `total` and the thresholds: `cum` is sorted.
        let cum = p[..last]
            .iter()
            .map(|&x| {
                acc += x;
                bernoulli_threshold(acc / total)
            })
            .collect();
        Cdf { cum, last }
    }

    /// The state the uniform word `u` gives.
    #[inline(always)]
    pub(super) fn draw(&self, u: u64) -> usize {
        self.cum.partition_point(|&t| t <= u).min(self.last)
    }
}

/// A validated channel's draws.
#[derive(Debug, Clone)]
pub(super) struct ChannelPlan {
    /// Arrival draws, entry `2 c + high`: low[c] then high[c].
    pub(super) arrive: Vec<Bern>,
    /// The transition from each state (row c of P).
    pub(super) rows: Vec<Cdf>,
    /// The law of c_1, the stationary law of P.
    pub(super) init: Cdf,
}

impl ChannelPlan {
    /// The draws of `ch`, whose stationary law is `stationary` (validated by the caller).
    pub(super) fn new(ch: &MarkovChannel, stationary: &[f64]) -> Self {
        ChannelPlan {
            arrive: ch
                .low
                .iter()
                .zip(&ch.high)
                .flat_map(|(&lo, &hi)| [Bern::new(lo), Bern::new(hi)])
                .collect(),
            rows: ch.p.iter().map(|row| Cdf::new(row)).collect(),
            init: Cdf::new(stationary),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdf_thresholds_are_exact() {
        let c = Cdf::new(&[0.0, 0.25, 0.0, 0.75, 0.0]);
        // State 0 and 2 have probability 0; state 3, the last positive one, takes the rest.
        assert_eq!(c.last, 3);
        assert_eq!(c.cum, vec![0, 1 << 62, 1 << 62]);
        assert_eq!(c.draw(0), 1);
        assert_eq!(c.draw((1 << 62) - 1), 1);
        assert_eq!(c.draw(1 << 62), 3);
        assert_eq!(c.draw(u64::MAX), 3);
        let one = Cdf::new(&[1.0]);
        assert_eq!((one.draw(0), one.draw(u64::MAX)), (0, 0));
        let sure = Cdf::new(&[0.0, 1.0, 0.0]);
        assert_eq!((sure.draw(0), sure.draw(u64::MAX)), (1, 1));
    }
}
