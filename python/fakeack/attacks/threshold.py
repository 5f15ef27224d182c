"""The attacker threshold: β sweeps, β̄, the sensor's decision, general attack patterns."""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt

from .._internal.types import FloatArray, IntArray, RatioLike
from .._internal.validate import as_fraction, as_int, as_probability, as_ratio
from ..model.schedules import OnlineDesign, design_online
from ..model.system import LinearSystem, compiled
from .chain import j_attack
from .kinds import MaskBlocking

__all__ = [
    "j_attack_pattern",
    "j_attack_limit",
    "BetaSweep",
    "beta_sweep",
    "BetaBar",
    "beta_bar",
    "Decision",
    "choose_schedule",
    "MaskSearch",
    "worst_mask",
]


def _t_max(t_max: int) -> int:
    return as_int("t_max", t_max, minimum=2)


def j_attack_pattern(
    system: LinearSystem, lam: float, z0: int, mask: npt.ArrayLike, mu: float = 1.0
) -> float:
    r"""Cost under any periodic blocking pattern of the attacker's flag counter.

    Generalises Algorithm 1: ``mask[sigma] == 1`` blocks the flag-ACK counted ``sigma`` in each
    period of ``len(mask)`` flags (``[1]*r + [0]*(t-r)`` is the paper's "first r of t").

    The renewal form: after each arrival the memory walk flags before the next arrival with
    probability :math:`u = a^{z_0}(\mu + (1-\mu)a)`; k blocked flags in a row put it in segment k.
    Balancing the flag rate over counter levels gives
    :math:`J = \sum_\sigma\sum_k \tilde c_{\sigma-k} W_k / \sum_\sigma\sum_k \tilde c_{\sigma-k} M_k`,
    where :math:`\tilde c_j = 1-u` if the flag before level j is blocked, else 1, and
    :math:`W_k` (:math:`M_k`) sums :math:`a^\tau\mathrm{Tr}\,h^\tau(\bar P)` (:math:`a^\tau`) over
    segment k (README, model notes). Checked against :func:`fakeack.general_attack_chain`.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length.
    mask : sequence of 0/1
        One period of the blocking pattern; not all ones (that is :func:`fakeack.j_max`).
    mu : float, optional
        Probability of the z0-bit memory at each step.
    """
    return j_attack(system, lam, z0, mu=mu, attack=MaskBlocking(mask))


def j_attack_limit(
    system: LinearSystem, lam: float, z0: int, beta: float | Fraction, mu: float = 1.0
) -> float:
    r"""Cost in the large-period limit :math:`r, t \to \infty`, :math:`r/t \to \beta`.

    The attacker blocks long runs of flags; the process alternates between the all-blocked regime
    (cost :math:`J_{\max}`, flag rate :math:`f_{\mathrm{blk}} = \lambda u/(1-u)`) and the unattacked
    one (cost :math:`J_{\mathrm{on}}`, flag rate :math:`f_{\mathrm{on}}`), each for a share of the
    flags, so each for a share of time proportional to flags over rate:

    .. math::
       J_\infty(\beta) = \frac{\beta J_{\max}/f_{\mathrm{blk}} + (1-\beta) J_{\mathrm{on}}/f_{\mathrm{on}}}
                              {\beta/f_{\mathrm{blk}} + (1-\beta)/f_{\mathrm{on}}}.

    This is the supremum of :math:`J(kr, kt)` over repetitions k of a pattern with budget β, so it
    is the worst an attacker with budget β can do with the paper's consecutive pattern.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability at low power.
    z0 : int
        Memory length.
    beta : float or Fraction
        Attacker budget :math:`\beta \in [0, 1]`.
    mu : float, optional
        Probability of the z0-bit memory at each step.

    Returns
    -------
    float
        ``inf`` for :math:`\beta > 0` when :math:`J_{\max}` is infinite.
    """
    core = compiled(system)
    lam = as_probability("lam", lam)
    z0 = as_int("z0", z0, minimum=1)
    mu = as_probability("mu", mu, closed=True)
    b = as_probability("beta", float(as_fraction("beta", beta)), closed=True)
    return core.j_attack_limit(lam, z0, mu, b)


@dataclass(frozen=True)
class BetaSweep:
    """:math:`J(\\tilde\\theta_{on})` at every β = r/t in lowest terms, t <= t_max, sorted by β."""

    r: npt.NDArray[np.uint32]
    """Blocked flag-ACKs per period (uint32)."""
    t: npt.NDArray[np.uint32]
    """Period in flag-ACKs (uint32)."""
    beta: FloatArray
    """r / t."""
    j_attack: FloatArray
    """Attacked cost at each fraction (``inf``, never NaN, where it exceeds the double range)."""
    j_offline: float
    """Cost of the optimal offline schedule at the same energy."""
    j_online: float
    """Unattacked online cost."""
    z0: int
    mu: float
    lam: float
    ratio: Fraction

    def __len__(self) -> int:
        return len(self.r)

    def __repr__(self) -> str:
        return (
            f"BetaSweep({len(self)} fractions r/t with t <= {int(self.t.max()) if len(self) else 0}, "
            f"J_online={self.j_online:.6g}, J_offline={self.j_offline:.6g}, z0={self.z0}, mu={self.mu:g})"
        )

    def _repr_html_(self) -> str:
        from .._internal import html as _html

        above = self.j_attack >= self.j_offline
        first = f"{self.r[above][0]}/{self.t[above][0]}" if above.any() else None
        return _html.key_values(
            "BetaSweep",
            [
                ("fractions r/t (lowest terms)", len(self)),
                ("largest period t", int(self.t.max()) if len(self) else None),
                ("lam, energy ratio", f"{self.lam:g}, {self.ratio}"),
                ("online design z0, mu", f"{self.z0}, {self.mu:g}"),
                ("J_online (no attack)", self.j_online),
                ("J_offline", self.j_offline),
                ("J_attack, smallest", float(self.j_attack.min()) if len(self) else None),
                ("J_attack, largest", float(self.j_attack.max()) if len(self) else None),
                ("smallest beta with J_attack >= J_offline", first),
            ],
        )


@dataclass(frozen=True)
class _Problem:
    """A validated (lam, ratio) with the online design to analyse."""

    lam: float
    ratio: Fraction
    design: OnlineDesign


def _problem(lam: float | Fraction, ratio: RatioLike, z0: int | None, mu: float | None) -> _Problem:
    """lam and ratio, with the online design given (z0, optional mu) or by design_online."""
    lam_f = as_probability("lam", lam)
    r = as_ratio("ratio", ratio)
    if z0 is None:
        if mu is not None:
            raise TypeError("mu: give z0 with mu (or neither, for fakeack.design_online's design)")
        design = design_online(lam, r)
    else:
        design = OnlineDesign(z0, 1.0 if mu is None else mu)
    return _Problem(lam_f, r, design)


def beta_sweep(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    t_max: int = 1000,
    *,
    z0: int | None = None,
    mu: float | None = None,
) -> BetaSweep:
    r"""The attacked cost at every :math:`\beta = r/t` in lowest terms, :math:`1 \le r < t \le t_{\max}`.

    The online schedule is :func:`fakeack.design_online` ``(lam, ratio)``. Each attack period is a
    renewal cycle, so :math:`J(r,t) = (t W_0 + a_r)/(t M_0 + b_r)` with :math:`a_r, b_r` accumulated
    once per r; fractions come in increasing order from the Farey sequence. :math:`t_{\max} = 10^4`
    (about :math:`3\cdot10^7` fractions) takes a few seconds.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability at low power.
    ratio : Fraction
        Energy ratio p/q (from :func:`fakeack.energy_ratio`).
    t_max : int, optional
        Largest period (default 1000).
    z0 : int, optional
        Memory length of the online schedule to analyse; by default
        :func:`fakeack.design_online` ``(lam, ratio)``, the schedule that spends the budget exactly.
    mu : float, optional
        Its memory mix; 1 when ``z0`` is given without it.

    Returns
    -------
    BetaSweep
    """
    core = compiled(system)
    pb = _problem(lam, ratio, z0, mu)
    t_max = _t_max(t_max)
    z0, mu = pb.design
    rr, tt, beta, j = core.beta_sweep(pb.lam, z0, mu, t_max)
    joff = core.j_offline(pb.lam, pb.ratio.numerator, pb.ratio.denominator)
    jon = core.j_online(pb.lam, z0, mu)
    return BetaSweep(rr, tt, beta, j, joff, jon, z0, mu, pb.lam, pb.ratio)


@dataclass(frozen=True)
class BetaBar:
    """The attacker threshold in its two definitions (see :func:`beta_bar`)."""

    finite: Fraction | None
    """Smallest r/t (t <= t_max, lowest terms) with J_attack >= J_offline; None if none."""
    limit: float
    """β at which the large-period limit J_∞(β) equals J_offline."""
    t_max: int
    j_offline: float
    j_online: float
    j_max: float
    z0: int
    mu: float

    def _repr_html_(self) -> str:
        from .._internal import html as _html

        return _html.key_values(
            "BetaBar: the attacker threshold",
            [
                (f"finite (smallest r/t, t <= {self.t_max})", self.finite),
                ("limit (large-period J_inf = J_offline)", self.limit),
                ("J_online", self.j_online),
                ("J_offline", self.j_offline),
                ("J_max (every flag blocked)", self.j_max),
                ("online design z0, mu", f"{self.z0}, {self.mu:g}"),
            ],
            "Two definitions of the threshold (see fakeack.beta_bar); fakeack.choose_schedule uses the "
            "limit: against a larger budget the sensor should ignore ACKs and go offline.",
        )


def beta_bar(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    t_max: int = 60,
    *,
    z0: int | None = None,
    mu: float | None = None,
) -> BetaBar:
    r"""The threshold :math:`\bar\beta` above which the sensor should drop ACKs (Sec. IV-C).

    The paper defines :math:`\bar\beta` by
    :math:`J(\tilde\theta_{on})_{\beta=\bar\beta} = J(\theta^\star_{off})`, but J is not a
    function of β alone: the run length r matters, and repeating a pattern (kr of kt) hurts more
    as k grows. Two well-defined versions are returned:

    * ``finite``: the smallest :math:`\beta = r/t` in lowest terms with :math:`t \le t_{\max}` and
      :math:`J(r,t) \ge J_{\mathrm{off}}`;
    * ``limit``: the root of :math:`J_\infty(\beta) = J_{\mathrm{off}}` for the large-period limit
      (:func:`j_attack_limit`), in closed form
      :math:`\bar\beta = G/(G+L)`, :math:`G = (J_{\mathrm{off}} - J_{\mathrm{on}})/f_{\mathrm{on}}`,
      :math:`L = (J_{\max} - J_{\mathrm{off}})/f_{\mathrm{blk}}`. It is the threshold against the
      worst attacker with budget β, and the one :func:`choose_schedule` uses.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability at low power.
    ratio : Fraction
        Energy ratio p/q.
    t_max : int, optional
        Largest attack period for ``finite`` (default 60).
    z0 : int, optional
        Memory length of the online schedule to analyse; by default
        :func:`fakeack.design_online` ``(lam, ratio)``, the schedule that spends the budget exactly.
    mu : float, optional
        Its memory mix; 1 when ``z0`` is given without it.
    """
    core = compiled(system)
    pb = _problem(lam, ratio, z0, mu)
    t_max = _t_max(t_max)
    z0, mu = pb.design
    first, limit, joff, jon, jmax = core.beta_bar(
        pb.lam, pb.ratio.numerator, pb.ratio.denominator, z0, mu, t_max
    )
    finite = None if first is None else Fraction(first[0], first[1])
    return BetaBar(finite, limit, t_max, joff, jon, jmax, z0, mu)


@dataclass(frozen=True)
class Decision:
    """The sensor's choice against an attacker of budget β."""

    schedule: str
    """"online" or "offline"."""
    beta: float
    beta_bar: float
    """The large-period threshold used for the decision."""
    j_online_attacked: float
    """Worst-case online cost at budget β (large-period limit)."""
    j_offline: float
    j_online: float
    z0: int
    mu: float


def choose_schedule(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    beta: float | Fraction,
    *,
    z0: int | None = None,
    mu: float | None = None,
) -> Decision:
    r"""Keep the online schedule or switch to the offline one (Sec. IV-C's rule).

    .. math::
       \tilde\theta = \theta_{\mathrm{on}} \text{ if } \beta < \bar\beta, \quad
       \theta^\star_{\mathrm{off}} \text{ otherwise},

    with :math:`\bar\beta` the large-period threshold of :func:`beta_bar`, i.e. against the worst
    attacker that blocks a fraction β of the flag-ACKs; the costs compared are
    :func:`j_attack_limit` at β and :func:`fakeack.j_offline`.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
    ratio : Fraction
        Energy ratio p/q.
    beta : float or Fraction
        The attacker's (estimated) budget in [0, 1].
    z0 : int, optional
        Memory length of the online schedule to analyse; by default
        :func:`fakeack.design_online` ``(lam, ratio)``, the schedule that spends the budget exactly.
    mu : float, optional
        Its memory mix; 1 when ``z0`` is given without it.
    """
    core = compiled(system)
    pb = _problem(lam, ratio, z0, mu)
    b = as_probability("beta", float(as_fraction("beta", beta)), closed=True)
    z0, mu = pb.design
    online, bb, jatt, joff, jon = core.choose_schedule(
        pb.lam, pb.ratio.numerator, pb.ratio.denominator, z0, mu, b
    )
    return Decision("online" if online else "offline", b, bb, jatt, joff, jon, z0, mu)


@dataclass(frozen=True)
class MaskSearch:
    """Result of :func:`worst_mask`."""

    mask: IntArray
    """The most damaging blocking pattern found (0/1, length t)."""
    j: float
    j_consecutive: float
    """Cost of the consecutive pattern (the paper's "first r of t")."""
    consecutive_is_worst: bool


def worst_mask(
    system: LinearSystem, lam: float, z0: int, t: int, blocked: int, mu: float = 1.0
) -> MaskSearch:
    """Exhaustive search for the most damaging mask with ``blocked`` of ``t`` flags blocked.

    Tests whether blocking consecutively, the paper's choice after the optimal-DoS result it cites,
    is the worst pattern for this system. ``t <= 24`` (all :math:`\\binom{t}{blocked}` masks).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability at low power.
    z0 : int
        Memory length.
    t : int
        Mask length (flag-ACKs per period), at most 24.
    blocked : int
        Blocked flag-ACKs per period, ``0 <= blocked < t``.
    mu : float, optional
        Probability of the z0-bit memory at each step.
    """
    core = compiled(system)
    lam = as_probability("lam", lam)
    z0 = as_int("z0", z0, minimum=1)
    t = as_int("t", t, minimum=1)
    if t > 24:
        raise ValueError(f"t must be at most 24 for an exhaustive search, got {t}")
    blocked = as_int("blocked", blocked, minimum=0)
    if blocked >= t:
        raise ValueError(f"blocked must be smaller than t = {t}, got {blocked}")
    mu = as_probability("mu", mu, closed=True)
    mask, j, jc = core.worst_mask(lam, z0, mu, t, blocked)
    return MaskSearch(np.array(mask, dtype=np.int64), j, jc, j <= jc * (1 + 1e-12))
