"""The attacker threshold: β sweeps, β̄, the sensor's decision, general attack patterns.

Every function takes a channel (:mod:`fakeack.model.channels`): the paper's channel keeps its
i.i.d. renewal forms, a Markov channel goes through :mod:`._markov` (the renewal with the
channel state as a phase, and the exact engine).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt

from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_fraction, as_int, as_probability, as_ratio
from ..model.channels import Channel, ChannelLike
from ..model.schedules import OnlineDesign, design_online, j_offline
from ..model.system import LinearSystem, compiled
from . import _markov
from ._args import channel_and_lam, required

__all__ = [
    "j_attack_limit",
    "BetaSweep",
    "beta_sweep",
    "BetaBar",
    "beta_bar",
    "Decision",
    "choose_schedule",
]


def _t_max(t_max: int) -> int:
    return as_int("t_max", t_max, minimum=2)


def j_attack_limit(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    z0: int | None = None,
    beta: float | Fraction | None = None,
    mu: float = 1.0,
    *,
    lam: float | None = None,
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
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float.
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

    Notes
    -----
    Under a Markov channel the same mix holds (each regime's time averages converge and a switch
    costs O(1) per period); the four numbers come from the exact engine, the all-blocked regime as
    ``fakeack.RandomBlocking(1)``.
    """
    ch, lam_f = channel_and_lam(channel, lam, "j_attack_limit")
    z0 = as_int("z0", required("j_attack_limit", "z0", z0), minimum=1)
    mu = as_probability("mu", mu, closed=True)
    beta_v = required("j_attack_limit", "beta", beta)
    b = as_probability("beta", float(as_fraction("beta", beta_v)), closed=True)
    if lam_f is not None:
        return compiled(system).j_attack_limit(lam_f, z0, mu, b)
    return _markov.j_limit(_markov.regimes(system, ch, OnlineDesign(z0, mu)), b)


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
    """The paper's lam, or a Markov channel's mean low-power arrival probability."""
    ratio: Fraction
    channel: Channel | None = None
    """The channel analysed."""

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
                (
                    "channel, energy ratio",
                    f"{self.channel if self.channel is not None else self.lam}, {self.ratio}",
                ),
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
    """A validated (channel, ratio) with the online design to analyse."""

    channel: Channel
    lam: float | None
    """The paper's lam on the paper's channel (its i.i.d. routes), else None."""
    ratio: Fraction
    design: OnlineDesign


def _problem(
    function: str,
    channel: object,
    lam: object,
    ratio: RatioLike | None,
    z0: int | None,
    mu: float | None,
) -> _Problem:
    """Channel and ratio, with the online design given (z0, optional mu) or by design_online."""
    ch, lam_f = channel_and_lam(channel, lam, function)
    r = as_ratio("ratio", required(function, "ratio", ratio))
    if z0 is None:
        if mu is not None:
            raise TypeError("mu: give z0 with mu (or neither, for fakeack.design_online's design)")
        # The number as given (a Fraction lam keeps the exact design), else the channel.
        raw = lam if lam is not None else channel
        exact = lam_f is not None and isinstance(raw, (int, float, Fraction))
        design = design_online(raw if exact else ch, r)  # type: ignore[arg-type]  # raw: a number
    else:
        design = OnlineDesign(z0, 1.0 if mu is None else mu)
    return _Problem(ch, lam_f, r, design)


def beta_sweep(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    ratio: RatioLike | None = None,
    t_max: int = 1000,
    *,
    z0: int | None = None,
    mu: float | None = None,
    lam: float | None = None,
) -> BetaSweep:
    r"""The attacked cost at every :math:`\beta = r/t` in lowest terms, :math:`1 \le r < t \le t_{\max}`.

    The online schedule is :func:`fakeack.design_online` ``(lam, ratio)``. Each attack period is a
    renewal cycle, so :math:`J(r,t) = (t W_0 + a_r)/(t M_0 + b_r)` with :math:`a_r, b_r` accumulated
    once per r; fractions come in increasing order from the Farey sequence. :math:`t_{\max} = 10^4`
    (about :math:`3\cdot10^7` fractions) takes a few seconds.

    Under a Markov channel whose high-power packets always arrive, each period is a cycle of runs
    of the renewal with the channel state as a phase (:func:`j_attack_pattern`):
    :math:`\Pi = B_r B_0^{t-1-r}`, so after an :math:`O(t_{\max}^2 K^3)` set-up every fraction
    costs :math:`O(K^3)` (:math:`t_{\max} = 1000` on a Gilbert-Elliott channel: about 0.1 s).
    If high-power packets can be lost, each fraction is an exact engine solve
    (:math:`t_{\max} \le 200`).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float.
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
    pb = _problem("beta_sweep", channel, lam, ratio, z0, mu)
    t_max = _t_max(t_max)
    z0, mu = pb.design
    if pb.lam is not None:
        rr, tt, beta, j = core.beta_sweep(pb.lam, z0, mu, t_max)
        joff = core.j_offline(pb.lam, pb.ratio.numerator, pb.ratio.denominator)
        jon = core.j_online(pb.lam, z0, mu)
        return BetaSweep(rr, tt, beta, j, joff, jon, z0, mu, pb.lam, pb.ratio, pb.channel)
    rr, tt, beta, j = _markov.sweep(system, pb.channel, pb.design, t_max)
    joff = j_offline(system, pb.channel, pb.ratio)
    jon = _markov.regimes(system, pb.channel, pb.design).j_on
    return BetaSweep(rr, tt, beta, j, joff, jon, z0, mu, pb.channel.mean_low, pb.ratio, pb.channel)


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
    channel: ChannelLike | None = None,
    ratio: RatioLike | None = None,
    t_max: int = 60,
    *,
    z0: int | None = None,
    mu: float | None = None,
    lam: float | None = None,
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

    Under a Markov channel ``finite`` comes from :func:`beta_sweep`'s renewal and ``limit`` from
    the same closed form with :math:`J_{\mathrm{on}}`, :math:`f_{\mathrm{on}}`,
    :math:`J_{\max}`, :math:`f_{\mathrm{blk}}` solved by the exact engine and
    :math:`J_{\mathrm{off}}` of the best offline pattern under that channel
    (:func:`fakeack.j_offline`).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float.
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
    pb = _problem("beta_bar", channel, lam, ratio, z0, mu)
    t_max = _t_max(t_max)
    z0, mu = pb.design
    if pb.lam is not None:
        first, limit, joff, jon, jmax = core.beta_bar(
            pb.lam, pb.ratio.numerator, pb.ratio.denominator, z0, mu, t_max
        )
        finite = None if first is None else Fraction(first[0], first[1])
        return BetaBar(finite, limit, t_max, joff, jon, jmax, z0, mu)
    joff = j_offline(system, pb.channel, pb.ratio)
    g = _markov.regimes(system, pb.channel, pb.design)
    rr, tt, _, j = _markov.sweep(system, pb.channel, pb.design, t_max)
    above = np.flatnonzero(j >= joff)
    found = None if above.size == 0 else Fraction(int(rr[above[0]]), int(tt[above[0]]))
    return BetaBar(found, _markov.beta_limit(g, joff), t_max, joff, g.j_on, g.j_max, z0, mu)


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
    channel: ChannelLike | None = None,
    ratio: RatioLike | None = None,
    beta: float | Fraction | None = None,
    *,
    z0: int | None = None,
    mu: float | None = None,
    lam: float | None = None,
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
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float.
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
    pb = _problem("choose_schedule", channel, lam, ratio, z0, mu)
    beta_v = required("choose_schedule", "beta", beta)
    b = as_probability("beta", float(as_fraction("beta", beta_v)), closed=True)
    z0, mu = pb.design
    if pb.lam is not None:
        online, bb, jatt, joff, jon = core.choose_schedule(
            pb.lam, pb.ratio.numerator, pb.ratio.denominator, z0, mu, b
        )
        return Decision("online" if online else "offline", b, bb, jatt, joff, jon, z0, mu)
    joff = j_offline(system, pb.channel, pb.ratio)
    g = _markov.regimes(system, pb.channel, pb.design)
    jatt = _markov.j_limit(g, b)
    choice = "online" if jatt < joff else "offline"
    return Decision(choice, b, _markov.beta_limit(g, joff), jatt, joff, g.j_on, z0, mu)
