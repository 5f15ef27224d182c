"""A vectorised numpy Monte Carlo of the fake-ACK protocol: the baseline ``fa.simulate`` is timed against.

It is written the way a careful researcher would write it in numpy, and it shares no code with
fakeack (P̄ comes from scipy's DARE, the traces from a plain matrix iteration):

* every per-run quantity is an array of shape ``(runs,)`` (``(runs, n)`` for the errors) and only
  time is a Python loop; there is no Python loop over runs;
* the randomness of ``chunk`` steps is drawn at once (``(chunk, runs)`` uniforms, float32, which
  is exact for λ = 0.5 and within 2^-24 otherwise), the per-step updates are in-place ufuncs on
  preallocated int32/bool buffers, and Tr P_k is a table lookup (``np.take``) on the holding time.

Protocol (the same as ``fakeack.simulate``'s, type B): at k = 1 the sensor uses high power (the
packet arrives, τ = 0), the detector's memory is all ones, the attacker's counter is 0. Each step:
the packet arrives iff high power or a Bernoulli(λ) success; τ = 0 on arrival else τ + 1; the
remote covariance is P̄ on arrival, h(P_{k-1}) otherwise, so Tr P_k = Tr h^τ(P̄). Online, the
detector counts zero ACKs since its last reset or arrival and sends a flag-ACK when they reach the
memory length L (z0 with probability μ, else z0 + 1, drawn every step), then resets; the attacker
drops the flag iff ``mask[counter]`` and advances its counter mod ``len(mask)`` on every flag (or,
with ``beta``, drops each flag independently with probability β, keeping no counter); with
``gamma`` it sends a forged flag packet with probability γ on each step on which the detector
sends none; a delivered or forged flag makes the next step high power. Offline, step k uses
``pattern[(k-1) % len]``.

State mode simulates the errors with Gaussian noise: the sensor's steady-state Kalman filter error
e^s_k = (I-KC)(A e^s_{k-1} + w_{k-1}) - K v_k (e^s_0 ~ N(0, P̄)) and the remote error e_k = e^s_k on
arrival, else A e_{k-1} + w_{k-1} (the same w), averaging ||e_k||² (whose mean is Tr E[P_k]).

Usage::

    from numpy_protocol import simulate
    res = simulate(1.2, 0.7, 0.8, 0.8, lam=0.5, z0=2, mask=[1, 0, 0, 0, 0], horizon=1000, runs=10**5)
    res.j, res.stderr
    simulate(1.2, 0.7, 0.8, 0.8, lam=0.5, z0=2, beta=0.2, horizon=1000, runs=10**5)    # RandomBlocking(0.2)
    simulate(1.2, 0.7, 0.8, 0.8, lam=0.5, z0=2, gamma=0.05, horizon=1000, runs=10**5)  # FlagInjection(0.05)
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

__all__ = ["BaselineResult", "h_traces", "pbar_posterior", "simulate"]


def _mat(x) -> np.ndarray:
    return np.atleast_2d(np.asarray(x, dtype=np.float64))


def pbar_posterior(A, C, Q, R) -> np.ndarray:
    """Steady-state posterior covariance P̄ = P - P C'(C P C' + R)^{-1} C P from scipy's DARE."""
    A, C, Q, R = map(_mat, (A, C, Q, R))
    prior = sla.solve_discrete_are(A.T, C.T, Q, R)
    S = C @ prior @ C.T + R
    pbar = prior - prior @ C.T @ np.linalg.solve(S, C @ prior)
    return 0.5 * (pbar + pbar.T)


def h_traces(A, Q, pbar, n: int) -> np.ndarray:
    """[Tr h^0(P̄), ..., Tr h^n(P̄)] with h(X) = A X A' + Q; entries past the float range are inf."""
    A, Q = _mat(A), _mat(Q)
    X = np.array(pbar, dtype=np.float64)
    out = np.empty(n + 1)
    out[0] = np.trace(X)
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(1, n + 1):
            X = A @ X @ A.T + Q
            t = np.trace(X)
            if not np.isfinite(t):
                out[i:] = np.inf
                break
            out[i] = t
    return out


def _longest_cyclic_run(v) -> int:
    v = [bool(x) for x in v]
    if all(v):
        return len(v)
    best = cur = 0
    for x in v + v:
        cur = cur + 1 if x else 0
        best = max(best, cur)
    return best


def _psd_factor(X: np.ndarray) -> np.ndarray:
    """L with L L' = X for symmetric PSD X (eigen-decomposition, so singular X is fine)."""
    w, V = np.linalg.eigh(0.5 * (X + X.T))
    keep = w > max(w.max(), 0.0) * 1e-14
    return V[:, keep] * np.sqrt(w[keep])


@dataclass(frozen=True)
class BaselineResult:
    """Averages over the runs (field meanings as in ``fakeack.SimulationResult``)."""

    j: float
    stderr: float
    mean_trace: np.ndarray
    j_k: np.ndarray
    high_power_rate: float
    flags_sent: float
    flags_blocked: float
    flags_forged: float
    runs: int
    horizon: int
    seconds: float


def simulate(
    A,
    C,
    Q,
    R,
    lam: float,
    *,
    pattern=None,
    z0: int | None = None,
    mu: float = 1.0,
    mask=None,
    beta: float | None = None,
    gamma: float = 0.0,
    horizon: int = 1000,
    runs: int = 10_000,
    seed: int = 1,
    mode: str = "covariance",
    chunk: int = 64,
) -> BaselineResult:
    """Monte Carlo of the protocol, vectorised over runs.

    Give either ``pattern`` (offline schedule, a 0/1 period starting with 1) or ``z0`` (online
    schedule, with memory mix ``mu``); ``mask`` (online only) is the attacker's periodic blocking
    mask over its flag counter, e.g. ``[1]*r + [0]*(t-r)``, or ``beta`` blocks each flag
    independently with that probability; ``gamma`` forges a flag with that probability on each
    step without a genuine one (beside either). ``mode`` is ``"covariance"`` or ``"state"``.
    """
    t0 = time.perf_counter()
    A, C, Q, R = map(_mat, (A, C, Q, R))
    if not 0.0 < lam < 1.0:
        raise ValueError(f"lam must lie in (0, 1), got {lam}")
    if (pattern is None) == (z0 is None):
        raise ValueError("give exactly one of pattern (offline) and z0 (online)")
    if mode not in ("covariance", "state"):
        raise ValueError(f"mode must be 'covariance' or 'state', got {mode!r}")
    horizon, runs, chunk = int(horizon), int(runs), int(chunk)
    online = z0 is not None
    if online:
        z0 = int(z0)
        if z0 < 1 or not 0.0 <= mu <= 1.0:
            raise ValueError("need z0 >= 1 and mu in [0, 1]")
        mask_arr = None if mask is None else np.asarray(mask, dtype=bool)
        if mask_arr is not None and mask_arr.size == 0:
            raise ValueError("mask must not be empty")
        if mask_arr is not None and beta is not None:
            raise ValueError("give at most one of mask and beta")
        if not (beta is None or 0.0 <= beta <= 1.0) or not 0.0 <= gamma <= 1.0:
            raise ValueError("beta and gamma must lie in [0, 1]")
        memory = z0 if mu == 1.0 else z0 + 1
        if beta is not None and beta > 0.0:
            reach = horizon  # any number of flags in a row may be blocked
        elif mask_arr is None:
            reach = memory
        elif mask_arr.all():
            reach = horizon
        else:
            reach = memory * (_longest_cyclic_run(mask_arr) + 1)
        mu_draw = 0.0 < mu < 1.0
    else:
        if mask is not None or beta is not None or gamma:
            raise ValueError(
                "an offline schedule sends no flag-ACK: mask, beta and gamma apply to online only"
            )
        pat = np.asarray(pattern, dtype=np.int8)
        if pat.ndim != 1 or pat.size == 0 or pat[0] != 1 or not np.isin(pat, (0, 1)).all():
            raise ValueError("pattern must be a non-empty 0/1 sequence starting with 1")
        reach = _longest_cyclic_run(pat == 0)
        mask_arr, mu_draw = None, False
    bound = int(min(reach, horizon))

    pbar = pbar_posterior(A, C, Q, R)
    rng = np.random.Generator(np.random.SFC64(seed))
    lam32 = np.float32(lam)
    mu32 = np.float32(mu)
    beta32 = np.float32(0.0 if beta is None else beta)
    gamma32 = np.float32(gamma)
    blocking_random = online and beta is not None
    forging = online and gamma > 0.0
    i32 = np.int32

    # Protocol state, one entry per run.
    tau = np.zeros(runs, dtype=i32)
    zeros = np.zeros(runs, dtype=i32)
    counter = np.zeros(runs, dtype=i32)
    hi = np.ones(runs, dtype=bool)  # k = 1 is a high-power step
    arrive = np.empty(runs, dtype=bool)
    lost = np.empty(runs, dtype=bool)
    flag = np.empty(runs, dtype=bool)
    short = np.empty(runs, dtype=bool)
    drop = np.empty(runs, dtype=bool)
    fake = np.empty(runs, dtype=bool)
    tmp_b = np.empty(runs, dtype=bool)
    x = np.empty(runs)
    run_sum = np.zeros(runs)
    mean_trace = np.empty(horizon)
    sent = blocked = forged = high = 0
    mask_i = None if mask_arr is None else mask_arr.astype(bool)
    period = 0 if mask_arr is None else mask_arr.size

    if mode == "covariance":
        tr = h_traces(A, Q, pbar, bound)
    else:
        n, m = A.shape[0], C.shape[0]
        prior = A @ pbar @ A.T + Q
        S = C @ prior @ C.T + R
        K = np.linalg.solve(S, C @ prior).T
        IKC = np.eye(n) - K @ C
        Lq, Lr, Lp = _psd_factor(Q), _psd_factor(R), _psd_factor(pbar)
        rq = Lq.shape[1]
        # Right-multiplying row vectors: e_new = e @ M.T.
        FT, GT, HT, AT, LqT = (IKC @ A).T, (IKC @ Lq).T, (K @ Lr).T, A.T, Lq.T
        es = rng.standard_normal((runs, Lp.shape[1])) @ Lp.T
        e = es.copy()
        scalar = n == 1 and m == 1 and rq == 1
        if scalar:
            f, g, h, a, lq = FT.item(), GT.item(), HT.item(), AT.item(), LqT.item()
            es1, e1 = es[:, 0].copy(), e[:, 0].copy()
            tmp = np.empty(runs)

    if mode == "state":
        # Keep each chunk of Gaussian draws near 32 MB.
        chunk = max(1, min(chunk, (1 << 22) // (runs * max(rq, m))))
    lucky_c = shortc = blockc = forgec = noise_w = noise_v = None
    for k in range(horizon):
        c = k % chunk
        if c == 0:
            steps = min(chunk, horizon - k)
            lucky_c = rng.random((steps, runs), dtype=np.float32) < lam32
            if mu_draw:
                shortc = rng.random((steps, runs), dtype=np.float32) < mu32
            if blocking_random:
                blockc = rng.random((steps, runs), dtype=np.float32) < beta32
            if forging:
                forgec = rng.random((steps, runs), dtype=np.float32) < gamma32
            if mode == "state":
                noise_w = rng.standard_normal((steps, runs, rq))
                noise_v = rng.standard_normal((steps, runs, m))
        lucky = lucky_c[c]
        # Sensor and channel.
        if online:
            np.logical_or(hi, lucky, out=arrive)
        elif pat[k % pat.size]:
            arrive.fill(True)
            high += runs
        else:
            arrive[:] = lucky
        np.logical_not(arrive, out=lost)
        tau += 1
        np.minimum(tau, bound, out=tau)
        tau *= lost
        # Event detector and attacker.
        if online:
            if mu_draw:
                short[:] = shortc[c]
            if mask_i is None and not blocking_random:
                # Every flag (genuine or forged) is delivered and followed by an arrival: the
                # zero count is τ.
                np.greater_equal(tau, z0 if mu_draw else memory, out=flag)
                if mu_draw:
                    np.logical_and(flag, short, out=flag)
                    np.greater_equal(tau, z0 + 1, out=tmp_b)
                    np.logical_or(flag, tmp_b, out=flag)
                np.copyto(hi, flag)
            else:
                zeros += 1
                zeros *= lost
                if mu_draw:
                    np.equal(zeros, z0, out=flag)
                    np.logical_and(flag, short, out=flag)
                    np.greater_equal(zeros, z0 + 1, out=tmp_b)
                    np.logical_or(flag, tmp_b, out=flag)
                else:
                    np.greater_equal(zeros, memory, out=flag)
                np.logical_not(flag, out=tmp_b)
                zeros *= tmp_b
                if blocking_random:
                    np.logical_and(blockc[c], flag, out=drop)
                else:
                    np.take(mask_i, counter, out=drop)
                    np.logical_and(drop, flag, out=drop)
                    counter += flag
                    np.not_equal(counter, period, out=tmp_b)
                    counter *= tmp_b
                np.logical_not(drop, out=tmp_b)
                np.logical_and(flag, tmp_b, out=hi)
                blocked += int(np.count_nonzero(drop))
            if forging:
                # A forged flag packet where the detector sent none.
                np.logical_not(flag, out=fake)
                np.logical_and(fake, forgec[c], out=fake)
                np.logical_or(hi, fake, out=hi)
                forged += int(np.count_nonzero(fake))
            sent += int(np.count_nonzero(flag))
        # Estimation error.
        if mode == "covariance":
            np.take(tr, tau, out=x)
        elif scalar:
            w, v = noise_w[c, :, 0], noise_v[c, :, 0]
            # e^s = f e^s + g w - h v;  e = a e + lq w unless the packet arrived.
            es1 *= f
            es1 += g * w
            es1 -= h * v
            np.multiply(e1, a, out=tmp)
            tmp += lq * w
            np.copyto(tmp, es1, where=arrive)
            e1, tmp = tmp, e1
            np.multiply(e1, e1, out=x)
        else:
            w, v = noise_w[c], noise_v[c]
            es = es @ FT + w @ GT - v @ HT
            e = np.where(arrive[:, None], es, e @ AT + w @ LqT)
            np.einsum("ij,ij->i", e, e, out=x)
        if mode == "state":
            np.nan_to_num(x, copy=False, nan=np.inf)
        run_sum += x
        mean_trace[k] = x.sum()

    mean_trace /= runs
    averages = run_sum / horizon
    j = float(averages.mean())
    stderr = float(averages.std(ddof=1) / np.sqrt(runs)) if runs > 1 else float("inf")
    if not np.isfinite(stderr):
        stderr = float("inf")
    steps = runs * horizon
    if online:
        # Δ at k = 1 and after every delivered or forged flag except one at the last step.
        high = runs + (sent - blocked + forged) - int(np.count_nonzero(hi))
    return BaselineResult(
        j=j,
        stderr=stderr,
        mean_trace=mean_trace,
        j_k=np.cumsum(mean_trace) / np.arange(1, horizon + 1),
        high_power_rate=high / steps,
        flags_sent=sent / steps,
        flags_blocked=blocked / steps,
        flags_forged=forged / steps,
        runs=runs,
        horizon=horizon,
        seconds=time.perf_counter() - t0,
    )
