"""Simulated detection rates: windows of the real protocol with the sensor's test in the loop
(the compiled game kernel with fall-back switched off), which check the formulas of
:mod:`fakeack.detection.probability`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _fakeack
from .._internal.types import FloatArray
from .._internal.validate import as_int, as_probability
from ..attacks.automata import AttackerAutomaton, MimicryAttack
from ..attacks.kinds import AttackLike
from ..model.channels import BernoulliChannel
from ..model.schedules import OnlineDesign, check_online
from ..montecarlo._automaton import SimAttack, as_sim_attack, kernel_attack
from .count import alarm_bounds
from .flags import delivered_flag_rate, estimate_beta, flag_rates
from .interval_test import cached_interval_test
from .likelihood import DEFAULT_ALTERNATIVE, likelihood_ratio_test, lr_tables
from .probability import KernelTest, check_test

__all__ = [
    "DetectionRates",
    "detection_rates",
    "simulate_windows",
]


def paper_min_gap(design: OnlineDesign) -> int:
    """The shortest gap between two flag-ACKs reaching the sensor without attack on the paper's
    channel, where a high-power packet always arrives (:attr:`fakeack.FlagProcess.min_gap` in
    closed form): z0 + 1, or z0 + 2 when mu = 0 (every flag then waits for z0 + 1 losses)."""
    return int(design.z0) + (1 if design.mu > 0 else 2)


def simulate_windows(
    lam: float,
    design: OnlineDesign,
    attack: SimAttack | None,
    n: int,
    runs: int,
    seed: int,
    test: str,
    alpha: float,
    alternative: str,
    burn_in: int,
    progress: bool | None = False,
    *,
    support: bool = True,
    lr_alternative: object = None,
) -> tuple[FloatArray, FloatArray]:
    """Alarms (0/1) and delivered flag-ACKs of ``runs`` simulated windows of ``n`` steps, one per run,
    after ``burn_in`` untested steps, by the closed-loop kernel (the sensor never falls back).
    ``support``: the window alarms at the support check too (the gap across its start counts);
    ``test="support"`` is the support check alone; ``test="lr"`` the likelihood-ratio test against
    ``lr_alternative``, its own support check included. Any attacker automaton plays move by move (a
    mimicry attacker without its own channel or design runs ``lam`` and ``design``)."""
    from .._internal.progress import Progress
    from .flags import any_system

    lr = None
    if test == "support":
        args: KernelTest = ("count", -1, n + 1, [], [], 0.0, None, 0)  # a count test that never alarms
        support = True
    elif test == "lr":
        alt = DEFAULT_ALTERNATIVE if lr_alternative is None else lr_alternative
        t_lr = likelihood_ratio_test(lam, design.z0, n, alpha, design.mu, alternative=alt)
        args = ("lr", -1, 0, [], [], t_lr.critical, None, 0)
        lr = lr_tables(t_lr)
        support = False  # the statistic's +inf increments are its support check
    elif test == "count":
        lo, hi = alarm_bounds(lam, design, n, alpha, alternative)
        args = ("count", lo, hi, [], [], 0.0, None, 0)
    else:
        t = cached_interval_test(lam, design, n, alpha)
        args = (
            "interval",
            -1,
            0,
            [int(e) for e in t.edges],
            [float(e) for e in t.expected],
            float(t.critical),
            None,
            0,
        )
    core, automaton = kernel_attack(attack, BernoulliChannel(lam), design)
    bar = Progress(runs, progress)
    burn_in = -(-burn_in // n) * n  # whole windows, so that the measured window is one window
    try:
        out = _fakeack.simulate_game(
            any_system()._core,
            lam,
            1,
            2,
            design.z0,
            design.mu,
            core,
            *args,
            n,
            n,
            burn_in,
            runs,
            seed,
            bar,
            min_gap=paper_min_gap(design) if support else 0,
            automaton=automaton,
            lr=lr,
        )
    finally:
        bar.close()
    return out["alarms"], out["delivered"]


@dataclass(frozen=True)
class DetectionRates:
    """Simulated performance of the sensor's tests (see :func:`detection_rates`)."""

    false_alarm: float
    """Fraction of attack-free windows flagged as attacked (should be close to alpha)."""
    detection: float
    """Fraction of attacked windows flagged."""
    beta_hat_mean: float
    """Mean of :func:`estimate_beta` over the attacked windows; NaN (as ``beta_hat_std``) for a
    window in which fewer than one flag-ACK is expected without attack, where it is undefined."""
    beta_hat_std: float
    beta: float
    """The attack's budget (the blocking part's, for an injection; for an attacker automaton, the
    long-run fraction of the genuine flag-ACKs it blocks)."""
    runs: int
    n_steps: int
    alpha: float
    false_alarm_stderr: float = math.nan
    detection_stderr: float = math.nan
    test: str = "count"
    alternative: str = "less"
    burn_in: int = 0
    """Steps simulated before each window (by default the automaton's mixing time)."""
    support: bool = True
    """Whether the windows alarmed at the support check too (always, for ``test="support"``)."""


def detection_rates(
    lam: float,
    z0: int,
    attack: AttackLike | MimicryAttack | AttackerAutomaton,
    n_steps: int = 1000,
    runs: int = 2000,
    mu: float = 1.0,
    alpha: float = 0.01,
    seed: int = 1,
    test: str = "count",
    alternative: str | None = None,
    burn_in: int | None = None,
    support: bool = True,
    *,
    lr_alternative: object = None,
) -> DetectionRates:
    """False-alarm and detection rates of the sensor's tests by Monte Carlo of the protocol.

    Simulates ``runs`` attack-free and ``runs`` attacked observation windows of ``n_steps`` steps
    (one window per run, after ``burn_in`` steps; the flag process does not depend on the plant)
    with the closed-loop kernel of :func:`fakeack.simulate_game`, and applies the test to
    each: the count test of :func:`detect_attack`, the interval test of
    :func:`fakeack.detect_intervals` or the likelihood-ratio test of
    :func:`fakeack.likelihood_ratio_test`, with their exact alarm regions. The default burn-in puts
    the window in the stationary regime that :func:`fakeack.detection_probability` describes;
    with ``burn_in=0`` every window starts from the paper's initial condition. Forged flag-ACKs
    (:class:`fakeack.FlagInjection`) count as delivered: the sensor cannot tell them from genuine
    ones, which is how :func:`fakeack.rate_matching_attack` hides from the count test, though not
    from the support check (``support``), which sees a flag-ACK sooner after the previous one than
    any can without attack: a window alarms when its test or the check does.

    Parameters
    ----------
    lam : float
        Arrival probability at low power.
    z0 : int
        Memory length of the event detector.
    attack : attack, (r, t) or str
        The attack to detect: :class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`,
        :class:`fakeack.RandomBlocking` or :class:`fakeack.FlagInjection` (its ``beta`` is that of
        its blocking part), or a spelling such as ``"1/5"`` or ``"inject:0.04+random:0.2"``; or
        any attacker automaton, played move by move: :class:`fakeack.MimicryAttack` (without its
        own channel or design, the simulated ones: the sensor then sees the attack-free flag
        law), :class:`fakeack.AttackerAutomaton`.
    n_steps : int, optional
        Observation window in steps (default 1000).
    runs : int, optional
        Windows simulated with and without the attack (default 2000).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    alpha : float, optional
        Level of the test (default 0.01).
    seed : int, optional
        Seed of the attack-free windows (the attacked ones use seed + 1).
    test : {"count", "interval", "lr", "support"}, optional
        The test (default the count test); ``"support"`` is the support check alone, as in
        :func:`fakeack.detection_probability`; ``"lr"`` the likelihood-ratio test against
        ``lr_alternative``, whose +inf increments are its support check (``support`` must then
        be left True: the check is part of the statistic).
    alternative : {"less", "greater", "two-sided"}, optional
        The count test's alternative (default "less", as :func:`detect_attack`); the interval test
        and the support check are two-sided (the default for them, and the only value they take).
    burn_in : int, optional
        Steps simulated before each window, rounded up to whole windows. The default is the
        automaton's mixing time (:meth:`fakeack.FlagProcess.mixing_steps`, to 1e-3 in total
        variation, under the attack and without it, whichever is longer): a periodic attack's
        phase can take 10^4 steps to mix. The result's ``burn_in`` states the value used.
    support : bool, optional
        Whether a window also alarms at the support check: a flag-ACK reaching the sensor fewer
        than z0 + 1 steps (z0 + 2 at mu = 0) after the previous one, which may lie before the
        window (default True). It never alarms without attack, nor under blocking alone.
    lr_alternative : RandomBlocking, FlagInjection or array_like, optional
        The attack the likelihood-ratio test is tuned to (``test="lr"`` only; default
        ``RandomBlocking(0.2)``).

    Returns
    -------
    DetectionRates
    """
    from .count import check_alternative

    lam, design = check_online(lam, z0, mu)
    att = as_sim_attack(attack)
    if att is None:
        raise ValueError("attack: give the attack whose detection rate you want, e.g. (1, 5)")
    n = as_int("n_steps", n_steps, minimum=1)
    runs = as_int("runs", runs, minimum=2, maximum=1 << 24)
    alpha = as_probability("alpha", alpha)
    seed = as_int("seed", seed, minimum=0, maximum=2**63)
    if test in ("support", "lr"):
        if not support:
            raise ValueError(f"support: test={test!r} includes the support check; it cannot be off")
    else:
        test = check_test(test)
    if lr_alternative is not None and test != "lr":
        raise ValueError(f"lr_alternative: only with test='lr', got test={test!r}")
    if alternative is None:
        alternative = "less" if test == "count" else "two-sided"
    alternative = check_alternative(alternative)
    if test != "count" and alternative != "two-sided":
        raise ValueError(f"alternative: the {test} test is two-sided by construction")
    if burn_in is None:
        from .process import flag_process

        burn_in = max(flag_process(lam, design, a).mixing_steps() for a in (None, att))
    burn_in = as_int("burn_in", burn_in, minimum=0)
    flagged: dict[str, float] = {}
    se: dict[str, float] = {}
    delivered = np.zeros(0)  # the attacked windows' counts, from the loop's last run
    for name, a, sd in (("clean", None, seed), ("attacked", att, seed + 1)):
        alarms, counts = simulate_windows(
            lam,
            design,
            a,
            n,
            runs,
            sd,
            test,
            alpha,
            alternative,
            burn_in,
            support=support,
            lr_alternative=lr_alternative,
        )
        p = float(np.mean(alarms))
        flagged[name], se[name] = p, math.sqrt(max(p * (1 - p), 0.0) / runs)
        delivered = counts
    beta_mean = beta_std = math.nan  # a window too short to estimate beta (documented)
    if n * delivered_flag_rate(lam, design.z0, None, design.mu) >= 1.0 - 1e-12:
        betas = np.array([estimate_beta(int(c), n, lam, design.z0, design.mu) for c in delivered])
        beta_mean, beta_std = float(betas.mean()), float(betas.std(ddof=1))
    if isinstance(att, (MimicryAttack, AttackerAutomaton)):
        rates = flag_rates(lam, design.z0, att, design.mu)
        beta = float(rates.blocked / rates.sent)
    else:
        beta = float(att.beta)
    return DetectionRates(
        flagged["clean"],
        flagged["attacked"],
        beta_mean,
        beta_std,
        beta,
        runs,
        n,
        alpha,
        se["clean"],
        se["attacked"],
        test,
        alternative,
        burn_in,
        bool(support),
    )
