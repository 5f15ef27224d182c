#!/usr/bin/env python
"""fakeack against the tools a researcher would otherwise use, on the same inputs, in one process.

Every row first checks that both sides give the same answer, then reports the median wall time of
several repeats (auto-looped like ``timeit`` when a call is short) and the speed ratio
peer / fakeack. A row whose answers disagree is reported as such, without a time, and makes the
script exit with status 1.

Tasks (``--tasks``, default all):

* ``pbar``: ``fa.LinearSystem(A, C, Q, R).pbar`` against ``scipy.linalg.solve_discrete_are`` on the
  dual (A', C') plus the conversion to the posterior P̄ = P - P C'(C P C' + R)^{-1} C P, on a fixed
  pseudo-random system (ρ(A) = 1.05, n_y = n_x/2), n_x = 1, 10, 50, 200. fakeack's time includes
  its input validation and detectability checks. BLAS is single-threaded on both sides (set
  ``OPENBLAS_NUM_THREADS`` yourself to change that for scipy).
* ``stationary``: the stationary law of the attack chain plus J on the paper's system
  (``fa.stationary_distribution`` + ``fa.j_attack``) against solving the chain's balance equations
  with ``scipy.sparse.linalg.spsolve``, the fair way: the matrix of ``fa.attack_chain`` (built
  outside the timed region, which favours scipy), one balance equation replaced by the pin
  π(0, 0) = 1 (sparse, unlike a row of ones), then normalised; J = Σ π Tr h^τ(P̄). Two column
  orderings: SuperLU's default COLAMD and NATURAL (the chain's own order, much less fill here:
  the best scipy can do). Also ``quantecon.MarkovChain(P).stationary_distributions`` (dense GTH)
  where a dense matrix is reasonable (|S| <= 5000). Sizes |S| ≈ 2e3, 5e3, 1e4, 1e6, 1e7; at 1e7
  scipy runs only if the time measured at 1e6, scaled linearly (x13), fits ``--scipy-budget``.
* ``sweep``: ``fa.beta_sweep`` (every r/t in lowest terms, t <= t_max) at t_max = 1e3, 1e4 against
  the naive approach, one chain per (r, t) built (``fa.attack_chain``) and solved with scipy
  (NATURAL ordering, its fastest here) plus its J. The naive approach cannot finish (3e5 chains at
  t_max = 1e3, 3e7 chains of up to 1e8 states at 1e4), so it is timed on pairs drawn at random
  (those over 2e6 states skipped) within ``--naive-budget`` seconds, each checked against the
  sweep's J, and its total is *extrapolated*: the linear model α + β|S| fitted on the timed pairs,
  summed over every pair's exact |S|. The NATURAL-order solve measured close to linear in |S| on
  these chains (see the stationary rows), so this is an estimate of the right order, not a bound;
  at t_max = 1e4 most chains would not even fit in memory. The row's peer says "extrapolated" and
  its note gives the sample and the model.
* ``montecarlo``: ``fa.simulate`` (covariance and state modes; paper's system, online z0 = 2,
  attack "first 1 of every 5"; in covariance mode also ``RandomBlocking(0.2)`` and
  ``FlagInjection(0.05)``) against the vectorised numpy baseline ``numpy_protocol.simulate``,
  same runs and horizon; the two J must agree within 4 combined standard errors. fakeack uses every
  core, numpy one. Skipped if the compiled module has no ``simulate`` yet. Then the same
  covariance run under ``GilbertElliott(0.2, 0.2, 1, 0)`` and ``GilbertElliott(0.1, 0.3, 0.9,
  0.2)`` (bit-sliced kernel) against the automaton kernel that ran every Markov channel before,
  both beside the exact engine's J_H.
* ``engine``: ``fa.Scenario(...).cost()`` (construction included) on a Gilbert-Elliott channel
  (p = 0.1, q = 0.3, λ_good = 0.9, λ_bad = 0.2) under periodic blocking of r of every t flag-ACKs,
  z0 = 2, sizes |E| ≈ 1e3 and 1e4 states of the automaton, against the explicit chain of
  (τ, e) a researcher would write (``benches/engine_peer.py``: τ truncated where its tail is below
  1e-12, the balance equations solved with ``scipy.sparse.linalg.spsolve``, COLAMD ordering), given
  K0, K1 and the truncation level outside its timed region.
* ``abi3`` (only when asked for, with ``--abi3-wheels ABI3.whl SPECIFIC.whl``): the shipped abi3
  build against a version-specific build of the same code, call by call in fresh processes (see
  ``benches/abi3.py``). The "speedup" column is specific / abi3: below 1 where abi3 is slower.
  The version-specific wheel comes from ``maturin build --release -F python`` (the ``abi3``
  feature left out).

Usage::

    python benches/compare.py                      # full run, several minutes
    python benches/compare.py --quick              # small sizes only, under two minutes
    python benches/compare.py --json out.json      # also write the records as JSON
    python benches/compare.py --tasks pbar,sweep   # a subset
    python benches/compare.py --tasks abi3 --abi3-wheels dist/*abi3*.whl target/wheels/*cp311*.whl

The JSON file is a list of records with exactly the keys ``task``, ``size``, ``peer``,
``fakeack_seconds``, ``peer_seconds``, ``speedup`` (``null`` for a skipped or disagreeing peer).
Timings depend on the machine and its load; the header prints the core count and load average.
"""

from __future__ import annotations

import os

# Dense BLAS/LAPACK single-threaded unless the caller says otherwise: fakeack's P̄ solver is
# single-threaded, and on a small shared machine threaded BLAS mostly oversubscribes (scipy's DARE at
# n_x = 50 ran ~10x slower threaded here). Must happen before numpy is imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from fractions import Fraction  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

import fakeack as fa  # noqa: E402
from fakeack import _fakeack  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy_protocol as npp  # noqa: E402

PAPER = (1.2, 0.7, 0.8, 0.8)
LAM = 0.5
RATIO = Fraction(1, 7)  # design_online(0.5, 1/7) = (z0 = 2, mu = 1)
# (z0, r, t) with |S| = r(r+1)z0/2 + t(z0+1) within 2 of the target, half the states in the growing
# levels sigma <= r (1e4, 1e6, 1e7 as in benches/core.rs).
CHAINS = {
    "2e3": (2, 31, 336),
    "5e3": (2, 50, 816),
    "1e4": (2, 70, 1_677),
    "1e6": (2, 700, 169_767),
    "1e7": (2, 2_236, 1_666_023),
}
QUANTECON_MAX_STATES = 5_000
NAIVE_TIMED_MAX_STATES = 2_000_000
TASKS = ("pbar", "stationary", "sweep", "montecarlo", "engine")
EXTRA_TASKS = ("abi3",)  # run only when named in --tasks


# ----------------------------------------------------------------------------- bookkeeping


@dataclass
class Row:
    task: str
    size: str
    peer: str
    fakeack_seconds: float | None
    peer_seconds: float | None
    note: str = ""

    @property
    def speedup(self) -> float | None:
        if self.fakeack_seconds and self.peer_seconds:
            return self.peer_seconds / self.fakeack_seconds
        return None

    def record(self) -> dict[str, Any]:
        return {
            "task": self.task,
            "size": self.size,
            "peer": self.peer,
            "fakeack_seconds": self.fakeack_seconds,
            "peer_seconds": self.peer_seconds,
            "speedup": self.speedup,
        }


class Bench:
    def __init__(self, repeats: int, budget: float):
        self.repeats, self.budget = repeats, budget
        self.rows: list[Row] = []
        self.failed = False

    def time(self, fn, repeats: int | None = None, budget: float | None = None) -> tuple[float, Any]:
        """Median seconds per call over up to ``repeats`` samples (stopping early past ``budget``
        seconds, after at least one); calls under 20 ms are looped so each sample lasts ~50 ms."""
        repeats = self.repeats if repeats is None else repeats
        budget = self.budget if budget is None else budget
        t0 = time.perf_counter()
        out = fn()
        first = time.perf_counter() - t0
        number = 1 if first >= 0.02 else max(1, int(0.05 / max(first, 1e-7)))
        samples = [first] if number == 1 else []
        start = time.perf_counter()
        while len(samples) < repeats and (time.perf_counter() - start < budget or not samples):
            t0 = time.perf_counter()
            for _ in range(number):
                out = fn()
            samples.append((time.perf_counter() - t0) / number)
        return statistics.median(samples), out

    def add(self, row: Row) -> None:
        self.rows.append(row)
        print(_format(row), flush=True)

    def disagree(self, task: str, size: str, peer: str, t_fa: float | None, why: str) -> None:
        self.failed = True
        self.add(Row(task, size, peer, t_fa, None, f"ANSWERS DISAGREE: {why}"))


def _fmt_s(x: float | None) -> str:
    if x is None:
        return "-"
    if x < 1e-3:
        return f"{x * 1e6:.1f} us"
    if x < 1:
        return f"{x * 1e3:.2f} ms"
    return f"{x:.3g} s"


def _format(row: Row) -> str:
    sp_ = "-" if row.speedup is None else f"{row.speedup:,.1f}x"
    return (
        f"{row.task:<11} {row.size:<22} {row.peer:<38} {_fmt_s(row.fakeack_seconds):>10} "
        f"{_fmt_s(row.peer_seconds):>10} {sp_:>11}  {row.note}"
    )


HEADER = f"{'task':<11} {'size':<22} {'peer':<38} {'fakeack':>10} {'peer':>10} {'speedup':>11}  note"


# ----------------------------------------------------------------------------- pbar


def random_system(n: int):
    """A fixed pseudo-random system: ρ(A) = 1.05, n_y = max(1, n/2), Q, R positive definite."""
    rng = np.random.default_rng(1000 + n)
    m = max(1, n // 2)
    A = rng.standard_normal((n, n))
    A *= 1.05 / max(abs(np.linalg.eigvals(A)))
    C = rng.standard_normal((m, n))
    B = rng.standard_normal((n, n))
    Q = B @ B.T / n + 0.1 * np.eye(n)
    D = rng.standard_normal((m, m))
    R = D @ D.T / m + 0.2 * np.eye(m)
    return A, C, Q, R


def task_pbar(b: Bench, quick: bool) -> None:
    for n in (1, 10, 50) if quick else (1, 10, 50, 200):
        A, C, Q, R = random_system(n)
        t_fa, p_fa = b.time(lambda A=A, C=C, Q=Q, R=R: fa.LinearSystem(A, C, Q, R).pbar)
        t_sc, p_sc = b.time(lambda A=A, C=C, Q=Q, R=R: npp.pbar_posterior(A, C, Q, R))
        err = np.linalg.norm(p_fa - p_sc) / np.linalg.norm(p_sc)
        if not err < 1e-8:
            b.disagree("pbar", f"n_x={n}", "scipy solve_discrete_are", t_fa, f"relative error {err:.2e}")
            continue
        b.add(Row("pbar", f"n_x={n}", "scipy solve_discrete_are", t_fa, t_sc, f"rel. diff {err:.1e}"))


# ----------------------------------------------------------------------------- stationary


def pinned_system(T: sp.csr_array) -> sp.csc_array:
    """T' - I with the balance equation of state 0 replaced by the pin π_0 = 1 (stays sparse)."""
    n = T.shape[0]
    M = sp.csr_array(T.T - sp.eye_array(n, format="csr"))
    M.data[M.indptr[0] : M.indptr[1]] = 0.0
    M[0, 0] = 1.0  # the diagonal entry exists (T' - I), so this is no structural change
    M.eliminate_zeros()
    return sp.csc_array(M)


def scipy_stationary_j(T, tau, tr, permc_spec: str) -> tuple[np.ndarray, float]:
    n = T.shape[0]
    rhs = np.zeros(n)
    rhs[0] = 1.0
    pi = spla.spsolve(pinned_system(T), rhs, permc_spec=permc_spec)
    pi /= pi.sum()
    return pi, _j_of(pi, tau, tr)


def _j_of(pi, tau, tr) -> float:
    # Tr h^tau(P̄) overflows to inf far out, where pi has underflowed to 0: those terms are 0.
    live = pi > 0
    return float(np.dot(pi[live], tr[tau[live]]))


def _agree(pi_fa, j_fa, pi_peer, j_peer) -> str | None:
    d = float(np.max(np.abs(pi_fa - pi_peer)))
    if not d <= 1e-12:
        return f"max |pi difference| {d:.2e}"
    if not abs(j_fa - j_peer) <= 1e-9 * abs(j_fa):
        return f"J {j_fa!r} vs {j_peer!r}"
    return None


def task_stationary(b: Bench, quick: bool, scipy_budget: float) -> None:
    sys_ = fa.LinearSystem(*PAPER)
    sizes = ("2e3", "1e4") if quick else ("2e3", "5e3", "1e4", "1e6", "1e7")
    try:
        import quantecon as qe
    except ImportError:
        qe = None
        b.add(
            Row(
                "stationary",
                "<=5e3",
                "quantecon",
                None,
                None,
                "skipped: quantecon not installed (pip install '.[bench]')",
            )
        )
    measured: dict[str, float] = {}
    for size in sizes:
        z0, r, t = CHAINS[size]
        n = fa.num_states(z0, r, t)
        label = f"S={size}"

        def run_fa(z0=z0, r=r, t=t):
            return fa.stationary_distribution(LAM, z0, r, t), fa.j_attack(sys_, LAM, z0, r, t)

        t_fa, (pi_fa, j_fa) = b.time(run_fa)
        ok = fa.balance_residual(LAM, z0, r, t, pi_fa) < 1e-12
        if not ok:
            b.disagree("stationary", label, "(balance residual)", t_fa, "fakeack's law is not stationary")
            continue
        states, T = fa.attack_chain(LAM, z0, r, t)
        tau = np.ascontiguousarray(states[:, 0])
        tr = sys_.h_traces(z0 * (r + 1))
        for spec in ("COLAMD", "NATURAL"):
            peer = f"scipy spsolve ({spec})"
            if size == "1e7":
                base = measured.get(spec)
                predicted = None if base is None else 13 * base
                if predicted is None or predicted > scipy_budget:
                    why = "no 1e6 timing" if predicted is None else f"predicted {predicted:.0f} s from 1e6"
                    b.add(
                        Row(
                            "stationary",
                            label,
                            peer,
                            t_fa,
                            None,
                            f"skipped: {why} > --scipy-budget {scipy_budget:.0f} s",
                        )
                    )
                    continue
            t_sc, (pi_sc, j_sc) = b.time(
                lambda T=T, tau=tau, tr=tr, spec=spec: scipy_stationary_j(T, tau, tr, spec),
                repeats=1 if n > 2_000_000 else None,
            )
            measured[spec] = t_sc
            why = _agree(pi_fa, j_fa, pi_sc, j_sc)
            if why:
                b.disagree("stationary", label, peer, t_fa, why)
                continue
            b.add(Row("stationary", label, peer, t_fa, t_sc, f"|S|={n:,}, J={j_fa:.6f}"))
        if qe is not None and n <= QUANTECON_MAX_STATES:
            dense = T.toarray()
            _ = qe.MarkovChain(np.array([[0.4, 0.6], [0.2, 0.8]])).stationary_distributions  # JIT, untimed

            def run_qe(dense=dense, tau=tau, tr=tr):
                pi = qe.MarkovChain(dense).stationary_distributions[0]
                return pi, _j_of(pi, tau, tr)

            t_qe, (pi_qe, j_qe) = b.time(run_qe, repeats=3 if n <= 2_000 else 1)
            why = _agree(pi_fa, j_fa, pi_qe, j_qe)
            if why:
                b.disagree("stationary", label, "quantecon MarkovChain (dense)", t_fa, why)
            else:
                b.add(
                    Row(
                        "stationary",
                        label,
                        "quantecon MarkovChain (dense)",
                        t_fa,
                        t_qe,
                        "dense matrix built outside the timing",
                    )
                )
        del T, states


# ----------------------------------------------------------------------------- sweep


def naive_pair(sys_, z0: int, r: int, t: int, tr) -> float:
    states, T = fa.attack_chain(LAM, z0, r, t)
    _, j = scipy_stationary_j(T, np.ascontiguousarray(states[:, 0]), tr, "NATURAL")
    return j


def task_sweep(b: Bench, quick: bool, naive_budget: float) -> None:
    sys_ = fa.LinearSystem(*PAPER)
    z0, mu = fa.design_online(LAM, RATIO)
    assert mu == 1.0, "the naive peer builds the mu = 1 chain"
    for t_max in (1_000,) if quick else (1_000, 10_000):
        size = f"t_max={t_max:.0e}".replace("e+0", "e")
        t_fa, sw = b.time(
            lambda t_max=t_max: fa.beta_sweep(sys_, LAM, RATIO, t_max), repeats=3 if t_max > 1_000 else None
        )
        npairs = len(sw)
        r_all = sw.r.astype(np.float64)
        t_all = sw.t.astype(np.float64)
        states_all = r_all * (r_all + 1) / 2 * z0 + t_all * (z0 + 1)
        tr = sys_.h_traces(z0 * t_max)
        # Pairs in random order (an unbiased sample of the sizes), skipping the few too large to
        # time here, until the budget is spent.
        order = np.random.default_rng(t_max).permutation(npairs)[:2_000]
        sizes, secs, worst = [], [], 0.0
        start = time.perf_counter()
        for i in order:
            if time.perf_counter() - start > naive_budget and len(secs) >= 3:
                break
            if states_all[i] > NAIVE_TIMED_MAX_STATES:
                continue
            r, t = int(sw.r[i]), int(sw.t[i])
            t0 = time.perf_counter()
            j = naive_pair(sys_, z0, r, t, tr)
            secs.append(time.perf_counter() - t0)
            sizes.append(states_all[i])
            worst = max(worst, abs(j - sw.j_attack[i]) / abs(sw.j_attack[i]))
        if not worst <= 1e-9:
            b.disagree("sweep", size, "naive scipy per (r, t)", t_fa, f"J relative difference {worst:.1e}")
            continue
        x, y = np.asarray(sizes), np.asarray(secs)
        beta_, alpha = np.polyfit(x, y, 1) if np.ptp(x) > 0 else (-1.0, -1.0)
        if alpha < 0 or beta_ <= 0:  # degenerate fit: cost proportional to |S|
            alpha, beta_ = 0.0, float(y.sum() / x.sum())
        alpha, beta_ = float(alpha), float(beta_)
        total = alpha * npairs + beta_ * float(states_all.sum())
        unbuildable = float(np.mean(states_all > fa.MAX_BUILD_STATES))
        note = (
            f"{npairs:,} pairs, sum|S|={states_all.sum():.2e}; naive timed on {len(secs)} random pairs "
            f"(|S| {x.min():.0f}..{x.max():.0f}, all J agree) and extrapolated linearly, "
            f"{alpha * 1e3:.2f} ms + {beta_ * 1e9:.0f} ns x |S| per pair"
            + (
                f" ({unbuildable:.0%} of pairs exceed fa.MAX_BUILD_STATES: not buildable at all)"
                if unbuildable
                else ""
            )
            + f"; per pair: fakeack {t_fa / npairs * 1e9:.0f} ns, naive ~{total / npairs:.3g} s"
        )
        b.add(Row("sweep", size, "naive scipy per (r, t) (extrapolated)", t_fa, total, note))


# ----------------------------------------------------------------------------- montecarlo


def task_montecarlo(b: Bench, quick: bool) -> None:
    if not hasattr(_fakeack, "simulate"):
        for mode in ("covariance", "state"):
            b.add(
                Row(
                    "montecarlo",
                    mode,
                    "numpy vectorised baseline",
                    None,
                    None,
                    "skipped: this build of fakeack._fakeack has no simulate binding yet",
                )
            )
        return
    sys_ = fa.LinearSystem(*PAPER)
    z0 = 2
    # (label, fakeack's attack, the baseline's attack arguments)
    periodic = ("1/5", fa.PeriodicBlocking(1, 5), dict(mask=[1, 0, 0, 0, 0]))
    random_ = ("random:0.2", fa.RandomBlocking(0.2), dict(beta=0.2))
    inject = ("inject:0.05", fa.FlagInjection(0.05), dict(gamma=0.05))
    cov, state = (20_000, 500), (4_096, 500)
    if not quick:
        cov, state = (100_000, 1_000), (20_000, 1_000)
    plans = [("covariance", *cov, periodic), ("state", *state, periodic)]
    plans += [("covariance", *cov, random_), ("covariance", *cov, inject)]
    for mode, runs, horizon, (label, attack, baseline_attack) in plans:
        size = f"{mode} {runs}x{horizon}" + ("" if label == "1/5" else f" {label}")
        j_exact = fa.j_attack(sys_, LAM, z0, attack=attack)

        def run_fa(mode=mode, runs=runs, horizon=horizon, attack=attack):
            return fa.simulate(
                sys_,
                LAM,
                fa.OnlineSchedule(z0),
                horizon=horizon,
                runs=runs,
                seed=1,
                attack=attack,
                mode=mode,
                progress=False,
            )

        def run_np(mode=mode, runs=runs, horizon=horizon, baseline_attack=baseline_attack):
            return npp.simulate(
                *PAPER,
                lam=LAM,
                z0=z0,
                horizon=horizon,
                runs=runs,
                seed=1,
                mode=mode,
                **baseline_attack,
            )

        t_fa, res_fa = b.time(run_fa)
        t_np, res_np = b.time(run_np, repeats=min(b.repeats, 3))
        se = math.hypot(res_fa.stderr, res_np.stderr)
        if not abs(res_fa.j - res_np.j) <= 4 * se:
            b.disagree(
                "montecarlo",
                size,
                "numpy vectorised baseline",
                t_fa,
                f"J {res_fa.j:.6f} vs {res_np.j:.6f} (4 se = {4 * se:.2e})",
            )
            continue
        steps = runs * horizon
        note = (
            f"fakeack {steps / t_fa:.3g} steps/s, numpy {steps / t_np:.3g} steps/s; "
            f"J {res_fa.j:.5f} vs {res_np.j:.5f} (exact stationary {j_exact:.5f})"
        )
        b.add(Row("montecarlo", size, "numpy vectorised baseline", t_fa, t_np, note))
    montecarlo_markov(b, sys_, z0, cov, periodic[1])


def montecarlo_markov(b: Bench, sys_, z0: int, size: tuple[int, int], attack) -> None:
    """Gilbert-Elliott rows beside the i.i.d. ones: the bit-sliced kernel against the automaton
    kernel that ran every Markov channel before, same runs, horizon and attack; the two J must
    agree within 4 combined standard errors, and each is shown beside the exact engine's."""
    from fakeack.model.system import compiled
    from fakeack.montecarlo import _automaton

    runs, horizon = size
    design = fa.OnlineSchedule(z0)
    for ch in (fa.GilbertElliott(0.2, 0.2, 1, 0), fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)):
        label = f"covariance {runs}x{horizon} GE({ch.p:g},{ch.q:g},{ch.lam_good:g},{ch.lam_bad:g})"

        def run_fa(ch=ch):
            return fa.simulate(sys_, ch, design, horizon, runs, seed=1, attack=attack, progress=False)

        def run_auto(ch=ch):
            core = compiled(sys_)
            return _automaton.run_automaton(core, ch, design, attack, horizon, runs, 1, lambda _: None, False)

        t_fa, res_fa = b.time(run_fa)
        t_au, res_au = b.time(run_auto, repeats=min(b.repeats, 3))
        j_exact = fa.expected_trace_curve(sys_, ch, design, horizon, attack=attack).j_k[-1]
        se = math.hypot(res_fa.stderr, res_au["stderr"])
        peer = "automaton kernel (the former route)"
        if not abs(res_fa.j - res_au["j"]) <= 4 * se:
            why = f"J {res_fa.j:.6f} vs {res_au['j']:.6f} (4 se = {4 * se:.2e})"
            b.disagree("montecarlo", label, peer, t_fa, why)
            continue
        steps = runs * horizon
        note = (
            f"fakeack {steps / t_fa:.3g} steps/s, automaton {steps / t_au:.3g} steps/s; "
            f"J {res_fa.j:.5f} vs {res_au['j']:.5f} (exact J_H {j_exact:.5f})"
        )
        b.add(Row("montecarlo", label, peer, t_fa, t_au, note))


# ----------------------------------------------------------------------------- main


# (size label, r, t): Gilbert-Elliott x PeriodicBlocking(r, t) with z0 = 2; about 5.8 states per t.
ENGINE_SIZES = (("1e3", 10, 170), ("1e4", 100, 1_720))


def task_engine(b: Bench, quick: bool) -> None:
    import engine_peer

    sys_ = fa.LinearSystem(*PAPER)
    channel = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    design = fa.OnlineDesign(2)
    for label, r, t in ENGINE_SIZES[:1] if quick else ENGINE_SIZES:
        attack = fa.PeriodicBlocking(r, t)
        t_fa, j_fa = b.time(lambda attack=attack: fa.Scenario(sys_, channel, design, attack).cost())
        sc = fa.Scenario(sys_, channel, design, attack)
        _, K0, K1 = sc.automaton()
        levels = engine_peer.truncation(sc)
        tr = engine_peer.traces(sys_.A, sys_.Q, sys_.pbar, levels)
        size = f"{label} ({sc.n_states} states, {levels} levels)"
        peer = "explicit (tau, e) chain, scipy spsolve"
        j_peer, t_peer = engine_peer.explicit_j_limited(K0, K1, levels, tr)  # one run: seconds or more
        if j_peer is None:
            b.add(Row("engine", size, peer, t_fa, None, f"J = {j_fa:.6f}; peer: {t_peer}"))
            continue
        if not math.isclose(j_fa, j_peer, rel_tol=1e-9):
            b.disagree("engine", size, peer, t_fa, f"J {j_fa!r} against {j_peer!r}")
            continue
        b.add(Row("engine", size, peer, t_fa, t_peer, f"J = {j_fa:.6f}"))


def task_abi3(b: Bench, wheels: list[str] | None, rounds: int) -> None:
    """The abi3 wheel against a version-specific one: the same calls, alternating processes."""
    import abi3

    if not wheels or len(wheels) != 2:
        print("abi3: give --abi3-wheels ABI3.whl SPECIFIC.whl", file=sys.stderr)
        b.failed = True
        return
    files, times = abi3.measure([Path(w) for w in wheels], rounds)
    peer = files[1].replace("_fakeack.", "").replace(".so", "").replace("-x86_64-linux-gnu", "")
    for name, (abi3_s, specific_s) in times["cpu"].items():
        kind = abi3.CALLS[name][1]
        diff = abi3_s - specific_s
        wall_abi3, wall_specific = times["wall"][name]
        note = (
            f"{kind}: CPU time abi3 {diff / specific_s:+.1%} ({diff * 1e9:+.0f} ns); "
            f"wall {_fmt_s(wall_abi3)} vs {_fmt_s(wall_specific)}"
        )
        b.add(Row("abi3", name, f"{peer} build (CPU time)", abi3_s, specific_s, note))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes only (under two minutes)")
    ap.add_argument("--json", metavar="FILE", help="write the records as a JSON list")
    ap.add_argument("--tasks", default=",".join(TASKS), help=f"comma-separated subset of {','.join(TASKS)}")
    ap.add_argument("--repeats", type=int, default=5, help="timed samples per measurement (median)")
    ap.add_argument(
        "--budget",
        type=float,
        default=20.0,
        help="stop repeating a measurement after this many seconds (default 20)",
    )
    ap.add_argument(
        "--scipy-budget",
        type=float,
        default=30.0,
        help="largest predicted scipy time at |S|=1e7 that is still run (default 30 s)",
    )
    ap.add_argument(
        "--naive-budget",
        type=float,
        default=None,
        help="seconds spent timing the naive sweep per t_max (default 20, quick 5)",
    )
    ap.add_argument(
        "--abi3-wheels",
        nargs=2,
        metavar=("ABI3", "SPECIFIC"),
        help="for --tasks abi3: the abi3 wheel and a version-specific wheel of the same code",
    )
    ap.add_argument("--abi3-rounds", type=int, default=7, help="alternating child runs per wheel (abi3)")
    args = ap.parse_args(argv)
    tasks = [x.strip() for x in args.tasks.split(",") if x.strip()]
    unknown = set(tasks) - set(TASKS) - set(EXTRA_TASKS)
    if unknown:
        ap.error(f"unknown task(s) {sorted(unknown)}; choose from {TASKS + EXTRA_TASKS}")
    repeats = min(args.repeats, 3) if args.quick else args.repeats
    budget = min(args.budget, 5.0) if args.quick else args.budget
    naive_budget = args.naive_budget if args.naive_budget is not None else (5.0 if args.quick else 20.0)

    print(
        f"fakeack {fa.__version__}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}, "
        f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}; "
        f"median of up to {repeats} samples{' (quick)' if args.quick else ''}"
    )
    print(HEADER)
    b = Bench(repeats, budget)
    t0 = time.perf_counter()
    for task in TASKS + EXTRA_TASKS:
        if task not in tasks:
            continue
        if task == "pbar":
            task_pbar(b, args.quick)
        elif task == "stationary":
            task_stationary(b, args.quick, args.scipy_budget)
        elif task == "sweep":
            task_sweep(b, args.quick, naive_budget)
        elif task == "montecarlo":
            task_montecarlo(b, args.quick)
        elif task == "engine":
            task_engine(b, args.quick)
        elif task == "abi3":
            task_abi3(b, args.abi3_wheels, args.abi3_rounds)
    print(f"done in {time.perf_counter() - t0:.0f} s, load average {os.getloadavg()[0]:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps([row.record() for row in b.rows], indent=2) + "\n")
        print(f"wrote {len(b.rows)} records to {args.json}")
    return 1 if b.failed else 0


if __name__ == "__main__":
    sys.exit(main())
