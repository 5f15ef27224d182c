r"""The flag-ACKs that reach the sensor as a Markov arrival process over the exact engine's
automaton, on any channel and under any attack (:func:`flag_process`).

The engine's automaton E (docs page "The exact engine") moves by :math:`K` each step, and its
state holds the sensor's next power, which is high exactly when a flag-ACK reached the sensor
this step (genuine or forged). Splitting :math:`K = D_0 + D_1` by whether the next state's power
is high makes the deliveries a discrete-time Markov arrival process: with :math:`\pi` the
stationary law and :math:`d = D_1\mathbf 1`, the rate is :math:`\lambda_f = \pi d` and, with
:math:`g` the solution of the Poisson equation :math:`(I - K)g = d - \lambda_f\mathbf 1`,
:math:`\pi g = 0`,

.. math:: \lim_{n\to\infty} \tfrac1n \mathrm{Var}\,N_n
          = \lambda_f(1 - \lambda_f) + 2\,\pi D_1 g,

since :math:`\mathrm{Cov}(X_k, X_{k+m}) = \pi D_1 K^{m-1} d - \lambda_f^2` and
:math:`\sum_{m\ge1}(K^{m-1} - \mathbf 1\pi)d = g` (the fundamental matrix). The count of a
window of n steps has the exact law of a forward recursion over (state, count)
(:meth:`FlagProcess.count_law`). On the paper's channel without attack the gaps are i.i.d. and
these reduce to the renewal moments of :func:`fakeack.flag_interval_moments`
(:math:`\lambda_f = 1/m`, variance rate :math:`v/m^3`); under a Markov channel successive gaps
are correlated, which is why only counts, not gap histograms, are tested there.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .._internal.types import FloatArray
from .._internal.validate import as_int
from ..engine.scenario import Scenario
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.schedules import OnlineDesign
from .flags import any_system

__all__ = [
    "FlagProcess",
    "flag_process",
]

#: Largest (states x steps x counts) of an exact count law, about a second of work.
MAX_LAW_WORK = 4 * 10**9
_STARTS = ("stationary", "initial")
_LABEL = re.compile(r"c=(\d+) z=(\d+) power=(high|low)")


def _stationary(K: sp.csr_array) -> FloatArray:
    """The stationary law of a unichain K (one closed class, as the engine guarantees)."""
    n = K.shape[0]
    A = (sp.identity(n, format="csr") - K).T.tolil()
    A[0, :] = 1.0  # replace one balance equation by the normalisation
    rhs = np.zeros(n)
    rhs[0] = 1.0
    pi = splu(A.tocsc()).solve(rhs)
    pi[np.abs(pi) < 1e-300] = 0.0
    return np.asarray(pi / pi.sum())


def _poisson(K: sp.csr_array, r: FloatArray, pi: FloatArray) -> FloatArray:
    """g with (I - K) g = r and pi g = 0 (r has pi r = 0; one column or several): fix g at a
    recurrent state, then shift, since the equations fixed there are independent for a unichain."""
    n = K.shape[0]
    ref = int(np.argmax(pi))
    A = (sp.identity(n, format="csr") - K).tolil()
    A[ref, :] = 0.0
    A[ref, ref] = 1.0
    rhs = r.copy()
    rhs[ref] = 0.0
    g = splu(A.tocsc()).solve(rhs)
    return np.asarray(g - pi @ g)


@dataclass(frozen=True)
class FlagProcess:
    """The flag-ACKs reaching the sensor as a Markov arrival process (see :func:`flag_process`)."""

    channel: Channel
    design: OnlineDesign
    attack: Any
    rate: float
    """Delivered flag-ACKs per step, :math:`\\pi D_1 \\mathbf 1`."""
    variance_rate: float
    """:math:`\\lim_n \\mathrm{Var}\\,N_n / n`."""
    D0: sp.csr_array = field(repr=False)
    """Transitions of E after which the sensor transmits at low power (no flag-ACK delivered)."""
    D1: sp.csr_array = field(repr=False)
    """Transitions after which it transmits at high power (a flag-ACK delivered)."""
    stationary: FloatArray = field(repr=False)
    initial: FloatArray = field(repr=False)
    """The paper's initial condition: high power at k = 1, memory restarted, c_1 stationary."""
    labels: tuple[str, ...] = field(default=(), repr=False)
    """The engine's label of each state (``c=... z=... power=... attacker=...``)."""

    @property
    def n_states(self) -> int:
        """States of the automaton."""
        return int(self.D0.shape[0])

    def _start(self, start: str) -> FloatArray:
        if start not in _STARTS:
            raise ValueError(f"start must be 'stationary' or 'initial', got {start!r}")
        return self.stationary if start == "stationary" else self.initial

    def count_moments(self, n_steps: int, start: str = "stationary") -> tuple[float, float]:
        r"""Exact mean and variance of the count :math:`N_n` of flag-ACKs delivered in n steps.

        :math:`E N_n = \sum_k p_k d` and
        :math:`\mathrm{Var}\,N_n = \sum_k p_k d(1 - p_k d) + 2\sum_{k<l} (p_k D_1 K^{l-k-1} d -
        p_k d\, p_l d)`, with :math:`p_k` the law of the state at step k, by one pass of
        sparse products (O(n^2) in the window, so at most 10^5 steps).

        Parameters
        ----------
        n_steps : int
            The window, 1..10^5 steps.
        start : {"stationary", "initial"}
            The law of the first state: stationary (a window in the long run) or the paper's
            initial condition (a run of :func:`fakeack.simulate`).

        Returns
        -------
        (mean, variance) : tuple of float
        """
        n = as_int("n_steps", n_steps, minimum=1, maximum=10**5)
        p = self._start(start)
        d = np.asarray(self.D1.sum(axis=1)).ravel()
        K = (self.D0 + self.D1).tocsr()
        D1t, Kt = self.D1.T.tocsr(), K.T.tocsr()
        mean, var = 0.0, 0.0
        # carry = sum over earlier steps k of p_k D1 K^(l-k-1): the joint mass of "a delivery at k"
        # pushed to step l; carry @ d is then sum_k P(X_k = 1, X_l = 1).
        carry = np.zeros(self.n_states)
        for _ in range(n):
            q = float(p @ d)
            mean += q
            var += q * (1.0 - q) + 2.0 * (float(carry @ d) - q * (mean - q))
            carry = Kt @ carry + D1t @ p
            p = Kt @ p
        return mean, max(var, 0.0)

    @property
    def min_gap(self) -> int:
        """The shortest possible gap (steps) between two flag-ACKs reaching the sensor: the least
        g >= 1 with :math:`D_1 D_0^{g-1} D_1` not zero on the states the chain visits; 0 if none
        is ever delivered twice. Without attack and with high-power packets that always arrive
        it is z0 + 1."""
        live = self.stationary > 0
        frontier = np.asarray(self.D1.T @ live.astype(float)).ravel() > 0  # just delivered
        D0t, D1t = self.D0.T.tocsr(), self.D1.T.tocsr()
        seen = np.zeros_like(frontier)
        for g in range(1, self.n_states + 2):
            if np.any(np.asarray(D1t @ frontier.astype(float)).ravel() > 0):
                return g
            frontier = np.asarray(D0t @ frontier.astype(float)).ravel() > 0
            if not frontier.any() or (seen >= frontier).all():
                break
            seen |= frontier
        return 0

    def _age_law(self, g: int) -> FloatArray:
        """The stationary joint law f[age, state] of the state and the steps since the last
        delivery (capped at g - 1): the chain run from the states' stationary law until it
        settles."""
        f = np.zeros((g, self.n_states))
        f[g - 1] = self.stationary
        for _ in range(10 * g + 200):
            new = self._age_step(f)[0]
            settled = np.abs(new - f).max() < 1e-15
            f = new
            if settled:
                break
        return f

    def _age_step(self, f: FloatArray) -> tuple[FloatArray, float]:
        """One step of (age, state) mass: the next mass with short-gap deliveries kept at age 0,
        and the mass of those short-gap deliveries (an age below g - 1 at delivery)."""
        g = f.shape[0]
        D0t, D1t = self._transposed
        delivered = D1t @ f.T  # (state, age)
        moved = (D0t @ f.T).T
        new = np.zeros_like(f)
        new[0] = delivered.sum(axis=1)
        new[1:] += moved[:-1]
        new[g - 1] += moved[g - 1]
        return new, float(delivered[:, : g - 1].sum())

    @property
    def _transposed(self) -> tuple[sp.csr_array, sp.csr_array]:
        return self.D0.T.tocsr(), self.D1.T.tocsr()

    def short_gap_probability(self, n_steps: int, min_gap: int) -> float:
        r"""P(a flag-ACK reaches the sensor within ``min_gap - 1`` steps of the previous one, in a
        stationary window of ``n_steps`` steps): the support check's alarm probability.

        The gap that straddles the window's start counts (the previous delivery may lie before
        it). A forward recursion over (state, steps since the last delivery, capped at
        ``min_gap``), from its stationary law, with the short-gap deliveries made absorbing.
        """
        n = as_int("n_steps", n_steps, minimum=1)
        g = as_int("min_gap", min_gap, minimum=1)
        if g == 1:
            return 0.0  # every gap is at least one step
        f = self._age_law(g)
        D0t, D1t = self._transposed
        alarm = 0.0
        for _ in range(n):
            delivered = D1t @ f.T  # (state, age): deliveries at an age below g - 1 alarm
            alarm += float(delivered[:, : g - 1].sum())
            moved = (D0t @ f.T).T
            new = np.zeros_like(f)
            new[0] = delivered[:, g - 1]
            new[1:] += moved[:-1]
            new[g - 1] += moved[g - 1]
            f = new
        return float(min(max(alarm, 0.0), 1.0))

    def window_alarm_probability(
        self, n_steps: int, min_gap: int, bounds: tuple[int, int], harm: int | None = None
    ) -> float:
        r"""P(the support check or the count test alarms) in a stationary window of ``n_steps``:
        :math:`1 - P(\text{no gap below min\_gap and } lo < N < hi)`, exactly.

        A forward recursion over (steps since the last delivery, state, count) in which a
        short-gap delivery and a count reaching ``hi`` leave the recursion (both are alarms);
        what is left at the end with a count above ``lo`` raised no alarm. With ``harm`` only
        alarms with :math:`N \le` ``harm`` count (the harmful rule), through
        :math:`P(N \le harm) - P(\text{no alarm}, N \le harm)`.

        Parameters
        ----------
        n_steps : int
            The window.
        min_gap : int
            The support check's shortest attack-free gap (:attr:`min_gap` of the attack-free
            process).
        bounds : (int, int)
            The count test's alarm region: :math:`N \le lo` or :math:`N \ge hi`.
        harm : int, optional
            Only alarms with at most this count.

        Returns
        -------
        float
        """
        n = as_int("n_steps", n_steps, minimum=1)
        g = as_int("min_gap", min_gap, minimum=1)
        lo, hi = int(bounds[0]), int(bounds[1])
        top = max(min(hi, n + 1), 1)  # counts 0..top-1 stay; reaching hi is an alarm
        if self.n_states * g * n * top > MAX_LAW_WORK:
            raise ValueError(
                f"n_steps = {n}: the joint law of the support check and the count needs about "
                f"{self.n_states * g * n * top:.2g} operations, more than {MAX_LAW_WORK:.0e}"
            )
        D0t, D1t = self._transposed
        # f[state, age, count] on the band of counts [a, b) that holds mass (the count of a step
        # spreads over O(sqrt(k)) values, a fraction of 0..top); age capped at g - 1 (g = 1: one
        # age, no gap is short). One sparse product per step for every (age, count) column.
        S = self.n_states
        f = np.zeros((S, g, 1))
        f[:, :, 0] = self._age_law(g).T
        a = 0
        for _ in range(n):
            width = f.shape[2]
            flat = f.reshape(S, g * width)
            delivered = (D1t @ flat).reshape(S, g, width)
            moved = (D0t @ flat).reshape(S, g, width)
            grown = min(a + width + 1, top) - a  # a count reaching hi leaves: an alarm
            new = np.zeros((S, g, grown))
            # A delivery at the largest age (a gap of at least g) moves the count up by one;
            # deliveries at a smaller age are short gaps and leave.
            new[:, 0, 1:] = delivered[:, g - 1, : grown - 1]
            if g > 1:
                new[:, 1:, :width] += moved[:, :-1]
            new[:, g - 1, :width] += moved[:, g - 1]
            mass = new.sum(axis=(0, 1))
            live = np.flatnonzero(mass > 1e-24)  # dropping the rest moves the result by < 1e-17
            if live.size == 0:  # every window has alarmed, up to far below rounding
                f = np.zeros((S, g, 0))
                break
            f = new[:, :, live[0] : live[-1] + 1]
            a += int(live[0])
        left = np.zeros(top)  # P(no alarm so far, N = c), c < top
        left[a : a + f.shape[2]] = f.sum(axis=(0, 1))
        quiet = left[max(lo + 1, 0) :]
        if harm is None:
            return float(min(max(1.0 - quiet.sum(), 0.0), 1.0))
        if harm < 0:
            return 0.0
        law = self.count_law(n)
        below = float(law[: harm + 1].sum())
        quiet_harm = float(left[max(lo + 1, 0) : harm + 1].sum())
        return float(min(max(below - quiet_harm, 0.0), 1.0))

    def mixing_steps(self, tol: float = 1e-3, max_steps: int = 10**6) -> int:
        r"""Steps after which the automaton, started from the paper's initial condition, is within
        ``tol`` of its stationary law in total variation: the least k with
        :math:`\tfrac12 \lVert p_0 K^k - \pi \rVert_1 \le` ``tol``.

        A burn-in this long puts a simulated window in the stationary regime that
        :func:`fakeack.detection_probability` describes, up to ``tol`` in every probability of the
        window; the attacker's phase (a periodic attack's counter) is what mixes slowly.

        Parameters
        ----------
        tol : float
            Total-variation distance, in (0, 1).
        max_steps : int
            Refuse (``ValueError`` naming ``tol``) if the law has not come that close by then.

        Returns
        -------
        int
        """
        tol = float(tol)
        if not 0.0 < tol < 1.0:
            raise ValueError(f"tol must lie in (0, 1), got {tol}")
        limit = as_int("max_steps", max_steps, minimum=1)
        Kt = (self.D0 + self.D1).T.tocsr()
        p = self.initial.copy()
        for k in range(limit + 1):
            if 0.5 * float(np.abs(p - self.stationary).sum()) <= tol:
                return k
            p = Kt @ p
        raise ValueError(
            f"tol = {tol}: the automaton is not within it of its stationary law after {limit} steps"
        )

    def count_law(self, n_steps: int, start: str = "stationary") -> FloatArray:
        r"""The exact law of the count :math:`N_n`: ``law[c] = P(N_n = c)``, c = 0..len-1.

        A forward recursion over (state, count): :math:`f_{k+1}(\cdot, c) = f_k(\cdot, c) D_0 +
        f_k(\cdot, c-1) D_1`. Refused (``ValueError`` naming ``n_steps``) beyond about a second
        of work.

        Parameters
        ----------
        n_steps : int
            The window.
        start : {"stationary", "initial"}
            As in :meth:`count_moments`.

        Returns
        -------
        numpy.ndarray
            Sums to 1 up to rounding; trailing counts of probability below 1e-300 are cut.
        """
        n = as_int("n_steps", n_steps, minimum=1)
        top = int(min(n, np.ceil(n * self.rate + 12.0 * np.sqrt(n * max(self.variance_rate, 1e-12)) + 12)))
        if self.n_states * n * (top + 1) > MAX_LAW_WORK:
            raise ValueError(
                f"n_steps = {n}: the exact count law needs about {self.n_states * n * top:.2g} operations "
                f"over {self.n_states} automaton states, more than {MAX_LAW_WORK:.0e}; count_moments gives "
                "its exact mean and variance"
            )
        f = np.zeros((self.n_states, top + 2))
        f[:, 0] = self._start(start)
        D0t, D1t = self.D0.T.tocsr(), self.D1.T.tocsr()
        for _ in range(n):
            moved = D1t @ f
            f = D0t @ f
            f[:, 1:] += moved[:, :-1]
            # Counts past `top` (12 standard deviations out) are lost to the last column's edge.
        law = f.sum(axis=0)
        law[np.abs(law) < 1e-300] = 0.0
        keep = np.flatnonzero(law)
        return np.asarray(law[: keep[-1] + 1] if keep.size else law[:1])


def flag_process(channel: ChannelLike, design: OnlineDesign, attack: object = None) -> FlagProcess:
    r"""The flag-ACKs that reach the sensor under ``attack``, as a Markov arrival process.

    Built on the exact engine's automaton (:meth:`fakeack.Scenario.automaton`) of the online
    ``design`` on ``channel`` under ``attack`` (any attack :class:`fakeack.Scenario` takes:
    blocking, forging, :class:`fakeack.MimicryAttack`, :class:`fakeack.AttackerAutomaton`).

    Parameters
    ----------
    channel : Channel or float
        The channel (a float: the paper's channel of that low-power arrival probability).
    design : OnlineDesign
        The online schedule.
    attack : optional
        The attack (None: none).

    Returns
    -------
    FlagProcess
        Its rate and variance rate, :math:`D_0`, :math:`D_1`, the stationary and the paper's
        initial law, and the exact count moments and law of a window.

    Raises
    ------
    ValueError, TypeError
        For a bad channel, design or attack (naming it), as :class:`fakeack.Scenario`.

    Examples
    --------
    >>> import fakeack as fa
    >>> fp = fa.flag_process(0.5, fa.OnlineDesign(2))
    >>> m, v = fa.flag_interval_moments(0.5, 2)
    >>> abs(fp.rate - 1 / m) < 1e-12 and abs(fp.variance_rate - v / m**3) < 1e-12
    True
    """
    ch = as_channel(channel, "channel")
    if not isinstance(design, OnlineDesign):
        raise TypeError(f"design must be a fakeack.OnlineDesign, got {type(design).__name__}")
    auto = Scenario(any_system(), ch, design, attack).automaton()
    parsed = [_LABEL.match(label) for label in auto.labels]
    if not all(parsed):
        raise RuntimeError("the engine's state labels changed; flag_process needs c=, z= and power=")
    high = np.array([m is not None and m.group(3) == "high" for m in parsed])
    K = (auto.K0 + auto.K1).tocsr()
    D1 = (K @ sp.diags(high.astype(np.float64))).tocsr()
    D0 = (K - D1).tocsr()
    D0.eliminate_zeros()
    D1.eliminate_zeros()
    pi = _stationary(K)
    d = np.asarray(D1.sum(axis=1)).ravel()
    rate = float(pi @ d)
    g = _poisson(K, d - rate, pi)
    variance_rate = rate * (1.0 - rate) + 2.0 * float((pi @ D1) @ g)
    # The engine explores from the paper's initial condition, whose states come first: high
    # power, memory restarted, the attacker at its start, one per channel state.
    initial = np.zeros(len(auto.labels))
    first = auto.labels[0].split(" attacker=")[-1] if " attacker=" in auto.labels[0] else None
    weights = ch.stationary
    for i, m in enumerate(parsed):
        assert m is not None
        same_attacker = first is None or auto.labels[i].endswith(f"attacker={first}")
        if m.group(3) != "high" or m.group(2) != "0" or not same_attacker:
            break
        initial[i] = weights[int(m.group(1))]
    initial /= initial.sum()
    return FlagProcess(
        ch, design, attack, rate, max(variance_rate, 0.0), D0, D1, pi, initial, tuple(auto.labels)
    )
