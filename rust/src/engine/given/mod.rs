//! An automaton E given by hand as K0 and K1 (new sensor policies, attackers, jammers), solved by
//! the same routes as an explored product.

use std::sync::OnceLock;

use crate::engine::graph;
use crate::engine::product::{push_row, Origin, Product, SparseRows};
use crate::engine::Engine;
use crate::error::{Error, Result};

#[cfg(test)]
mod tests;

/// K0 or K1 as COO triplets (rows, cols, vals), indices from 0; repeated entries add up.
pub type Triplets<'a> = (&'a [i64], &'a [i64], &'a [f64]);

/// How far a row of K0 + K1 may sum from 1.
pub const ROW_SUM_TOL: f64 = 1e-12;

/// The argument an error about the given automaton names.
const ARG: &str = "K0";

impl Engine {
    /// The engine of an automaton E given by hand: `n` states, `k0` the transitions whose packet
    /// is lost (τ -> τ + 1), `k1` those whose packet arrives (τ -> 0), `init` the law of e_0 before
    /// step 1 (state 0 surely when `None`; the holding time starts at τ_0 = 0) and a label per
    /// state (its index when `None`).
    ///
    /// J, the stability index, the holding-time law, the cost curve and the stationary law are
    /// those of [`Engine::new`], from the same coupled Stein equations
    /// Z_e = P̄ + (w_e - 1) Q + Σ_f K0[e, f] A Z_f A', J = Tr Σ_e ν_e Z_e. With several closed
    /// classes, J is the long-run mean from `init` (each class weighted by the chance of ending in
    /// it). The automaton carries no power or flag-ACK information, so
    /// [`Engine::high_power_rate`] and [`Engine::flag_rates`] return an error.
    ///
    /// # Errors
    /// [`Error::TooLarge`] naming `K0` when `n` exceeds `max_states` (before allocating);
    /// [`Error::InvalidArgument`] naming `K0` or `K1` for an index outside 0..n, a negative or
    /// non-finite value, or triplets of unequal lengths; `K0 + K1` when a row of K0 + K1 is not
    /// 1 within [`ROW_SUM_TOL`]; `init` for a law that is not one, or a state it never reaches;
    /// `labels` for a count other than `n`; `K0` when from some state no packet ever arrives
    /// again (ρ(K0) = 1).
    ///
    /// ```
    /// use fakeack::{Engine, LinearSystem};
    ///
    /// // One state: every packet arrives with probability 0.6.
    /// let (lam, a, q, pbar) = (0.6, 1.2f64, 0.8, 0.5);
    /// let e = Engine::from_automaton(1, (&[0], &[0], &[1.0 - lam]), (&[0], &[0], &[lam]), None, None, 10)?;
    /// let system = LinearSystem::scalar(a, 0.7, q, 0.8)?;
    /// let pbar = system.pbar()[(0, 0)];
    /// let j = (lam * pbar + (1.0 - lam) * q) / (1.0 - (1.0 - lam) * a * a);
    /// assert!((e.cost(&system)? - j).abs() < 1e-12 * j);
    /// # Ok::<(), fakeack::Error>(())
    /// ```
    pub fn from_automaton(
        n: usize,
        k0: Triplets<'_>,
        k1: Triplets<'_>,
        init: Option<&[f64]>,
        labels: Option<Vec<String>>,
        max_states: usize,
    ) -> Result<Self> {
        // State indices are u32 in the sparse rows.
        let limit = max_states.min(u32::MAX as usize - 1);
        if n > limit {
            return Err(Error::TooLarge {
                arg: ARG.into(),
                requested: n as u128,
                limit: limit as u128,
            });
        }
        if n == 0 {
            return Err(Error::invalid(
                ARG,
                "the automaton needs at least one state",
            ));
        }
        if let Some(l) = &labels {
            if l.len() != n {
                return Err(Error::invalid(
                    "labels",
                    format!("{} labels for {n} states", l.len()),
                ));
            }
        }
        let init = initial_law(n, init)?;
        let k0 = rows_of("K0", n, k0)?;
        let k1 = rows_of("K1", n, k1)?;
        for e in 0..n {
            let s: f64 = k0.row(e).chain(k1.row(e)).map(|(_, v)| v).sum();
            if (s - 1.0).abs() > ROW_SUM_TOL {
                return Err(Error::invalid(
                    "K0 + K1",
                    format!("row {e} sums to {s}, not 1 (within {ROW_SUM_TOL:e})"),
                ));
            }
        }
        let product = Product {
            init,
            k0,
            k1,
            origin: Origin::Given(labels),
        };
        check_reached(&product)?;
        graph::check_arrivals(&product, ARG)?;
        Ok(Engine {
            product,
            arg: ARG,
            stationary: OnceLock::new(),
            rho_k0: OnceLock::new(),
        })
    }
}

/// The initial law: state 0 surely, or `init` checked to be a probability vector.
fn initial_law(n: usize, init: Option<&[f64]>) -> Result<Vec<f64>> {
    let Some(init) = init else {
        let mut law = vec![0.0; n];
        law[0] = 1.0;
        return Ok(law);
    };
    if init.len() != n {
        return Err(Error::invalid(
            "init",
            format!("{} entries for {n} states", init.len()),
        ));
    }
    if let Some(i) = init.iter().position(|&x| !(x.is_finite() && x >= 0.0)) {
        return Err(Error::invalid(
            "init",
            format!("entry {i} is {}, not a probability", init[i]),
        ));
    }
    let s: f64 = init.iter().sum();
    if (s - 1.0).abs() > ROW_SUM_TOL {
        return Err(Error::invalid(
            "init",
            format!("sums to {s}, not 1 (within {ROW_SUM_TOL:e})"),
        ));
    }
    Ok(init.to_vec())
}

/// CSR rows of a triplet matrix, checked: indices in 0..n, values finite and >= 0; repeated
/// entries summed, zeros dropped (a zero in K1 must not count as an arrival).
fn rows_of(arg: &str, n: usize, (rows, cols, vals): Triplets<'_>) -> Result<SparseRows> {
    if rows.len() != cols.len() || rows.len() != vals.len() {
        return Err(Error::invalid(
            arg,
            format!(
                "rows, cols and vals have {}, {} and {} entries",
                rows.len(),
                cols.len(),
                vals.len()
            ),
        ));
    }
    let index = |what: &str, x: i64| -> Result<u32> {
        usize::try_from(x)
            .ok()
            .filter(|&i| i < n)
            .map(|i| i as u32)
            .ok_or_else(|| Error::invalid(arg, format!("{what} index {x} is outside 0..{n}")))
    };
    let mut count = vec![0usize; n + 1];
    for (k, &v) in vals.iter().enumerate() {
        if !(v.is_finite() && v >= 0.0) {
            return Err(Error::invalid(
                arg,
                format!("entry {k} is {v}: a probability must be finite and >= 0"),
            ));
        }
        count[index("row", rows[k])? as usize + 1] += 1;
        index("column", cols[k])?;
    }
    for i in 0..n {
        count[i + 1] += count[i];
    }
    // Bucket the entries by row, then let push_row sort and sum each.
    let mut fill = count.clone();
    let mut order = vec![0usize; vals.len()];
    for (k, &r) in rows.iter().enumerate() {
        let r = r as usize;
        order[fill[r]] = k;
        fill[r] += 1;
    }
    let mut m = SparseRows {
        indptr: Vec::with_capacity(n + 1),
        indices: Vec::with_capacity(vals.len()),
        data: Vec::with_capacity(vals.len()),
    };
    m.indptr.push(0);
    let mut row: Vec<(u32, f64)> = Vec::new();
    for i in 0..n {
        row.clear();
        row.extend(
            order[count[i]..count[i + 1]]
                .iter()
                .filter(|&&k| vals[k] > 0.0)
                .map(|&k| (cols[k] as u32, vals[k])),
        );
        push_row(&mut m, &mut row);
    }
    Ok(m)
}

/// Every state must be reached from the initial law: J is the long-run mean from it, and an
/// unreached state's loss loop would still count in ρ(K0).
fn check_reached(p: &Product) -> Result<()> {
    let n = p.n();
    let mut seen: Vec<bool> = p.init.iter().map(|&x| x > 0.0).collect();
    let mut stack: Vec<usize> = (0..n).filter(|&e| seen[e]).collect();
    while let Some(e) = stack.pop() {
        for (f, _) in p.k0.row(e).chain(p.k1.row(e)) {
            if !seen[f] {
                seen[f] = true;
                stack.push(f);
            }
        }
    }
    match seen.iter().position(|&s| !s) {
        None => Ok(()),
        Some(bad) => Err(Error::invalid(
            "init",
            format!(
                "state {bad} ({}) is never reached from the initial law (state 0 unless init is \
                 given); drop it or start from a law that reaches it",
                p.labels()[bad]
            ),
        )),
    }
}
