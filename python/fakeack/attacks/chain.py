"""The fake-ACK attack (Sec. IV): its Markov chain, stationary law and cost."""

from __future__ import annotations

import numbers

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from .. import _fakeack
from .._internal.types import FloatArray, IntArray
from .._internal.validate import as_int, as_probability
from ..model.channels import ChannelLike, as_channel, channel_argument, is_paper_channel
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem, compiled
from .automata import AttackerAutomaton, MimicryAttack, discard_forgeries
from .kinds import (
    Attack,
    AttackLike,
    FlagInjection,
    MaskBlocking,
    PeriodicBlocking,
    attack_argument,
    core_attack,
)

__all__ = [
    "num_states",
    "attack_chain",
    "stationary_distribution",
    "balance_residual",
    "j_attack",
    "general_attack_chain",
    "stationary_gth",
]


def _check(lam: float, z0: int, r: int, t: int) -> tuple[float, int, int, int]:
    lam, z0 = as_probability("lam", lam), as_int("z0", z0, minimum=1)
    att = PeriodicBlocking(r, t)
    return lam, z0, att.r, att.t


def num_states(z0: int, r: int, t: int) -> int:
    r"""Number of chain states :math:`|\mathcal S| = \tfrac12 r(r+1)z_0 + t(z_0+1)` (Sec. IV-B).

    Parameters
    ----------
    z0 : int
        Memory length.
    r, t : int
        The attacker blocks the first r of every t flag-ACKs.
    """
    _, z0, r, t = _check(0.5, z0, r, t)
    return int(_fakeack.num_states(z0, r, t))


def attack_chain(lam: float, z0: int, r: int, t: int) -> tuple[IntArray, sp.csr_array]:
    r"""The Markov chain :math:`S_k = (\tau_k, \sigma_k)` under the fake-ACK attack (Sec. IV-B).

    States follow the paper's order (level :math:`\sigma = 0..t-1`; in level :math:`\sigma \le r`,
    :math:`\tau = 0..z_0(\sigma+1)`, else :math:`\tau = 0..z_0`); transitions follow rules 1)-4),
    with the attacker blocking the first r of every t flag-ACKs (Model note 3).

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length :math:`z_0 \ge 1` (fixed, :math:`\mu = 1`).
    r, t : int
        The attacker blocks the first ``r`` of every ``t`` flag-ACKs, ``0 <= r < t``. A pair that
        is not in lowest terms is a different attack (kr blocked in a row out of kt) and is built
        as given.

    Returns
    -------
    states : numpy.ndarray
        ``(|S|, 2)`` int64 array of ``[tau, sigma]``.
    T : scipy.sparse.csr_array
        Row-stochastic: ``T[i, j] = P[S_{k+1} = j | S_k = i]``, i.e. the transpose of the paper's
        column-stochastic :math:`\mathcal T_s` (for ``z0=2, r=1, t=3`` its eq. (12), with Model
        note 4 applied).

    Raises
    ------
    ValueError
        On bad arguments, or when :math:`|\mathcal S|` exceeds ``fakeack.MAX_BUILD_STATES``
        (2·10^7); :func:`stationary_distribution` and :func:`j_attack` need no matrix.
    """
    lam, z0, r, t = _check(lam, z0, r, t)
    states, indptr, indices, data = _fakeack.attack_chain(lam, z0, r, t)
    n = states.shape[0]
    return states, sp.csr_array((data, indices, indptr), shape=(n, n))


def stationary_distribution(lam: float, z0: int, r: int, t: int, *, method: str = "structured") -> FloatArray:
    r"""Stationary law :math:`\Pi^\star` of the attack chain, aligned with :func:`attack_chain`.

    Solves :math:`\mathcal T_s \Pi = \Pi`, :math:`\sum\Pi = 1` (eq. (13)).

    Parameters
    ----------
    lam, z0, r, t
        As in :func:`attack_chain`.
    method : {"structured", "gth"}
        ``"structured"`` (default) fills the closed form
        :math:`\pi(\tau,\sigma) \propto \tilde c(\sigma-k)\,a^\tau` in :math:`O(|\mathcal S|)`
        without building the matrix (k is the segment of :math:`\tau`; :math:`\tilde c = 1` at
        level 0 and above r, :math:`1-a^{z_0}` between); see the model notes in the README.
        ``"gth"`` builds the matrix and runs Grassmann-Taksar-Heyman state reduction, an
        independent general solver.

    Returns
    -------
    numpy.ndarray
        Non-negative, summing to 1. Check it with :func:`balance_residual`.
    """
    lam, z0, r, t = _check(lam, z0, r, t)
    if method == "structured":
        return _fakeack.stationary_structured(lam, z0, r, t)
    if method == "gth":
        _, indptr, indices, data = _fakeack.attack_chain(lam, z0, r, t)
        return _fakeack.stationary_gth(indptr, indices, data)
    raise ValueError(f"method must be 'structured' or 'gth', got {method!r}")


def balance_residual(lam: float, z0: int, r: int, t: int, pi: npt.ArrayLike) -> float:
    r""":math:`\|\Pi' T - \Pi'\|_1` of a candidate stationary law, applying rules 1)-4) on the fly.

    Parameters
    ----------
    lam, z0, r, t
        As in :func:`attack_chain`.
    pi : array_like
        Candidate stationary vector aligned with :func:`attack_chain`'s states.

    Returns
    -------
    float
        The balance residual; the structured solver's is below 1e-12 (tests).
    """
    lam, z0, r, t = _check(lam, z0, r, t)
    arr = np.ascontiguousarray(pi, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"pi must be 1-D, got {arr.ndim}-D")
    return _fakeack.balance_residual(lam, z0, r, t, arr)


#: What :func:`j_attack` takes as its attack: the built-in ones and the engine's automata.
AnyAttack = Attack | MimicryAttack | AttackerAutomaton


def _any_attack(r: object, t: int | None, attack: object) -> AnyAttack:
    """:func:`attack_argument`, also taking a :class:`MimicryAttack` or an :class:`AttackerAutomaton`
    as ``attack`` (or in r's place)."""
    if attack is None and t is None and isinstance(r, (MimicryAttack, AttackerAutomaton)):
        attack, r = r, None
    if isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        if r is not None or t is not None:
            raise TypeError("give either r and t, or attack, not both")
        return attack
    return attack_argument(r, t, attack)  # type: ignore[arg-type]  # it validates any object


def _is_number(x: object) -> bool:
    """Whether ``x`` is a real number (what :func:`fakeack.model.as_channel` reads as ``lam``)."""
    return isinstance(x, (numbers.Real, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _structured(att: AnyAttack) -> bool:
    """Whether the structured renewal forms compute ``att`` (on the paper's channel)."""
    if isinstance(att, (MimicryAttack, AttackerAutomaton)):
        return False
    return not (isinstance(att, FlagInjection) and att.min_gap > 1)


def j_attack(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    z0: int | None = None,
    r: int | AttackLike | MimicryAttack | AttackerAutomaton = None,
    t: int | None = None,
    mu: float = 1.0,
    *,
    attack: AttackLike | MimicryAttack | AttackerAutomaton = None,
    lam: float | None = None,
    authenticated: bool = False,
) -> float:
    r"""Cost :math:`J(\tilde\theta_{\mathrm{on}})` under a fake-ACK attack (Sec. IV-B, eq. (14)).

    :math:`J = \sum_{\mathcal S}\Pi^\star(\tau,\sigma)\,\mathrm{Tr}\,h^\tau(\bar P)`, summed per
    segment of the stationary law against the weighted traces
    :math:`a^\tau\mathrm{Tr}\,h^\tau(\bar P)`: :math:`O(r z_0)` for the paper's attack, so
    chains of :math:`10^7` states and more cost microseconds, and long blocked runs never overflow
    where the weighted terms are finite. Any blocking mask and any :math:`\mu` use the renewal
    form (Model notes), checked against the full chain (:func:`general_attack_chain`).
    Independent blocking and forged flag-ACKs, which the paper leaves to future work, use the
    renewal cycle from one fresh start to the next (see :class:`fakeack.RandomBlocking` and
    :class:`fakeack.FlagInjection`).

    These structured forms run on the paper's channel (one state, a high-power packet always
    arrives) for the built-in attacks with ``min_gap = 1``. Every other case — a Markov channel,
    :class:`fakeack.MimicryAttack`, :class:`fakeack.AttackerAutomaton`, a
    :class:`fakeack.FlagInjection` with ``min_gap > 1`` — is the exact engine's
    :meth:`fakeack.Scenario.cost` (the coupled Stein equations of docs page "The exact engine").

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        :class:`fakeack.BernoulliChannel`, :class:`fakeack.MarkovChannel`,
        :class:`fakeack.GilbertElliott`, or a float: the paper's channel of that low-power arrival
        probability :math:`\lambda` (in (0, 1) on the structured route).
    z0 : int
        Memory length of the event detector.
    r, t : int, optional
        Block the first ``r`` of every ``t`` flag-ACKs (``r = 0`` is the unattacked online
        schedule); the same as ``attack=fakeack.PeriodicBlocking(r, t)``.
    mu : float, optional
        Memory mix :math:`\mu \in [0, 1]` as in :func:`fakeack.j_online`. For ``mu < 1`` the chain
        also needs the zeros in the memory since its last reset (the paper says its results cover
        this case but never writes it down). Costs :math:`O(r^2)` for ``mu < 1``.
    attack : attack, str, MimicryAttack or AttackerAutomaton, optional
        The attack, instead of ``r, t`` (an attack object may also be passed in r's place):
        :class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`,
        :class:`fakeack.RandomBlocking`, :class:`fakeack.FlagInjection` (any ``min_gap``),
        :class:`fakeack.MimicryAttack` (its ``None`` channel and design are this call's),
        :class:`fakeack.AttackerAutomaton`, or a spelling such as ``"1/5"``, ``"random:0.3"`` or
        ``"inject:0.1+random:0.3"``. A mask that blocks every flag-ACK is refused on every
        channel: its cost is that of the always-low sensor (:func:`fakeack.j_max` on the paper's
        channel, ``fakeack.Scenario(system, channel, fakeack.OfflineSchedule(pattern="0"))``
        elsewhere).
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float): ``j_attack(system, lam=0.5, z0=2, ...)`` still
        works. Giving both is a TypeError.
    authenticated : bool, keyword-only, optional
        Whether the sensor authenticates flag-ACKs and so rejects forged ones (default False):
        then only the attack's blocking part acts (``fakeack.attacks.discard_forgeries``), a
        forger without ``block`` costs J_on, and mimicry becomes the blocking of every genuine
        flag-ACK its virtual detector would not send.

    Returns
    -------
    float
        The attacked cost; ``inf`` (never NaN) where it is infinite or lies beyond the double
        range. On the structured route it is always finite in exact arithmetic (a finite r
        bounds the holding time), and ``inf`` only when long blocked runs reach where
        :math:`(1-\lambda)\rho(A)^2 \ge 1`; on the engine route it is ``inf`` exactly when
        :meth:`fakeack.Scenario.stability_index` is at least 1.

    Raises
    ------
    TypeError, ValueError
        For a missing or doubly given channel or attack, or a bad argument (naming it); on the
        engine route, a ValueError naming the channel or the attack when from some state no
        packet ever arrives again.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> round(fa.j_attack(s, 0.5, 2, attack=fa.PeriodicBlocking(1, 5)), 6)
    1.819651
    >>> mask = fa.MaskBlocking([1, 0, 0, 0, 0])
    >>> fa.j_attack(s, 0.5, 2, 1, 5) == fa.j_attack(s, 0.5, 2, attack=mask)
    True
    >>> round(fa.j_attack(s, 0.5, 2, attack=fa.RandomBlocking(0.2)), 6)
    1.832057
    >>> round(fa.j_attack(s, 0.5, 2, attack=fa.MimicryAttack()), 3)
    2.181
    >>> round(fa.j_attack(s, fa.GilbertElliott(0.1, 0.3, 0.9, 0.2), 2, attack=fa.MimicryAttack()), 3)
    2.011
    """
    core = compiled(system)
    att = _any_attack(r, t, attack)
    number = lam if lam is not None and channel is None else channel if lam is None else None
    if _structured(att) and _is_number(number):
        # A number is the paper's channel: today's route, without building the channel object.
        ch, channel_name, paper = None, "channel" if lam is None else "lam", True
    else:
        ch, channel_name = channel_argument(channel, lam, "j_attack")
        paper = is_paper_channel(ch)
    if z0 is None:
        raise TypeError("j_attack() missing the memory length z0")
    z0 = as_int("z0", z0, minimum=1)
    mu = as_probability("mu", mu, closed=True)
    if authenticated:
        # The sensor rejects forged flag-ACKs: only the attack's blocking part acts.
        if ch is None:
            ch = as_channel(number, channel_name)
        kept = discard_forgeries(att, channel=ch, design=OnlineDesign(z0, mu))
        if kept is None:
            from ..model.schedules import j_online

            return j_online(system, ch if not is_paper_channel(ch) else float(ch.low[0]), z0, mu)
        att, paper = kept, is_paper_channel(ch)
    if isinstance(att, MaskBlocking) and all(att.mask):
        hint = (
            "fakeack.j_max(system, lam)"
            if paper
            else "fakeack.Scenario(system, channel, fakeack.OfflineSchedule(pattern='0')).cost()"
        )
        raise ValueError(f"mask blocks every flag-ACK; its cost is {hint}")
    if paper and _structured(att):
        assert not isinstance(att, (MimicryAttack, AttackerAutomaton))  # _structured
        lam_value = as_probability(channel_name, number if ch is None else float(ch.low[0]))
        return core.j_attack(lam_value, z0, mu, core_attack(att))
    from ..engine.scenario import Scenario  # the engine imports this package's attack objects

    assert ch is not None  # only the structured route skips the channel object
    return Scenario(system, ch, OnlineDesign(z0, mu), att).cost()


def general_attack_chain(
    lam: float, z0: int, mask: npt.ArrayLike | PeriodicBlocking | MaskBlocking, mu: float = 1.0
) -> tuple[IntArray, sp.csr_array]:
    r"""The attack chain in full generality: any memory mix :math:`\mu` and any blocking mask.

    States are :math:`(\tau, z, \sigma)`: holding time, zeros in the detector's memory since its
    last reset, attacker counter. Built by breadth-first exploration of the protocol's rules from
    the paper's initial state, so it shares no formula with the structured solvers and serves as
    their independent check.

    Parameters
    ----------
    lam : float
        Arrival probability at low power.
    z0 : int
        Memory length.
    mask : sequence of 0/1, PeriodicBlocking or MaskBlocking
        The attack: ``mask[sigma] == 1`` blocks the flag-ACK counted sigma in each period of
        ``len(mask)`` (``[1]*r + [0]*(t-r)`` is the paper's attack), or an attack object. A mask
        of all ones is refused (the chain is infinite; its cost is :func:`fakeack.j_max`).
    mu : float, optional
        Probability of the z0-bit memory at each step.

    Returns
    -------
    states : numpy.ndarray
        ``(n, 3)`` int64 ``[tau, zeros, sigma]`` in exploration order.
    T : scipy.sparse.csr_array
        Row-stochastic transition matrix.
    """
    lam = as_probability("lam", lam)
    z0 = as_int("z0", z0, minimum=1)
    mu = as_probability("mu", mu, closed=True)
    att = mask if isinstance(mask, (PeriodicBlocking, MaskBlocking)) else MaskBlocking(mask)
    states, indptr, indices, data = _fakeack.general_attack_chain(lam, z0, mu, core_attack(att))
    n = states.shape[0]
    return states, sp.csr_array((data, indices, indptr), shape=(n, n))


def stationary_gth(T: npt.ArrayLike | sp.sparray | sp.spmatrix) -> FloatArray:
    """Stationary law of any irreducible row-stochastic sparse or dense matrix.

    Grassmann-Taksar-Heyman state reduction: no subtractions, so every entry is accurate to a few
    ulps even when it is tiny. Sparse fill-in makes it slow for large, densely coupled chains.

    Parameters
    ----------
    T : array_like or scipy.sparse matrix
        Square, non-negative, rows summing to 1.

    Returns
    -------
    numpy.ndarray
        The stationary vector, summing to 1.

    References
    ----------
    .. [1] W. K. Grassmann, M. I. Taksar, D. P. Heyman, "Regenerative analysis and steady state
       distributions for Markov chains", Operations Research 33(5), 1985.
    """
    M = sp.csr_array(T)  # type: ignore[arg-type]  # scipy reads any array_like; its stubs take arrays
    if M.ndim != 2 or M.shape[0] != M.shape[1] or M.shape[0] == 0:
        raise ValueError(f"T must be a non-empty square matrix, got shape {M.shape}")
    M.sum_duplicates()
    M.sort_indices()
    data = np.asarray(M.data, dtype=np.float64)
    if not np.all(np.isfinite(data)) or np.any(data < 0):
        raise ValueError("T must be finite and non-negative")
    rows = np.asarray(M.sum(axis=1)).ravel()
    if np.max(np.abs(rows - 1.0)) > 1e-10:
        raise ValueError("T must be row-stochastic (rows summing to 1)")
    return _fakeack.stationary_gth(M.indptr.astype(np.int64), M.indices.astype(np.int64), data)
