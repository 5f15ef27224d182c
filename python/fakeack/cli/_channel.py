"""The packet channel as the command line prints it: a line of text, a JSON object, and the
i.i.d. channel of the same mean that ``fakeack analyze`` puts beside a bursty one."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..model.channels import BernoulliChannel, Channel, GilbertElliott, MarkovChannel, is_paper_channel

__all__ = ["channel_json", "channel_label", "channel_short", "channel_text", "iid_twin", "memory"]

#: Channels with at most this many states print their matrices.
_PRINT_STATES = 4


def _g(x: float) -> str:
    return f"{float(x):g}"


def _vector(x: np.ndarray) -> str:
    return "[" + ", ".join(_g(v) for v in x) + "]"


def memory(channel: Channel) -> float:
    r"""How strongly consecutive channel states are correlated.

    ``1 - p - q`` for a Gilbert-Elliott channel (the eigenvalue of ``P`` other than 1: 0 means
    i.i.d. states, near 1 long bursts); for another channel the largest modulus of an eigenvalue
    of ``P`` other than the stationary one (0 for one state).
    """
    if isinstance(channel, GilbertElliott):
        return 1.0 - channel.p - channel.q
    if channel.n_states == 1:
        return 0.0
    moduli = np.sort(np.abs(np.linalg.eigvals(channel.P)))
    return float(moduli[-2])


def channel_label(channel: Channel | float) -> str:
    """The channel's parameters in one short phrase (``Gilbert-Elliott p=0.1, q=0.1, ...``)."""
    if not isinstance(channel, Channel):
        return f"i.i.d. lam={_g(channel)}"
    if isinstance(channel, BernoulliChannel):
        return f"i.i.d. lam={_g(channel.lam)}"
    if isinstance(channel, GilbertElliott):
        text = (
            f"Gilbert-Elliott p={_g(channel.p)}, q={_g(channel.q)}, lam_good={_g(channel.lam_good)}, "
            f"lam_bad={_g(channel.lam_bad)}"
        )
        if (channel.high_good, channel.high_bad) != (1.0, 1.0):
            text += f", high_good={_g(channel.high_good)}, high_bad={_g(channel.high_bad)}"
        return text
    if channel.n_states == 1:
        return f"i.i.d. lam={_g(channel.low[0])}, high={_g(channel.high[0])}"
    if channel.n_states > _PRINT_STATES:
        return f"Markov, {channel.n_states} states"
    P = "[" + ", ".join(_vector(row) for row in channel.P) + "]"
    return f"Markov P={P}, low={_vector(channel.low)}, high={_vector(channel.high)}"


def channel_short(channel: Channel) -> str:
    """A figure title's name of the channel: ``GE(0.1, 0.1, 1, 0)``, ``Markov (3 states)``."""
    if isinstance(channel, GilbertElliott):
        values = [channel.p, channel.q, channel.lam_good, channel.lam_bad]
        if (channel.high_good, channel.high_bad) != (1.0, 1.0):
            values += [channel.high_good, channel.high_bad]
        return "GE(" + ", ".join(_g(v) for v in values) + ")"
    if channel.n_states == 1:
        return channel_label(channel)
    return f"Markov ({channel.n_states} states)"


def channel_text(channel: Channel | float) -> str:
    """:func:`channel_label`, then for a channel with memory its long-run law and mean arrivals."""
    label = channel_label(channel)
    if not isinstance(channel, Channel) or channel.n_states == 1:
        return label
    pi = channel.stationary
    if isinstance(channel, GilbertElliott):
        law = f"memory 1-p-q = {_g(memory(channel))}; good {pi[0]:.4g}, bad {pi[1]:.4g} of the time"
    else:
        law = f"memory {_g(memory(channel))}; stationary law {_vector(np.round(pi, 6))}"
    high = "" if channel.mean_high == 1.0 else f", {channel.mean_high:.6g} at high power"
    return f"{label} ({law}; mean arrival {channel.mean_low:.6g} at low power{high})"


def channel_json(channel: Channel | float) -> dict[str, Any]:
    """The channel for ``--json``: its kind and parameters, P, low, high, the stationary law."""
    ch = channel if isinstance(channel, Channel) else BernoulliChannel(float(channel))
    if isinstance(ch, BernoulliChannel):
        params: dict[str, Any] = {"kind": "bernoulli", "lam": ch.lam}
    elif isinstance(ch, GilbertElliott):
        params = {
            "kind": "gilbert-elliott",
            "p": ch.p,
            "q": ch.q,
            "lam_good": ch.lam_good,
            "lam_bad": ch.lam_bad,
            "high_good": ch.high_good,
            "high_bad": ch.high_bad,
        }
    else:
        params = {"kind": "markov"}
    return {
        **params,
        "paper": is_paper_channel(ch),
        "label": channel_label(ch),
        "P": ch.P,
        "low": ch.low,
        "high": ch.high,
        "stationary": ch.stationary,
        "mean_low": ch.mean_low,
        "mean_high": ch.mean_high,
        "memory": memory(ch),
    }


def iid_twin(channel: Channel) -> Channel:
    r"""The i.i.d. channel of the same mean: one state with :math:`\pi\cdot\mathrm{low}` and
    :math:`\pi\cdot\mathrm{high}`.

    It is the paper's channel (:class:`fakeack.BernoulliChannel`) when every high-power packet
    arrives, else a one-state :class:`fakeack.MarkovChannel`. For a Gilbert-Elliott channel with
    ``p + q = 1`` and ``high_good = high_bad`` it is the channel itself in distribution (docs page
    "Bursty channels").
    """
    low, high = _clip(channel.mean_low), _clip(channel.mean_high)  # sums of pi_i x_i: up to 1 + 1e-16
    if np.all(channel.high == 1.0):
        return BernoulliChannel(low)
    return MarkovChannel([[1.0]], [low], [high])


def _clip(x: float) -> float:
    return min(1.0, max(0.0, x))
