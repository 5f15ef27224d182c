"""detection_curves: detection_probability over window lengths, per test and attack; the interval
test's windows with fewer than 100 expected flag-ACKs left out; clear errors."""

import numpy as np
import pytest

import fakeack as fa
from fakeack.detection import detection_curves


def test_every_point_is_detection_probabilitys():
    attacks = [
        None,
        fa.PeriodicBlocking(1, 5),
        fa.rate_matching_attack(0.5, 2, 0.2, min_gap=3),
        fa.MimicryAttack(),
        fa.FlagInjection(0.0004),
    ]
    c = detection_curves(0.5, 2, attacks, [300, 1000], alpha=0.05)
    assert c.probability.shape == (3, 5, 2) and c.tests == ("count", "interval", "support")
    for i, test in enumerate(c.tests):
        for j, a in enumerate(attacks):
            for k, n in enumerate(c.n_steps):
                if test == "interval" and n == 300:  # 43 expected flag-ACKs: refused
                    assert np.isnan(c.probability[i, j, k])
                    continue
                assert c.probability[i, j, k] == fa.detection_probability(0.5, 2, a, int(n), 0.05, test)
    assert np.all(c.probability[2, :4] == 0.0) and c.probability[2, 4, 1] > 0.1  # only the naive forger


@pytest.mark.parametrize(
    ("kw", "error", "match"),
    [
        ({"tests": ["chi2"]}, ValueError, "tests: each must be one of"),
        ({"tests": []}, ValueError, "tests must not be empty"),
        ({"n_steps": []}, ValueError, "n_steps must not be empty"),
        ({"n_steps": [0]}, ValueError, "n_steps"),
        ({"attacks": []}, ValueError, "attacks must not be empty"),
        ({"alpha": 1.5}, ValueError, "alpha"),
        ({"support": "yes"}, TypeError, "support must be True or False"),
    ],
)
def test_bad_arguments_name_themselves(kw, error, match):
    args = {"attacks": [None], "n_steps": [1000], **kw}
    with pytest.raises(error, match=match):
        detection_curves(0.5, 2, args.pop("attacks"), args.pop("n_steps"), **args)
