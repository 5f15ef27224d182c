r"""The worst attack on the flag-ACKs: a linear program over the occupation measure of
:math:`(\min(\tau_k, T), e, a)`.

The attacker reads, at the end of every step, :math:`t = \min(\tau_k, T)` and the attack-free
state :math:`e = (c_k, n, \text{flag})` (:mod:`fakeack.optimal.state_policy`), and chooses the
sensor's next power :math:`a` (block a genuine flag-ACK: low; forge one on a quiet step: high).
Over :math:`x(t, e, a)`, the long-run frequency of (t, e, a), the worst attack within a blocking
budget :math:`\beta` solves

.. math::
   \max_x \sum_{t,e,a} x(t,e,a)\,\bar c_t \quad\text{s.t.}\quad
   \sum_{e \in \text{flag}} x(t,e,\text{low}) \le \beta \sum_{e \in \text{flag},a} x(t,e,a)
   \ \text{(summed over t)},

with the balance of the chain for :math:`t \ge 1`, the channel's stationary marginal and
:math:`x \ge 0`; :math:`\bar c_t = \mathrm{Tr}\,h^t(\bar P)` for t < T and an upper bound of
the cost of every :math:`\tau \ge T` at t = T (:func:`worst_attack`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._internal.types import FloatArray
from .._internal.validate import as_int, as_probability
from ..attacks.automata import AttackerAutomaton
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem, compiled
from ._attack_lp import attack_free_gaps, solve
from .power import FIRST_TAU, MAX_AUTO_TAU, MAX_TAU, TAIL_RTOL
from .state_policy import StatePolicy, automaton_cost, protocol_steps

__all__ = ["WorstAttack", "worst_attack", "INFORMATION", "STEALTH"]

#: The attackers' information :func:`worst_attack` knows.
INFORMATION = ("eavesdrop",)
#: The stealth constraints :func:`worst_attack` knows (None: no constraint).
STEALTH: tuple[str | None, ...] = (None, "support", "gap-law")


@dataclass(frozen=True)
class WorstAttack:
    r"""The worst attack within a blocking budget (see :func:`worst_attack`).

    Up to the LP's tolerance (about 1e-9 relative),
    ``j_lp - tail_bound <= j <= J* <= j_lp``, with :math:`J^\star` the supremum of J over every
    attacker within the budgets.
    """

    j: float
    """The exact long-run cost J under ``policy`` (attained)."""
    j_lp: float
    """The LP's optimal value: an upper bound on J under every attacker within the budgets
    (``j`` itself where the attack-free policy is the only one feasible, found without the LP:
    see :func:`worst_attack`)."""
    policy: StatePolicy
    """The optimal attacker (a flag row never visited repeats the next visited one; no forging
    where unvisited)."""
    blocked_fraction: float
    """The long-run fraction of the genuine flag-ACKs that ``policy`` blocks (at most beta)."""
    forged_fraction: float
    """The long-run fraction of quiet steps on which ``policy`` forges a flag-ACK."""
    tail_bound: float
    """A rigorous bound on ``j_lp - j`` from the truncation (see :func:`worst_attack`)."""
    tau_max: int
    """The truncation T: the policy's last row holds for every :math:`\\tau_k \\ge T`."""
    automaton: AttackerAutomaton | None
    """An attacker that sees only the genuine flag-ACKs and acts as ``policy`` (same J), when one
    exists: mu = 1, no forging and blocking independent of the channel state; else None."""
    received_gaps: FloatArray
    """The law of the gaps between the flag-ACKs the sensor receives under ``policy``: entry i is
    gap i + 1, the last entry every gap >= G (G = 1 without a stealth constraint: ``[1.0]``)."""


def worst_attack(
    system: LinearSystem,
    channel: ChannelLike,
    design: OnlineDesign,
    beta: float,
    *,
    information: str = "eavesdrop",
    forge_budget: float = 0.0,
    stealth: str | None = None,
    tau_max: int | None = None,
) -> WorstAttack:
    r"""The attack on the flag-ACKs of greatest long-run cost J within a blocking budget, by LP.

    **Model.** At the end of step k the remote detector has sent a genuine flag-ACK or not; the
    attacker, knowing :math:`\tau_k` (the holding time after step k), the channel state
    :math:`c_k`, the detector's zero count and whether a flag-ACK was sent
    (``information="eavesdrop"``, everything about the past that matters for the future),
    blocks the flag-ACK or, on a quiet step, forges one. In the long run it blocks at most a
    fraction ``beta`` of the genuine flag-ACKs and forges on at most a fraction ``forge_budget``
    of the quiet steps. With this information the (min(τ, T), e) chain is a controlled Markov
    chain, so the optimum is an LP over its occupation measure (module docstring), and its value
    bounds every attacker within the budgets, whatever it sees.

    **Stealth.** With d in the state, the gap law is linear in the occupation measure. It is
    imposed through the attack-free hazards :math:`h_l = \Pr[\text{gap} = l \mid \text{gap}
    \ge l]`: with :math:`R_l` the long-run rate of received gaps that reach length l, the rate
    of deliveries at gap l is :math:`h_l R_l`, and :math:`R_1` is the attack-free flag rate
    (equivalent to the law :math:`p_l = h_l \prod_{i<l}(1 - h_i)` at that rate, with
    coefficients of order 1 however small :math:`p_l`). A test on the marginal law of the gaps
    cannot see such an attacker; a test on the correlation of consecutive gaps still may, since
    the optimum's gaps need not be independent (mimicry's are: it runs a copy of the
    attack-free protocol).

    **Gap law without forging.** With ``forge_budget=0`` every flag-ACK received is a genuine
    one. On an i.i.d. channel each genuine flag-ACK leaves the protocol in the same state (the
    detector's count restarts), so a received gap is an attack-free gap plus, for each
    flag-ACK blocked in it, the steps to the next genuine one (at least one): blocking any
    positive fraction makes the mean received gap longer than the attack-free mean, and the
    received rate lower than the attack-free one. The attack-free policy is then the only
    attacker within the budgets; it is returned without the LP (``j_lp = j`` = J_on,
    ``tail_bound = 0``). On a Markov channel the LP decides.

    **Scaling.** The masses fall like :math:`g^t` (g the channel's largest loss probability)
    while the traces grow like :math:`\rho(A)^{2t}` (1e32 at t = 200 on the paper's example). The
    LP is solved in :math:`y(t,\cdot) = x(t,\cdot)/s^t`, :math:`s = \sqrt{g/\rho(A)^2}`, so
    that scaled masses and scaled costs both fall like :math:`(g\rho(A)^2)^{t/2}`, with
    cumulative variables :math:`\sigma_t = (\dots)_t + s\,\sigma_{t+1}` for the sums over all t
    (normalisation, budgets), as in :func:`fakeack.optimal_power_policy`. Under the gap law the
    policy is read off the masses at gap d relative to the attack-free tail
    :math:`\Pr[\text{gap} > d]` (the mass the law puts there), down to the truncation; the
    solver's tolerances (1e-10) are absolute, so the received law is met to about 1e-9 in the
    worst case (within 1e-15 on the paper's example at T = 200). Where HiGHS fails on the
    program, it is solved again with the columns and rows at gap d scaled by that tail (the
    same program, on which HiGHS's factorisations take other paths).

    **The tail bound, on the safe side.** For a maximisation the truncation must not lower the
    LP's value: the aggregated state t = T is costed at an upper bound of what every
    :math:`\tau \ge T` costs. In the long run, whatever the attacker does,
    :math:`\Pr[\tau_k \ge T + j] \le m_T g^j` (each of j further losses has conditional
    probability at most g), :math:`m_T = \Pr[\tau_k \ge T]`, and :math:`\mathrm{tr}_i` grows, so
    :math:`E[\mathrm{tr}_\tau; \tau \ge T] \le m_T(\mathrm{tr}_T + g\,\mathrm{Tr}\,W)`,
    :math:`W = g A W A' + h(X) - X`, :math:`X = h^T(\bar P)` (Abel summation; the increments
    are :math:`\mathrm{Tr}\,A^{j-1}(h(X)-X)A'^{j-1} \ge 0`). Every attacker's aggregated
    measure is feasible, so ``j_lp`` is an upper bound on the optimum :math:`J^\star`; the
    optimal policy's exact J is at least its LP cost with the tail term removed, and
    :math:`m_T \le g^T` (T losses in a row), so
    ``j_lp - tail_bound <= j <= J* <= j_lp`` with ``tail_bound`` :math:`= g^T g\,\mathrm{Tr}\,W`,
    a bound that holds for every attacker and falls like :math:`(g\rho(A)^2)^T`.

    Parameters
    ----------
    system : LinearSystem
        The process and its sensor.
    channel : Channel or float
        The packet channel (a float: the paper's low-power arrival probability, high power
        always arriving).
    design : OnlineDesign
        The online schedule's remote detector (z0, mu).
    beta : float
        Largest long-run fraction of the genuine flag-ACKs blocked, in [0, 1].
    information : {"eavesdrop"}, keyword-only, optional
        What the attacker sees: ``"eavesdrop"``, the holding time and the detector's state.
    forge_budget : float, keyword-only, optional
        Largest long-run fraction of quiet steps with a forged flag-ACK, in [0, 1] (default 0).
    stealth : {None, "support", "gap-law"}, keyword-only, optional
        What the flag-ACKs the sensor receives must look like. None: anything. ``"support"``:
        no gap between two received flag-ACKs shorter than the shortest attack-free gap.
        ``"gap-law"``: the gaps' marginal law is the attack-free one (each gap length up to
        the length where the attack-free tail falls below 1e-12, the longer ones together) and
        they come at the attack-free rate. Both put d, the steps since the last flag-ACK
        received (capped at the constraint's length), in the LP's state, and the optimum reads
        it; a truncated law is a relaxation, so ``j_lp`` still bounds every attacker whose
        received gaps have exactly the attack-free law.
    tau_max : int, keyword-only, optional
        The truncation T (1 to 4096); None: 64, doubled until ``tail_bound`` is at most 1e-12
        of ``j`` (ValueError past 1024).

    Returns
    -------
    WorstAttack

    Raises
    ------
    TypeError, ValueError
        Naming ``beta`` or ``forge_budget`` outside [0, 1] (``forge_budget`` also when HiGHS
        finds no attacker within the budgets that meets the stealth constraint), ``information`` or
        ``stealth`` not known, ``design`` not an OnlineDesign, ``tau_max``; naming ``channel``
        when its largest loss probability g has :math:`g\rho(A)^2 \ge 1` (an attacker can then
        make J infinite, or nearly so, and the tail bound is infinite).
    ConvergenceError
        If HiGHS does not solve the LP.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> w = worst_attack(s, 0.5, fa.OnlineDesign(2), 0.5, tau_max=100)
    >>> str(w.policy)
    'tau 1-2: block 0.428571; tau >= 3: block'
    >>> abs(w.j / fa.j_attack_limit(s, 0.5, 2, 0.5) - 1) < 1e-9  # consecutive blocking's limit
    True
    >>> w.j_lp - w.tail_bound <= w.j * (1 + 1e-9) and w.j <= w.j_lp * (1 + 1e-9)
    True
    """
    compiled(system)
    ch = as_channel(channel, "channel")
    if not isinstance(design, OnlineDesign):
        raise TypeError(f"design must be an OnlineDesign, got {type(design).__name__}")
    b = as_probability("beta", beta, closed=True)
    phi = as_probability("forge_budget", forge_budget, closed=True)
    if not isinstance(information, str) or information not in INFORMATION:
        raise ValueError(f"information must be one of {INFORMATION}, got {information!r}")
    if stealth not in STEALTH:
        raise ValueError(f"stealth must be one of {STEALTH}, got {stealth!r}")
    g = float(np.max(1.0 - np.minimum(ch.low, ch.high)))
    if g * system.spectral_radius**2 >= 1.0:
        raise ValueError(
            f"channel: its largest loss probability {g:.6g} times rho(A)^2 = {system.spectral_radius**2:.6g} "
            "is at least 1: an attacker who keeps the power low can make J infinite or unbounded"
        )
    if tau_max is not None:
        T = as_int("tau_max", tau_max, minimum=1, maximum=MAX_TAU)
        return _solve(system, ch, design, (b, phi), g, T, stealth)
    T = FIRST_TAU
    while True:
        res = _solve(system, ch, design, (b, phi), g, T, stealth)
        if res.tail_bound <= TAIL_RTOL * res.j:
            return res
        if 2 * T > MAX_AUTO_TAU:
            raise ValueError(
                f"tau_max: the tail beyond tau = {T} is not negligible (bound {res.tail_bound:.3g} against "
                f"J = {res.j:.6g}); give tau_max to accept a truncated answer with its tail_bound"
            )
        T *= 2


def _solve(
    system: LinearSystem,
    ch: Channel,
    design: OnlineDesign,
    budgets: tuple[float, float],
    g: float,
    T: int,
    stealth: str | None,
) -> WorstAttack:
    steps = protocol_steps(ch, design)
    gaps = attack_free_gaps(steps) if stealth == "gap-law" else None
    if gaps is not None and budgets[1] == 0.0 and ch.n_states == 1:
        # Only the attack-free policy is feasible (worst_attack's docstring): no LP.
        free = StatePolicy(np.zeros(T + 1))
        aut = free.automaton(ch, design)
        j = automaton_cost(system, aut)
        return WorstAttack(j, j, free, 0.0, 0.0, 0.0, T, free.flag_automaton(design), gaps[0])
    min_gap = int(np.flatnonzero(attack_free_gaps(steps)[0])[0]) + 1 if stealth == "support" else 1
    sol = solve(system, ch, steps, budgets, g, T, gaps, min_gap)
    aut = sol.policy.automaton(ch, design)
    j = automaton_cost(system, aut)
    return WorstAttack(
        float(j),
        sol.j_lp,
        sol.policy,
        aut.blocked_fraction,
        aut.forged_fraction,
        sol.tail_bound,
        T,
        sol.policy.flag_automaton(design),
        aut.received_gaps,
    )
