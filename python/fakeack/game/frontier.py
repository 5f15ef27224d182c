"""The stealthy frontier: the most damaging attack of a family that a test sees rarely enough."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._internal.progress import Progress
from .._internal.types import FloatArray
from .._internal.validate import as_int, as_probability, as_real
from ..attacks.automata import AttackerAutomaton, MimicryAttack, discard_forgeries
from ..attacks.chain import j_attack
from ..attacks.kinds import Attack, FlagInjection, PeriodicBlocking, RandomBlocking
from ..attacks.random import rate_matching_attack
from ..attacks.rates import high_power_rate
from ..detection.count import check_alternative
from ..detection.likelihood import DEFAULT_ALTERNATIVE, likelihood_ratio_test
from ..detection.probability import (
    check_test,
    detection_probability,
    forges,
)
from ..model.schedules import OnlineDesign, check_online
from ..model.system import LinearSystem, compiled

__all__ = [
    "FAMILIES",
    "StealthyFrontier",
    "stealthy_frontier",
]


#: The attack families searched.
FAMILIES = ("periodic", "random", "random+inject", "careful", "mimicry")


@dataclass(frozen=True)
class StealthyFrontier:
    """The result of :func:`stealthy_frontier`."""

    attack: Attack | MimicryAttack | None
    """The attack of the family with the largest J whose detection probability per window is at
    most ``max_detection`` (``None`` if even no attack is detected more often, i.e. max_detection
    below the false-alarm rate)."""
    j: float
    """Its J (stationary, online)."""
    high_power_rate: float
    """Its fraction of steps at high power."""
    detection: float
    """Its detection probability per window."""
    frontier: tuple[FloatArray, FloatArray]
    """(detection, J) of the family's Pareto frontier (no other attack has higher J at lower
    detection), sorted by detection: J against detection probability, for plotting."""
    frontier_attacks: list[Attack | MimicryAttack]
    """The attacks on the frontier, in the same order."""
    candidates: tuple[FloatArray, FloatArray]
    """(detection, J) of every attack searched."""
    family: str
    test: str
    n_steps: int
    alpha: float
    max_detection: float
    j_online: float


def _candidates(
    family: str, lam: float, design: OnlineDesign, t_max: int, grid: int
) -> list[Attack | MimicryAttack]:
    if family == "mimicry":
        return [MimicryAttack()]
    if family == "periodic":
        return [PeriodicBlocking(r, t) for t in range(1, t_max + 1) for r in range(t)]
    betas = np.linspace(0.0, 1.0, grid)
    if family == "random":
        return [RandomBlocking(b) for b in betas]
    out: list[Attack | MimicryAttack] = []
    # A grid of (beta, gamma) and the rate-matching curve through it; the careful forger keeps
    # every gap at least z0 + 1 (the support check's minimum) on a coarser grid, each of its
    # points costing a pass over the engine's automaton.
    careful = family == "careful"
    gap = design.z0 + 1 if careful else 1
    gammas = np.linspace(0.0, 0.2, 6 if careful else (grid + 1) // 2)
    for b in betas[:-1]:
        for g in gammas:
            out.append(FlagInjection(g, RandomBlocking(b), min_gap=gap))
        out.append(rate_matching_attack(lam, design.z0, b, design.mu, min_gap=gap))
    return out


def stealthy_frontier(
    system: LinearSystem,
    lam: float,
    z0: int,
    n_steps: int,
    alpha: float,
    test: str,
    family: str,
    max_detection: float,
    t_max: int = 60,
    mu: float = 1.0,
    *,
    alternative: str = "two-sided",
    grid: int = 41,
    authenticated: bool = False,
    support: bool = True,
    lr_alternative: object = None,
    progress: bool | None = None,
) -> StealthyFrontier:
    r"""The attack of a family that maximises J subject to a detection probability per window of at
    most ``max_detection``.

    Every attack of the family is scored by its exact stationary J (:func:`fakeack.j_attack`) and
    its detection probability (:func:`fakeack.detection_probability`, a window of ``n_steps`` at
    level ``alpha``, with the support check beside the test unless ``support=False``); the best
    admissible one is returned with the family's Pareto frontier. With the check, the
    ``"random+inject"`` family's forgers, which ignore the attack-free gaps, are seen in most
    windows, and the careful ones (``"careful"``, ``"mimicry"``) are what remains.

    Families: ``"periodic"``, every :class:`fakeack.PeriodicBlocking` ``(r, t)`` with
    ``t <= t_max`` (pairs not in lowest terms included: they block longer runs);
    ``"random"``, :class:`fakeack.RandomBlocking` on a grid of ``grid`` budgets in [0, 1];
    ``"random+inject"``, :class:`fakeack.FlagInjection` with independent blocking on a grid of
    budgets β and forging probabilities γ in [0, 0.2], plus the rate-matching attack
    (:func:`fakeack.rate_matching_attack`) at each β; ``"careful"``, the same forger respecting
    the support check (``min_gap = z0 + 1``, six γ per β, and its rate-matching curve, scored on
    the flag process of the engine's automaton); ``"mimicry"``, :class:`fakeack.MimicryAttack`,
    whose flag law is the attack-free one, so its detection probability is the test's
    false-alarm rate.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    n_steps : int
        Window length in steps.
    alpha : float
        The test's false-alarm level, in (0, 1).
    test : {"count", "interval", "lr"}
        The sensor's test; ``"lr"`` is the likelihood-ratio test against ``lr_alternative``
        (:func:`fakeack.likelihood_ratio_test`), whose +inf increments are its support check.
    family : {"periodic", "random", "random+inject", "careful", "mimicry"}
        The attacks searched.
    max_detection : float
        Largest admissible detection probability per window, in [0, 1].
    t_max : int, optional
        Longest period of the periodic family (default 60).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    alternative : str, optional
        The count test's alternative (default two-sided).
    grid : int, optional
        Budgets in the random families' grids (default 41).
    authenticated : bool, optional
        Whether the sensor authenticates flag-ACKs, rejecting forged ones (default False): each
        attack is then scored by its blocking part (``fakeack.attacks.discard_forgeries``), so a
        forger gains nothing from forging.
    support : bool, optional
        Whether the sensor runs the support check beside its test (default True), as
        :func:`fakeack.detection_probability` combines them (the likelihood-ratio test always
        has it).
    lr_alternative : RandomBlocking, FlagInjection or array_like, optional
        The attack the likelihood-ratio test is tuned to (``test="lr"`` only; default
        ``RandomBlocking(0.2)``).
    progress : bool, optional
        A progress bar over the attacks for the likelihood-ratio test, whose law takes about a
        second per attack at 1000 steps (default: when run interactively and longer than a
        second).

    Returns
    -------
    StealthyFrontier
    """
    compiled(system)
    lam, design = check_online(lam, z0, mu)
    z0, mu = design
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    alpha = as_probability("alpha", alpha)
    test = "lr" if test == "lr" else check_test(test)
    if lr_alternative is not None and test != "lr":
        raise ValueError(f"lr_alternative: only with test='lr', got test={test!r}")
    alternative = check_alternative(alternative) if test == "count" else "two-sided"
    if family not in FAMILIES:
        raise ValueError(f"family must be one of {FAMILIES}, got {family!r}")
    bound = as_real("max_detection", max_detection)
    if not 0.0 <= bound <= 1.0:
        raise ValueError(f"max_detection must lie in [0, 1], got {bound}")
    t_max = as_int("t_max", t_max, minimum=1, maximum=500)
    grid = as_int("grid", grid, minimum=2, maximum=1001)
    attacks = _candidates(family, lam, design, t_max, grid)
    for name, flag in (("authenticated", authenticated), ("support", support)):
        if not isinstance(flag, bool):
            raise TypeError(f"{name} must be True or False, got {flag!r}")
    played = [discard_forgeries(a, channel=lam, design=design) if authenticated else a for a in attacks]
    j = np.array([j_attack(system, lam, z0, mu=mu, attack=a) for a in played])
    # Mimicry delivers exactly the attack-free flag process, so every flag-timing test sees it
    # at its false-alarm rate.
    timed = [None if isinstance(a, MimicryAttack) else a for a in played]
    if test == "lr":  # one test, its law under each attack; the support check is in the statistic
        tuned = DEFAULT_ALTERNATIVE if lr_alternative is None else lr_alternative
        lr = likelihood_ratio_test(lam, z0, n, alpha, mu, alternative=tuned)
        bar = Progress(len(timed), progress, desc="fakeack stealthy_frontier", unit="attack")
        try:
            found = []
            for a in timed:
                found.append(lr.detection_probability(a))
                bar(len(found))
            d = np.array(found)
        finally:
            bar.close()
    else:
        d = np.array(
            [detection_probability(lam, z0, a, n, alpha, test, alternative, mu, support=False) for a in timed]
        )
    if support and test != "lr":
        d = _with_support(lam, design, n, alpha, test, alternative, timed, d)
    j_on = j_attack(system, lam, z0, mu=mu, attack=PeriodicBlocking(0, 1))
    # Pareto frontier: by detection (ties: larger J first), keep each new maximum of J.
    order = np.lexsort((-j, d))
    front: list[int] = []
    best = -np.inf
    for i in order:
        if j[i] > best:
            front.append(i)
            best = j[i]
    ok = np.flatnonzero(d <= bound)
    if ok.size:
        i = int(ok[np.argmax(j[ok])])
        att, ji, di = attacks[i], float(j[i]), float(d[i])
        hp = high_power_rate(lam, z0, played[i], mu)
    else:
        att, ji, di, hp = None, float("nan"), float("nan"), float("nan")
    return StealthyFrontier(
        att,
        ji,
        hp,
        di,
        (d[front], j[front]),
        [attacks[i] for i in front],
        (d, j),
        family,
        test,
        n,
        alpha,
        bound,
        j_on,
    )


def _with_support(
    lam: float,
    design: OnlineDesign,
    n: int,
    alpha: float,
    test: str,
    alternative: str,
    attacks: list[Attack | AttackerAutomaton | None],
    alone: FloatArray,
) -> FloatArray:
    """The detection probabilities with the support check beside the test (only forgery shortens
    a gap, so the rest keep the test's own)."""
    d = alone.copy()
    for i, a in enumerate(attacks):
        if forges(a, False):
            d[i] = detection_probability(lam, design.z0, a, n, alpha, test, alternative, design.mu)
    return d
