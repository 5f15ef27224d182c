"""high_power_rate, energy_per_step and flag_rates under a channel.

Expected values: the old code path bit for bit on the paper's channel (the compiled core's
structured rates called directly), the i.i.d. reduction (Gilbert-Elliott with p + q = 1 and equal
high-power probabilities is the paper's channel with lam = pi_good lam_good + pi_bad lam_bad) to
1e-12, closed forms on GilbertElliott(p, q, 1, 0) derived below, and the explicit chain of
tests/engine/reference_engine.py.
"""

import sys
from pathlib import Path

import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack import _fakeack
from fakeack.attacks.kinds import core_attack

sys.path.insert(0, str(Path(__file__).parent.parent / "engine"))
import reference_engine as ref  # noqa: E402

ATTACKS = [
    None,
    fa.PeriodicBlocking(1, 3),
    fa.MaskBlocking([1, 0, 1, 1]),
    fa.RandomBlocking(0.3),
    fa.FlagInjection(0.1),
    fa.FlagInjection(0.05, block=fa.PeriodicBlocking(1, 2)),
]
M3 = fa.MarkovChannel(
    [[0.9, 0.1, 0.0], [0.2, 0.6, 0.2], [0.0, 0.5, 0.5]], low=[0.9, 0.5, 0.05], high=[1.0, 1.0, 0.7]
)


def ge_rate(p, q, z0, mu=1.0):
    """High-power rate without attack on GilbertElliott(p, q, 1, 0): in a bad run (P(B >= n) =
    a^(n-1), a = 1 - q, at rate pq/(p+q)) cycles of m = z0 + 1 (prob mu) or z0 + 2 steps each end
    in a flag and a high-power step; E[flags per run] = phi / (a^2 (1 - phi)), phi = E[a^m]."""
    a = 1.0 - q
    phi = mu * a ** (z0 + 1) + (1.0 - mu) * a ** (z0 + 2)
    return p * q / (p + q) * phi / (a * a * (1.0 - phi))


def ge_sent_all_blocked(p, q, z0):
    """Flags sent with every one blocked on GilbertElliott(p, q, 1, 0): always low power, so a run
    of B bad steps holds floor(B / z0) flags (the count restarts after each), E = sum_j
    P(B >= j z0) = a^(z0-1) / (1 - a^z0), at pq/(p+q) runs per step."""
    a = 1.0 - q
    return p * q / (p + q) * a ** (z0 - 1) / (1.0 - a**z0)


@pytest.mark.parametrize("attack", ATTACKS, ids=str)
def test_bernoulli_bit_for_bit(attack):
    for lam in (0.5, 0.3):
        for z0, mu in ((2, 1.0), (3, 0.4)):
            old = _fakeack.flag_rates(lam, z0, mu, core_attack(attack))
            old_rate = _fakeack.high_power_rate(lam, z0, mu) if attack is None else old[1]
            for c in (lam, fa.BernoulliChannel(lam)):
                assert fa.high_power_rate(c, z0, attack, mu) == old_rate
                assert tuple(fa.flag_rates(c, z0, attack, mu)) == old
                assert fa.energy_per_step(c, z0, 3.0, 1.0, attack, mu) == 1.0 + 2.0 * old_rate
            assert fa.high_power_rate(lam=lam, z0=z0, attack=attack, mu=mu) == old_rate
            assert tuple(fa.flag_rates(lam=lam, z0=z0, attack=attack, mu=mu)) == old
            assert (
                fa.energy_per_step(lam=lam, z0=z0, Delta=3.0, delta=1.0, attack=attack, mu=mu)
                == 1.0 + 2.0 * old_rate
            )


@pytest.mark.parametrize("attack", ATTACKS, ids=str)
@pytest.mark.parametrize(("p", "lam_good", "lam_bad"), [(0.3, 0.9, 0.2), (0.55, 0.7, 0.45)])
def test_iid_reduction(attack, p, lam_good, lam_bad):
    ge = fa.GilbertElliott(p, 1.0 - p, lam_good, lam_bad)
    lam = (1.0 - p) * lam_good + p * lam_bad
    for z0, mu in ((1, 1.0), (2, 0.6)):
        assert_allclose(
            fa.high_power_rate(ge, z0, attack, mu), fa.high_power_rate(lam, z0, attack, mu), rtol=1e-12
        )
        assert_allclose(
            tuple(fa.flag_rates(ge, z0, attack, mu)),
            tuple(fa.flag_rates(lam, z0, attack, mu)),
            rtol=1e-12,
            atol=1e-15,
        )
        assert_allclose(
            fa.energy_per_step(ge, z0, 5.0, 2.0, attack, mu),
            fa.energy_per_step(lam, z0, 5.0, 2.0, attack, mu),
            rtol=1e-12,
        )


@pytest.mark.parametrize(("p", "q"), [(0.1, 0.1), (0.2, 0.5), (0.05, 0.3)])
def test_bursty_closed_forms(p, q):
    ge = fa.GilbertElliott(p, q, 1, 0)
    for z0 in (1, 2, 4):
        for mu in (1.0, 0.35):
            f = ge_rate(p, q, z0, mu)
            assert_allclose(fa.high_power_rate(ge, z0, mu=mu), f, rtol=1e-12)
            sent, delivered, forged = fa.flag_rates(ge, z0, mu=mu)
            assert_allclose((sent, delivered), (f, f), rtol=1e-12)
            assert forged == 0.0
            assert_allclose(fa.energy_per_step(ge, z0, 4.0, 1.0, mu=mu), 1.0 + 3.0 * f, rtol=1e-12)
        blocked = fa.flag_rates(ge, z0, fa.MaskBlocking([1]))
        assert_allclose(blocked.sent, ge_sent_all_blocked(p, q, z0), rtol=1e-12)
        assert blocked.delivered == 0.0 and fa.high_power_rate(ge, z0, fa.MaskBlocking([1])) == 0.0
        assert_allclose(blocked.blocked, blocked.sent, rtol=1e-15)


def test_the_bursty_online_rate_is_about_one_sixth():
    """A sanity check: about 0.166 on GilbertElliott(0.1, 0.1, 1, 0) (1/7 i.i.d.)."""
    assert abs(fa.high_power_rate(fa.GilbertElliott(0.1, 0.1, 1, 0), 2) - 0.166) < 5e-4


def reference_rates(ch, z0, mu, attacker):
    return ref.rates(ref.Chain(ch.P, ch.low, ch.high, ("online", z0, mu), attacker))


@pytest.mark.parametrize("ch", [0.5, fa.GilbertElliott(0.2, 0.4, 0.9, 0.3), M3], ids=["paper", "GE", "M3"])
def test_engine_only_attacks_against_the_explicit_chain(ch):
    """Attacks only the engine computes (min_gap > 1, automata) go to the engine on every channel,
    the paper's included (as fa.j_attack), and agree with reference_engine's explicit chain."""
    c = fa.model.as_channel(ch)
    inj = fa.FlagInjection(0.2, min_gap=3)
    hp, sent, delivered, forged = reference_rates(c, 2, 1.0, ref.Inject(0.2, None, 3))
    assert_allclose(fa.high_power_rate(ch, 2, inj), hp, rtol=1e-10)
    assert_allclose(tuple(fa.flag_rates(ch, 2, inj)), (sent, delivered, forged), rtol=1e-10)
    onoff = fa.AttackerAutomaton(
        {
            0: {"flag": [(0.7, True, 0), (0.3, False, 1)], "quiet": [(1.0, False, 0)]},
            1: {"flag": [(1.0, False, 1)], "quiet": [(0.8, False, 1), (0.2, False, 0)]},
        }
    )
    hp, sent, delivered, forged = reference_rates(
        c, 3, 0.5, ref.attacker_from(onoff.flag, onoff.quiet, onoff.start)
    )
    assert_allclose(fa.high_power_rate(ch, 3, onoff, 0.5), hp, rtol=1e-10)
    assert_allclose(tuple(fa.flag_rates(ch, 3, onoff, 0.5))[:2], (sent, delivered), rtol=1e-10)
    # Mimicry delivers a virtual attack-free system's flag-ACKs: exactly the attack-free rate.
    assert_allclose(fa.high_power_rate(ch, 2, fa.MimicryAttack()), fa.high_power_rate(ch, 2), rtol=1e-12)


def test_bad_arguments_name_the_argument():
    ge = fa.GilbertElliott(0.1, 0.1, 1, 0)
    with pytest.raises(TypeError, match=names("channel")):
        fa.high_power_rate("x", 2)
    with pytest.raises(TypeError, match=names("lam")):
        fa.flag_rates(0.5, 2, lam=0.5)
    with pytest.raises(ValueError, match=names("lam")):
        fa.flag_rates(1.5, 2)  # a number is the paper's lam
    with pytest.raises(ValueError, match=names("channel")):
        fa.flag_rates(fa.BernoulliChannel(0.0), 2)
    with pytest.raises(ValueError, match=names("lam")):
        fa.high_power_rate(lam=0.0, z0=2)
    with pytest.raises(TypeError, match=names("z0")):
        fa.high_power_rate(ge)
    with pytest.raises(ValueError, match=names("z0")):
        fa.flag_rates(ge, 0)
    with pytest.raises(ValueError, match=names("Delta")):
        fa.energy_per_step(ge, 2, 1.0, 1.0)
    with pytest.raises(TypeError, match=names("attack")):
        fa.high_power_rate(ge, 2, [1, 0])
    with pytest.raises(ValueError, match=names("lam")):
        fa.online_high_power_rate(1.5, 2)  # the wrappers keep naming lam
