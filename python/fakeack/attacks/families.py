"""The attack families side by side: periodic blocking (the paper's, in its large-period worst
case), independent blocking and rate-matching injection, in cost and in energy."""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt

from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_probability, as_ratio, as_real
from ..model.schedules import OnlineDesign, design_online
from ..model.system import LinearSystem, compiled
from .chain import j_attack
from .kinds import Attack, FlagInjection, RandomBlocking
from .random import beta_bar_random, random_blocking_sweep, rate_matching_attack
from .rates import energy_per_step
from .threshold import j_attack_limit

__all__ = [
    "AttackFamilies",
    "attack_families",
    "OtherAttackRow",
    "other_attacks_table",
]


@dataclass(frozen=True)
class AttackFamilies:
    """J and energy per step against the budget β for each family (see :func:`attack_families`)."""

    beta: FloatArray
    """The budgets."""
    j_periodic: FloatArray
    """Periodic blocking, large-period worst case :math:`J_\\infty(\\beta)`."""
    j_random: FloatArray
    """Independent blocking with probability β."""
    j_rate_matching: FloatArray
    """Independent blocking hidden by forged flags (:func:`fakeack.rate_matching_attack`)."""
    energy_periodic: FloatArray
    energy_random: FloatArray
    energy_rate_matching: FloatArray
    j_offline: float
    j_online: float
    psi: float
    """The budget: energy per step of the unattacked online schedule."""


def attack_families(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    Delta: float,
    delta: float,
    betas: npt.ArrayLike | None = None,
) -> AttackFamilies:
    r"""J and energy per step of the three attack families at each budget β.

    The periodic family is the paper's attack in its large-period limit (the worst with budget β;
    :func:`fakeack.j_attack_limit`), whose energy follows from its delivered flag rate
    :math:`(1-\beta)/(\beta/f_{blk} + (1-\beta)/f_{on})`; the others are exact
    (:func:`fakeack.j_attack`, :func:`fakeack.energy_per_step`). The online schedule is
    :func:`fakeack.design_online` ``(lam, ratio)``.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio p/q.
    Delta, delta : float
        Energy of a high-power and a low-power transmission.
    betas : array_like, optional
        Budgets in [0, 1] (default 101 points).
    """
    core = compiled(system)
    lam_f, r = as_probability("lam", lam), as_ratio("ratio", ratio)
    hi, lo = as_real("Delta", Delta), as_real("delta", delta)
    design = design_online(lam, r)
    z0, mu = design
    b = np.linspace(0.0, 1.0, 101) if betas is None else np.asarray(betas, dtype=np.float64)
    j_per = np.array([j_attack_limit(system, lam_f, z0, x, mu) for x in b])
    j_rand = random_blocking_sweep(system, lam_f, z0, b, mu).j_attack
    matching = [rate_matching_attack(lam_f, z0, x, mu) for x in b]
    j_match = np.array([j_attack(system, lam_f, z0, mu=mu, attack=a) for a in matching])
    f_on, f_blk = _core_rates(lam_f, design)
    per_rate = np.array([_periodic_rate(x, f_on, f_blk) for x in b])
    e_per = lo + (hi - lo) * per_rate
    e_rand = np.array([energy_per_step(lam_f, z0, hi, lo, RandomBlocking(x), mu) for x in b])
    e_match = np.array([energy_per_step(lam_f, z0, hi, lo, a, mu) for a in matching])
    return AttackFamilies(
        b,
        j_per,
        j_rand,
        j_match,
        e_per,
        e_rand,
        e_match,
        core.j_offline(lam_f, r.numerator, r.denominator),
        core.j_online(lam_f, z0, mu),
        energy_per_step(lam_f, z0, hi, lo, None, mu),
    )


def _core_rates(lam: float, design: OnlineDesign) -> tuple[float, float]:
    from ..detection.flags import regime_rates

    return regime_rates(lam, design)


def _periodic_rate(beta: float, f_on: float, f_blk: float) -> float:
    """Delivered flags per step of the large-period attack: each regime for its share of flags."""
    if beta >= 1.0:
        return 0.0
    return (1.0 - beta) / (beta / f_blk + (1.0 - beta) / f_on)


@dataclass(frozen=True)
class OtherAttackRow:
    """One row of :func:`other_attacks_table`."""

    label: str
    j: float
    energy: float


def other_attacks_table(
    system: LinearSystem, lam: float, ratio: RatioLike, Delta: float, delta: float
) -> tuple[list[OtherAttackRow], float]:
    """J and energy per step under the other attacks at the paper's budgets, and the threshold
    against independent blocking (:func:`fakeack.beta_bar_random`).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability at low power.
    ratio : Fraction
        Energy ratio p/q; the online schedule is :func:`fakeack.design_online` ``(lam, ratio)``.
    Delta, delta : float
        Energy of a high-power and a low-power transmission.
    """
    lam_f, r = as_probability("lam", lam), as_ratio("ratio", ratio)
    z0, mu = design_online(lam, r)
    attacks: list[tuple[str, Attack]] = [
        ("random blocking beta=1/5", RandomBlocking(0.2)),
        ("random blocking beta=2/3", RandomBlocking(2 / 3)),
        ("injection gamma=0.1", FlagInjection(0.1)),
    ]
    matching = rate_matching_attack(lam_f, z0, Fraction(1, 5), mu)
    attacks.append((f"rate matching beta=1/5 (gamma={matching.gamma:.4f})", matching))
    rows = [
        OtherAttackRow(
            label,
            j_attack(system, lam_f, z0, mu=mu, attack=att),
            energy_per_step(lam_f, z0, Delta, delta, att, mu),
        )
        for label, att in attacks
    ]
    return rows, beta_bar_random(system, lam_f, r)
