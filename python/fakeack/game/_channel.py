"""The closed-loop game under a Markov channel: what the compiled kernel is given (the design and
the fall-back pattern under the channel, the count test's bounds from the attack-free flag law of
the channel and the support check's shortest attack-free gap) — see :func:`fakeack.simulate_game`."""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any, cast

from .._internal.types import RatioLike
from .._internal.validate import as_int, as_probability, as_ratio, as_real
from ..attacks.kinds import MaskBlocking
from ..attacks.rates import FlagRates
from ..attacks.threshold import choose_schedule
from ..detection.count import process_alarm_bounds, rates_harmful_bound
from ..detection.flags import flag_rates
from ..detection.probability import KernelTest
from ..detection.process import flag_process
from ..model.channels import Channel
from ..model.offline import offline_search
from ..model.schedules import OnlineDesign, design_online
from ..model.system import LinearSystem
from .policies import SensorPolicy

__all__ = ["PlayedGame", "channel_game"]


@dataclass(frozen=True)
class PlayedGame:
    """The compiled game kernel's arguments: schedules, window, policy and (None: the paper's) channel."""

    lam: float
    ratio: Fraction
    design: OnlineDesign
    n: int
    policy: KernelTest
    channel: Channel | None = None
    offline: tuple[int, ...] | None = None
    """The fall-back pattern (first symbol = step 1); None: Theorem 3.1's of ``ratio``."""
    min_gap: int = 0
    """The support check's shortest allowed gap between flag-ACKs (0: no check)."""

    def channel_args(self) -> dict[str, Any]:
        """The kernel's keyword arguments for the channel and the fall-back pattern."""
        if self.channel is None:
            return {}
        ch = self.channel
        return {
            "channel_p": ch.P.tolist(),
            "channel_low": ch.low.tolist(),
            "channel_high": ch.high.tolist(),
            "offline_pattern": None if self.offline is None else [bool(x) for x in self.offline],
        }


def _sent(rates: FlagRates) -> float:
    return float(rates.sent)


def channel_game(
    system: LinearSystem,
    channel: Channel,
    ratio: RatioLike,
    policy: SensorPolicy,
    n_steps: int,
    beta_bar: float | None,
) -> PlayedGame:
    """The game of :func:`fakeack.simulate_game` under a Markov ``channel``."""
    r = as_ratio("ratio", ratio)
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    design = design_online(channel, r)
    pattern = tuple(int(x) for x in offline_search(system, channel, r).pattern)
    kernel: KernelTest
    min_gap = 0
    if policy.test == "offline":
        kernel = ("offline", -1, 0, [], [], 0.0, None, 0)
    elif policy.test == "never":
        kernel = ("online", -1, 0, [], [], 0.0, None, 0)
    elif policy.test == "cusum":  # its statistic goes as the kernel's `cusum` argument
        kernel = ("cusum", -1, 0, [], [], 0.0, None, cast(int, policy.fallback))
    elif policy.test == "lr":  # its tables go as the kernel's `lr` argument
        critical = policy.lr_test(channel, design, n).critical
        kernel = ("lr", -1, 0, [], [], critical, None, cast(int, policy.fallback))
    elif policy.test == "interval":
        raise ValueError(
            "policy: the interval test's law assumes independent gaps between flag-ACKs, which holds "
            f"only on the paper's i.i.d. channel, not on {channel!r}; use the count test"
        )
    else:
        alpha, fallback = cast(float, policy.alpha), cast(int, policy.fallback)
        process = flag_process(channel, design)
        lo, hi = process_alarm_bounds(process, n, alpha, policy.alternative)
        if policy.support:
            min_gap = process.min_gap  # 1 where a high-power packet can be lost: no check
        harm = None
        if policy.rule == "harmful":
            if beta_bar is None:
                bb = choose_schedule(system, channel, r, 0, z0=design.z0, mu=design.mu).beta_bar
            else:
                bb = as_real("beta_bar", beta_bar)
            z0, mu = design
            f_on = _sent(flag_rates(channel, z0, None, mu))
            f_blk = _sent(flag_rates(channel, z0, MaskBlocking([1]), mu))
            harm = rates_harmful_bound(f_on, f_blk, n, bb)
        kernel = ("count", lo, hi, [], [], 0.0, harm, fallback)
    lam = as_probability("channel", channel.mean_low)  # informational: the kernel uses the channel
    return PlayedGame(lam, r, design, n, kernel, channel, pattern, min_gap)
