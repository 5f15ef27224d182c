r"""The online design: the (z0, mu) whose attack-free high-power rate equals the energy ratio.

On the paper's channel (:func:`design_paper`) the rate of Model note 2,
:math:`f(z_0, \mu) = \lambda a^{z_0}(\mu + (1-\mu)a) / (1 - \mu a^{z_0+1} - (1-\mu)a^{z_0+2})`, is
settled in exact rationals; under any other channel (:func:`design_under_channel`) the rate is the
exact engine's and mu is found by bisection. :func:`fakeack.design_online` chooses between them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction

from .._internal.types import RatioLike
from .._internal.validate import as_fraction, as_probability, as_ratio
from .channels import Channel
from .exact import online_rate

__all__ = [
    "design_paper",
    "design_under_channel",
    "MAX_DESIGN_Z0",
    "EXACT_DESIGN_Z0",
    "MAX_CHANNEL_DESIGN_Z0",
    "MU_TOL",
]

#: Largest memory :func:`design_under_channel` looks for.
MAX_CHANNEL_DESIGN_Z0 = 2**16
#: Width of the final bracket of mu in :func:`design_under_channel`.
MU_TOL = 1e-15


def _rate_exact(lam: Fraction, z0: int, mu: Fraction) -> Fraction:
    a = 1 - lam
    return lam * a**z0 * (mu + (1 - mu) * a) / (1 - mu * a ** (z0 + 1) - (1 - mu) * a ** (z0 + 2))


def design_paper(lam: float | Fraction, ratio: RatioLike, name: str = "lam") -> tuple[int, float]:
    """:func:`fakeack.design_online` on the paper's channel: exact rationals (``name``: lam's argument)."""
    lam_f = as_probability(name, lam)
    lam_q = as_fraction(name, lam)
    rho = as_ratio("ratio", ratio)
    one = Fraction(1)
    top = _rate_exact(lam_q, 1, one)
    if rho > top:
        raise ValueError(
            f"ratio {rho} exceeds the largest high-power rate an online schedule with z0 >= 1 can "
            f"use at lam={lam_f} ({float(top):.6g} = (1-lam)/(2-lam))"
        )
    # f(z, 1) falls geometrically in z: bracket z0 in floats (bisection), then settle the boundary
    # exactly, where exact powers stay cheap.
    z0 = _largest_z_float(lam_f, float(rho))
    if z0 > MAX_DESIGN_Z0:
        raise ValueError(
            f"ratio {rho} is so small that the online schedule would need a memory of about {z0} "
            f"steps (more than {MAX_DESIGN_Z0})"
        )
    if z0 <= EXACT_DESIGN_Z0:
        z0 = max(1, z0 - 1)
        while _rate_exact(lam_q, z0 + 1, one) >= rho:
            z0 += 1
        # Now f(z0+1, 1) < rho <= f(z0, 1).
        if _rate_exact(lam_q, z0, one) == rho:
            return z0, 1.0
        a = 1 - lam_q
        mu_q = (rho * (1 - a ** (z0 + 2)) - lam_q * a ** (z0 + 1)) / ((1 - a) * a**z0 * (lam_q + rho * a))
        return z0, float(mu_q)
    rf, ln_a = float(rho), math.log1p(-lam_f)
    apow = math.exp(z0 * ln_a)
    mu = (rf * -math.expm1((z0 + 2) * ln_a) - lam_f * apow * (1.0 - lam_f)) / (
        lam_f * apow * (lam_f + rf * (1.0 - lam_f))
    )
    return z0, min(max(mu, 0.0), 1.0)


#: Largest memory design_online returns, and the largest it settles in exact arithmetic.
MAX_DESIGN_Z0 = 1_000_000
EXACT_DESIGN_Z0 = 2_000


def _largest_z_float(lam: float, rho: float) -> int:
    """Largest z >= 1 with f(z, 1) >= rho in floating point (bisection; f falls in z)."""
    ln_a = math.log1p(-lam)

    def f(z: int) -> float:
        # 1 - a^(z+1) by expm1: for lam below 1e-16, 1 - lam rounds to 1.
        return lam * math.exp(z * ln_a) / -math.expm1((z + 1) * ln_a)

    lo, hi = 1, 2
    while f(hi) >= rho and hi < 2**40:
        lo, hi = hi, hi * 2
    return _last_at_least(f, rho, lo, hi)


def _last_at_least(f: Callable[[int], float], rho: float, lo: int, hi: int) -> int:
    """The largest z in [lo, hi) with f(z) >= rho, for f falling in z, f(lo) >= rho > f(hi)."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if f(mid) >= rho:
            lo = mid
        else:
            hi = mid
    return lo


def design_under_channel(channel: Channel, ratio: Fraction) -> tuple[int, float]:
    r"""The online design :math:`(z_0, \mu)` whose engine high-power rate on ``channel`` is ``ratio``.

    With :math:`f(z, \mu)` the engine's rate, :math:`f(z, 0) = f(z + 1, 1)` (a memory of z bits
    with probability 0 is a memory of z + 1). :math:`z_0` is the bracket
    :math:`f(z_0 + 1, 1) < \rho \le f(z_0, 1)`, found by comparing the rates with
    :math:`\rho` (doubling, then bisection on the integers: a bracket exists by the discrete
    intermediate value theorem once :math:`f(1,1) \ge \rho > f(z,1)`, and it is the only one where
    f falls in z). Then :math:`\mu = 1` if :math:`f(z_0, 1) = \rho`, else the root of
    :math:`f(z_0, \mu) = \rho` by bisection on :math:`[0, 1]` (:math:`f(z_0, 0) < \rho \le f(z_0, 1)`)
    until the bracket is ``fakeack.model.design.MU_TOL`` wide; of its two ends, the one whose rate is nearer.

    Raises
    ------
    ValueError
        Naming ``ratio`` when it exceeds :math:`f(1, 1)` (no online schedule spends that much)
        or needs a memory beyond ``MAX_CHANNEL_DESIGN_Z0``.
    """
    rho = float(ratio)
    rates: dict[int, float] = {}

    def f(z: int) -> float:
        if z not in rates:
            rates[z] = online_rate(channel, z, 1.0)
        return rates[z]

    top = f(1)
    if not rho <= top:
        raise ValueError(
            f"ratio {ratio} exceeds the largest high-power rate an online schedule with z0 >= 1 can "
            f"use on this channel ({top:.6g}, the rate of z0 = 1): no online schedule meets the budget"
        )
    lo, hi = 1, 2
    while f(hi) >= rho:
        if hi >= MAX_CHANNEL_DESIGN_Z0:
            raise ValueError(
                f"ratio {ratio} is so small that the online schedule would need a memory of more "
                f"than {MAX_CHANNEL_DESIGN_Z0} steps on this channel: no online schedule meets the budget"
            )
        lo, hi = hi, min(2 * hi, MAX_CHANNEL_DESIGN_Z0)
    z0 = _last_at_least(f, rho, lo, hi)  # f(z0 + 1, 1) < rho <= f(z0, 1)
    if f(z0) == rho:
        return z0, 1.0
    a, b = 0.0, 1.0
    ga, gb = f(z0 + 1) - rho, f(z0) - rho  # g(0) < 0 <= g(1)
    while b - a > MU_TOL:
        m = 0.5 * (a + b)
        if m in (a, b):
            break
        gm = online_rate(channel, z0, m) - rho
        if gm >= 0.0:
            b, gb = m, gm
        else:
            a, ga = m, gm
    return z0, (b if abs(gb) <= abs(ga) else a)
