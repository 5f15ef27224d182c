r"""Jamming of the data channel: attacks that destroy the sensor's packets.

A jammed step loses the sensor's packet whatever its power; an unjammed step arrives with the
channel's probability at the sensor's power. The remote detector sees a jammed step as a loss
like any other, so against the online schedule jamming also makes it send flag-ACKs. Jamming is
a change of the channel: the jammed channel's arrival probabilities are the channel's times the
chance that the step is not jammed, and :class:`fakeack.Scenario` evaluates it exactly
(``attack=Jamming(...)`` or ``attack=RandomJamming(...)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._internal.types import IntArray
from .._internal.validate import as_probability
from ..model.channels import ChannelLike, MarkovChannel, as_channel, closed_classes
from ..model.schedules import as_pattern

__all__ = ["Jamming", "RandomJamming", "JammingAttack", "MAX_JAMMED_STATES"]

#: Most states (channel states x pattern period) of a periodically jammed channel.
MAX_JAMMED_STATES = 1024
#: Longest pattern a repr writes out.
_REPR = 64


@dataclass(frozen=True, init=False)
class Jamming:
    r"""A jammer that jams the data channel by a periodic pattern.

    Step k is jammed iff ``pattern[(k - 1) % L]`` is 1, L the pattern's length: the first symbol
    is step 1, as for :class:`fakeack.OfflineSchedule`, so ``Jamming("10")`` against
    ``OfflineSchedule(pattern="10")`` jams every high-power step. A jammed step loses the packet
    at any power; an unjammed step k arrives with the channel's probability in state
    :math:`c_k` at the sensor's power. The arrival probability of step k is therefore

    .. math:: \Pr[\gamma_k = 1 \mid c_k, \text{power}] = (1 - j_{(k-1) \bmod L})\,
       \lambda_{\text{power}}(c_k),

    with j the pattern: the channel becomes the Markov chain of :math:`(c_k, (k-1) \bmod L)`
    (:meth:`jammed_channel`), started at phase 0 by :class:`fakeack.Scenario`.

    Parameters
    ----------
    pattern : str or sequence of 0/1
        One period, 1 = jammed, first symbol = step 1 (a string such as ``"0110"``, or 0/1 or
        booleans). At least one step must be unjammed (else no packet ever arrives).

    Raises
    ------
    TypeError
        ``pattern`` not a string or a sequence of 0/1 or booleans.
    ValueError
        ``pattern`` empty, with a symbol other than 0 and 1, or jamming every step.

    Examples
    --------
    >>> import fakeack as fa
    >>> jam = Jamming("0011")
    >>> jam.period, jam.jammed_fraction
    (4, 0.5)
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> tr = s.h_traces(2)   # ideal channel, high power: tau runs 0, 0, 1, 2 over a period
    >>> sc = fa.Scenario(s, 1.0, fa.OfflineSchedule(pattern="1"), jam)
    >>> bool(abs(sc.cost() - (2 * tr[0] + tr[1] + tr[2]) / 4) < 1e-12)
    True
    """

    pattern: tuple[int, ...]
    """One period of the jamming, 1 = jammed, first entry = step 1."""

    def __init__(self, pattern: object) -> None:
        pat = as_pattern(pattern)
        if all(pat):
            raise ValueError("pattern must leave at least one step unjammed (a 0): else no packet arrives")
        object.__setattr__(self, "pattern", pat)

    @property
    def period(self) -> int:
        """L, the pattern's length."""
        return len(self.pattern)

    @property
    def jammed_fraction(self) -> float:
        """The long-run fraction of jammed steps."""
        return sum(self.pattern) / len(self.pattern)

    @property
    def jammed(self) -> IntArray:
        """The pattern as an ``int64`` array of 0/1."""
        return np.array(self.pattern, dtype=np.int64)

    @property
    def label(self) -> str:
        """``"jam:<pattern>"``."""
        return (
            f"jam:{''.join(map(str, self.pattern))}" if self.period <= _REPR else f"jam:<{self.period} steps>"
        )

    def jammed_channel(self, channel: ChannelLike) -> MarkovChannel:
        r"""The channel of :math:`(c, \varphi)`, :math:`\varphi = (k - 1) \bmod L` the phase.

        State ``c * L + phi`` moves to ``c' * L + (phi + 1) % L`` with probability ``P[c, c']``;
        its arrival probabilities are ``low[c]`` and ``high[c]`` when ``pattern[phi]`` is 0 and
        0 when it is 1. As a channel on its own its first state has the stationary law, a phase
        drawn uniformly; :class:`fakeack.Scenario` with ``attack=Jamming(...)`` starts it at
        phase 0 instead.

        Parameters
        ----------
        channel : Channel or float
            The channel without jamming (a float is the paper's channel).

        Returns
        -------
        MarkovChannel
            ``K * L`` states.

        Raises
        ------
        ValueError
            Naming ``channel`` when ``K * L`` exceeds ``MAX_JAMMED_STATES`` (1024), or when the
            channel's states cycle with a period that shares a factor with L (the jammed chain
            then has several closed classes, which a channel may not).
        """
        ch = as_channel(channel)
        k, period = ch.n_states, self.period
        if k * period > MAX_JAMMED_STATES:
            raise ValueError(
                f"channel: {k} states times the jamming period {period} exceed {MAX_JAMMED_STATES} states"
            )
        shift = np.roll(np.eye(period), 1, axis=1)  # phase phi -> phi + 1 mod L
        P = np.kron(np.asarray(ch.P), shift).astype(np.float64)
        free = 1.0 - self.jammed.astype(np.float64)
        low = np.kron(np.asarray(ch.low), free)
        high = np.kron(np.asarray(ch.high), free)
        if len(closed_classes(P)) != 1:
            raise ValueError(
                f"channel: its states cycle with a period that shares a factor with the jamming period "
                f"{period}, so the phase and the state never mix; use a pattern of another length"
            )
        return MarkovChannel(P, low, high)

    def __repr__(self) -> str:
        if self.period <= _REPR:
            return f"Jamming({''.join(map(str, self.pattern))!r})"
        return f"Jamming(<{sum(self.pattern)} jammed of {self.period} steps>)"

    def __str__(self) -> str:
        body = "".join(map(str, self.pattern)) if self.period <= 40 else f"{self.period} steps"
        return f"jamming pattern {body}"


@dataclass(frozen=True, init=False)
class RandomJamming:
    r"""A jammer that jams each step independently with probability ``rate``.

    A jammed step loses the packet at any power, so the channel's arrival probabilities are
    multiplied by :math:`1 - r` in every state and at both powers:

    .. math:: \Pr[\gamma_k = 1 \mid c_k, \text{power}] = (1 - r)\,\lambda_{\text{power}}(c_k).

    With an offline schedule of period 1 on a one-state channel every step is lost with the
    same probability q, the holding time is geometric and
    :math:`J = \sum_{\tau \ge 0} (1 - q) q^{\tau}\,\mathrm{Tr}\,h^{\tau}(\bar P)`.

    Parameters
    ----------
    rate : float
        The probability r in [0, 1] that a step is jammed.

    Raises
    ------
    TypeError, ValueError
        Naming ``rate`` when it is not a number in [0, 1].

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> sc = fa.Scenario(s, 1.0, fa.OfflineSchedule(pattern="1"), RandomJamming(0.25))
    >>> q = 0.25   # every step is lost with probability 1/4
    >>> pbar, Q, a2 = float(s.pbar[0, 0]), 0.8, 1.44
    >>> bool(abs(sc.cost() - ((1 - q) * pbar + q * Q) / (1 - q * a2)) < 1e-12)
    True
    """

    rate: float
    """The probability that a step is jammed."""

    def __init__(self, rate: float) -> None:
        object.__setattr__(self, "rate", as_probability("rate", rate, closed=True))

    @property
    def jammed_fraction(self) -> float:
        """The long-run fraction of jammed steps (the rate)."""
        return self.rate

    @property
    def label(self) -> str:
        """``"jam:random:<rate>"``."""
        return f"jam:random:{self.rate:g}"

    def jammed_channel(self, channel: ChannelLike) -> MarkovChannel:
        """The channel with every arrival probability multiplied by ``1 - rate``.

        Exact for every use of the channel, flag-ACK attacks included:
        ``fa.Scenario(s, RandomJamming(r).jammed_channel(ch), design, attack)`` is the
        scenario under both.

        Parameters
        ----------
        channel : Channel or float
            The channel without jamming (a float is the paper's channel).

        Returns
        -------
        MarkovChannel
        """
        ch = as_channel(channel)
        keep = 1.0 - self.rate
        return MarkovChannel(ch.P, np.asarray(ch.low) * keep, np.asarray(ch.high) * keep)

    def __repr__(self) -> str:
        return f"RandomJamming(rate={self.rate!r})"

    def __str__(self) -> str:
        return f"random jamming, rate {self.rate:g}"


#: The jamming attacks :class:`fakeack.Scenario` takes.
JammingAttack = Jamming | RandomJamming
