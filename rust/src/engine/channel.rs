//! The packet channel: a finite Markov chain whose state sets the arrival probability of a
//! low-power and of a high-power packet.

use crate::error::{Error, Result};

/// Tolerance on a row sum of a stochastic matrix (and of an attacker's move list).
pub const ROW_SUM_TOL: f64 = 1e-12;

/// A Markov channel: K states, `P[i][j] = P(c_{k+1} = j | c_k = i)` row-stochastic with one
/// closed class, and in state i a low-power packet arrives with probability `low[i]`, a
/// high-power one with `high[i]`. The first step's state c_1 has the stationary law.
///
/// [`Channel::bernoulli`] is the i.i.d. channel of the paper (K = 1, high power always arrives).
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    k: usize,
    p: Vec<f64>,
    low: Vec<f64>,
    high: Vec<f64>,
    stationary: Vec<f64>,
}

impl Channel {
    /// A validated Markov channel. Refused, naming the argument: a `P` that is not square K x K
    /// (K >= 1), has an entry outside [0, 1], a row whose sum is off 1 by more than
    /// [`ROW_SUM_TOL`], or more than one closed class; `low` or `high` not of length K or with an
    /// entry outside [0, 1].
    pub fn markov(p: Vec<Vec<f64>>, low: Vec<f64>, high: Vec<f64>) -> Result<Self> {
        let k = p.len();
        if k == 0 {
            return Err(Error::invalid("P", "must have at least one state"));
        }
        let mut flat = Vec::with_capacity(k * k);
        for (i, row) in p.iter().enumerate() {
            if row.len() != k {
                return Err(Error::invalid(
                    "P",
                    format!("must be square: row {i} has {} entries, not {k}", row.len()),
                ));
            }
            for (j, &x) in row.iter().enumerate() {
                if !(x.is_finite() && (0.0..=1.0).contains(&x)) {
                    return Err(Error::invalid(
                        "P",
                        format!("entry ({i}, {j}) must lie in [0, 1], got {x}"),
                    ));
                }
            }
            let s: f64 = row.iter().sum();
            if (s - 1.0).abs() > ROW_SUM_TOL {
                return Err(Error::invalid(
                    "P",
                    format!("row {i} must sum to 1, sums to {s}"),
                ));
            }
            flat.extend_from_slice(row);
        }
        for (name, v) in [("low", &low), ("high", &high)] {
            if v.len() != k {
                return Err(Error::invalid(
                    name,
                    format!(
                        "must have one entry per channel state ({k}), got {}",
                        v.len()
                    ),
                ));
            }
            if let Some((i, x)) = v
                .iter()
                .enumerate()
                .find(|(_, x)| !(x.is_finite() && (0.0..=1.0).contains(*x)))
            {
                return Err(Error::invalid(
                    name,
                    format!("entry {i} must lie in [0, 1], got {x}"),
                ));
            }
        }
        let closed = closed_class(&flat, k)?;
        let stationary = dense_gth(&flat, k, &closed);
        Ok(Channel {
            k,
            p: flat,
            low,
            high,
            stationary,
        })
    }

    /// The i.i.d. channel: every low-power packet arrives with probability `lam` in [0, 1], every
    /// high-power one arrives.
    pub fn bernoulli(lam: f64) -> Result<Self> {
        if !(lam.is_finite() && (0.0..=1.0).contains(&lam)) {
            return Err(Error::invalid(
                "lam",
                format!("must lie in [0, 1], got {lam}"),
            ));
        }
        Channel::markov(vec![vec![1.0]], vec![lam], vec![1.0])
    }

    /// Gilbert-Elliott: state 0 good, 1 bad, `P = [[1-p, p], [q, 1-q]]`, low-power arrival
    /// `lam_good` / `lam_bad`, high-power `high_good` / `high_bad`.
    pub fn gilbert_elliott(
        p: f64,
        q: f64,
        lam_good: f64,
        lam_bad: f64,
        high_good: f64,
        high_bad: f64,
    ) -> Result<Self> {
        Channel::markov(
            vec![vec![1.0 - p, p], vec![q, 1.0 - q]],
            vec![lam_good, lam_bad],
            vec![high_good, high_bad],
        )
    }

    /// Number of channel states K.
    pub fn n_states(&self) -> usize {
        self.k
    }

    /// Transition probability from state `i` to state `j`.
    pub fn p(&self, i: usize, j: usize) -> f64 {
        self.p[i * self.k + j]
    }

    /// Row `i` of P.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.p[i * self.k..(i + 1) * self.k]
    }

    /// Low-power arrival probability per state.
    pub fn low(&self) -> &[f64] {
        &self.low
    }

    /// High-power arrival probability per state.
    pub fn high(&self) -> &[f64] {
        &self.high
    }

    /// The stationary law of P (zero off its closed class).
    pub fn stationary(&self) -> &[f64] {
        &self.stationary
    }
}

/// The one closed class of the K x K stochastic matrix `p` (row-major) as a membership mask;
/// refused (naming `P`) when there are several. A state is in a closed class iff it is reachable
/// from every state it reaches.
pub(crate) fn closed_class(p: &[f64], k: usize) -> Result<Vec<bool>> {
    let reach: Vec<Vec<bool>> = (0..k)
        .map(|s| {
            let mut seen = vec![false; k];
            let mut stack = vec![s];
            seen[s] = true;
            while let Some(i) = stack.pop() {
                for j in 0..k {
                    if p[i * k + j] > 0.0 && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
            seen
        })
        .collect();
    let closed: Vec<bool> = (0..k)
        .map(|i| (0..k).all(|j| !reach[i][j] || reach[j][i]))
        .collect();
    // Two closed states are in one class iff each reaches the other.
    let first = closed.iter().position(|&c| c).unwrap_or(0);
    if (0..k).any(|j| closed[j] && !reach[first][j]) {
        return Err(Error::invalid(
            "P",
            "must have exactly one closed class (the channel's long-run law would depend on its start)",
        ));
    }
    Ok(closed)
}

/// Stationary law of the stochastic matrix restricted to its closed class, by the
/// Grassmann-Taksar-Heyman reduction (no subtractions). K is small: dense O(K^3).
pub(crate) fn dense_gth(p: &[f64], k: usize, closed: &[bool]) -> Vec<f64> {
    let idx: Vec<usize> = (0..k).filter(|&i| closed[i]).collect();
    let m = idx.len();
    let mut a: Vec<f64> = Vec::with_capacity(m * m);
    for &i in &idx {
        for &j in &idx {
            a.push(p[i * k + j]);
        }
    }
    for n in (1..m).rev() {
        let s: f64 = (0..n).map(|j| a[n * m + j]).sum();
        if s <= 0.0 {
            continue;
        }
        for i in 0..n {
            a[i * m + n] /= s;
        }
        for i in 0..n {
            let ain = a[i * m + n];
            if ain == 0.0 {
                continue;
            }
            for j in 0..n {
                a[i * m + j] += ain * a[n * m + j];
            }
        }
    }
    let mut x = vec![0.0; m];
    x[0] = 1.0;
    for n in 1..m {
        x[n] = (0..n).map(|i| x[i] * a[i * m + n]).sum();
    }
    let total: f64 = x.iter().sum();
    let mut out = vec![0.0; k];
    for (t, &i) in idx.iter().enumerate() {
        out[i] = x[t] / total;
    }
    out
}
