//! Searches on the product automaton's graph: whether every state reaches an arrival, whether K
//! is one strongly connected class, its closed classes, whether K0 has a cycle.

use crate::engine::product::{Product, SparseRows};
use crate::error::{Error, Result};

/// The reversed graph of the union of `parts` (their entries' patterns), in CSR form: the
/// predecessors of f are `idx[ptr[f]..ptr[f + 1]]`.
fn reversed(n: usize, parts: &[&SparseRows]) -> (Vec<usize>, Vec<u32>) {
    let mut ptr = vec![0usize; n + 1];
    for m in parts {
        for &f in &m.indices {
            ptr[f as usize + 1] += 1;
        }
    }
    for f in 0..n {
        ptr[f + 1] += ptr[f];
    }
    let mut fill = ptr.clone();
    let mut idx = vec![0u32; ptr[n]];
    for m in parts {
        for e in 0..n {
            for &f in &m.indices[m.indptr[e]..m.indptr[e + 1]] {
                idx[fill[f as usize]] = e as u32;
                fill[f as usize] += 1;
            }
        }
    }
    (ptr, idx)
}

/// Marks every state with a path to one of `seeds` in the graph whose reversal is `rev`.
fn reaching(rev: &(Vec<usize>, Vec<u32>), seeds: Vec<usize>) -> Vec<bool> {
    let (ptr, idx) = rev;
    let mut ok = vec![false; ptr.len() - 1];
    for &e in &seeds {
        ok[e] = true;
    }
    let mut stack = seeds;
    while let Some(f) = stack.pop() {
        for &e in &idx[ptr[f]..ptr[f + 1]] {
            if !ok[e as usize] {
                ok[e as usize] = true;
                stack.push(e as usize);
            }
        }
    }
    ok
}

/// Every state must reach an arrival (so ρ(K0) < 1), by reverse reachability from the states
/// with an arriving transition. `arg` names what to blame.
pub(crate) fn check_arrivals(p: &Product, arg: &str) -> Result<()> {
    let n = p.n();
    let seeds = (0..n)
        .filter(|&e| p.k1.indptr[e + 1] > p.k1.indptr[e])
        .collect();
    let ok = reaching(&reversed(n, &[&p.k0]), seeds);
    if let Some(bad) = ok.iter().position(|&x| !x) {
        return Err(Error::invalid(
            arg,
            format!(
                "from state {} ({}) no packet ever arrives again: rho(K0) = 1 and the cost is infinite",
                bad,
                p.labels()[bad]
            ),
        ));
    }
    Ok(())
}

/// Whether K's graph is one strongly connected class: state 0 reaches every state and every
/// state reaches state 0 (two searches, cheaper than [`closed_classes`] in the usual case).
pub(crate) fn strongly_connected(p: &Product) -> bool {
    let n = p.n();
    let mut seen = vec![false; n];
    let mut stack = vec![0usize];
    seen[0] = true;
    let mut count = 1;
    while let Some(e) = stack.pop() {
        for m in [&p.k0, &p.k1] {
            for &f in &m.indices[m.indptr[e]..m.indptr[e + 1]] {
                if !seen[f as usize] {
                    seen[f as usize] = true;
                    count += 1;
                    stack.push(f as usize);
                }
            }
        }
    }
    count == n
        && reaching(&reversed(n, &[&p.k0, &p.k1]), vec![0])
            .iter()
            .all(|&x| x)
}

/// The closed classes of K's graph (members of each), by an iterative Tarjan.
pub(crate) fn closed_classes(p: &Product) -> Vec<Vec<usize>> {
    let n = p.n();
    let succ = |e: usize| p.k0.row(e).chain(p.k1.row(e)).map(|(f, _)| f);
    let mut index = vec![u32::MAX; n];
    let mut low = vec![0u32; n];
    let mut on = vec![false; n];
    let mut comp = vec![u32::MAX; n];
    let mut stack: Vec<usize> = Vec::new();
    let mut ncomp = 0u32;
    let mut counter = 0u32;
    for root in 0..n {
        if index[root] != u32::MAX {
            continue;
        }
        // (node, iterator position over its successors)
        let mut call: Vec<(usize, usize)> = vec![(root, 0)];
        index[root] = counter;
        low[root] = counter;
        counter += 1;
        stack.push(root);
        on[root] = true;
        while let Some(&mut (v, ref mut pos)) = call.last_mut() {
            let next = succ(v).nth(*pos);
            *pos += 1;
            match next {
                Some(w) if index[w] == u32::MAX => {
                    index[w] = counter;
                    low[w] = counter;
                    counter += 1;
                    stack.push(w);
                    on[w] = true;
                    call.push((w, 0));
                }
                Some(w) => {
                    if on[w] {
                        low[v] = low[v].min(index[w]);
                    }
                }
                None => {
                    call.pop();
                    if let Some(&(u, _)) = call.last() {
                        low[u] = low[u].min(low[v]);
                    }
                    if low[v] == index[v] {
                        while let Some(w) = stack.pop() {
                            on[w] = false;
                            comp[w] = ncomp;
                            if w == v {
                                break;
                            }
                        }
                        ncomp += 1;
                    }
                }
            }
        }
    }
    let mut leaves = vec![false; n.min(ncomp as usize)];
    leaves.iter_mut().for_each(|x| *x = true);
    for e in 0..n {
        if succ(e).any(|f| comp[f] != comp[e]) {
            leaves[comp[e] as usize] = false;
        }
    }
    let mut slot = vec![usize::MAX; ncomp as usize];
    let mut classes: Vec<Vec<usize>> = Vec::new();
    for (e, &c) in comp.iter().enumerate() {
        let c = c as usize;
        if leaves[c] {
            if slot[c] == usize::MAX {
                slot[c] = classes.len();
                classes.push(Vec::new());
            }
            classes[slot[c]].push(e);
        }
    }
    classes
}

/// Whether K0's graph has no cycle (then ρ(K0) = 0).
pub(crate) fn is_acyclic(k0: &SparseRows) -> bool {
    let n = k0.n();
    let mut indeg = vec![0u32; n];
    for &j in &k0.indices {
        indeg[j as usize] += 1;
    }
    let mut queue: Vec<usize> = (0..n).filter(|&e| indeg[e] == 0).collect();
    let mut seen = 0;
    while let Some(e) = queue.pop() {
        seen += 1;
        for (f, _) in k0.row(e) {
            indeg[f] -= 1;
            if indeg[f] == 0 {
                queue.push(f);
            }
        }
    }
    seen == n
}
