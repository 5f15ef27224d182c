"""The ``[channel]`` section of a config and the ``--channel`` option: what they read, and every
bad value refused with the key named (exit 2 on the command line, no traceback)."""

import re
from fractions import Fraction

import pytest

import fakeack as fa
from conftest import PAPER
from fakeack import cli, config
from fakeack.config.channel import channel_table, parse_channel_option, read_channel

SYSTEM = """
[system]
A = 1.2
C = 0.7
Q = 0.8
R = 0.8
"""
ENERGY = '\n[energy]\nratio = "1/7"\n'
GE = """
[channel]
kind = "gilbert-elliott"
p = 0.1
q = 0.3
lam_good = 0.9
lam_bad = 0.2
"""


def parse(text):
    return config.parse_config(config.loads(text))


def run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


# ------------------------------------------------------------------------------ what is read


def test_gilbert_elliott_section():
    """The mean is pi_good lam_good + pi_bad lam_bad with pi_good = q/(p+q) = 3/4: 0.725; the
    designed schedule spends the budget under the channel, by the exact engine."""
    cfg = parse(SYSTEM + GE + ENERGY)
    assert cfg.channel == fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    assert not cfg.paper_channel and cfg.channel_arg is cfg.channel
    assert cfg.lam == pytest.approx(0.75 * 0.9 + 0.25 * 0.2, abs=1e-15)
    assert cfg.designed
    rate = fa.Scenario(cfg.system, cfg.channel, cfg.online).high_power_rate()
    assert rate == pytest.approx(1 / 7, abs=1e-12)


def test_high_powers_and_fraction_strings():
    cfg = parse(SYSTEM + GE.replace("p = 0.1", 'p = "1/10"') + "high_good = 1\nhigh_bad = 0.5\n" + ENERGY)
    assert cfg.channel == fa.GilbertElliott(0.1, 0.3, 0.9, 0.2, 1.0, 0.5)
    markov = """
[channel]
kind = "markov"
P = [["1/3", "1/3", "1/3"], [0.5, 0.5, 0], [1, 0, 0]]
low = [0.9, 0.5, 0]
"""
    ch = parse(SYSTEM + markov + ENERGY).channel
    assert ch.P[0].tolist() == [1 / 3, 1 / 3, 1 / 3] and ch.high.tolist() == [1.0, 1.0, 1.0]
    # pi solves pi P = pi: pi = (6, 4, 2)/12 by hand (pi_2 = pi_0/3, pi_1 = pi_0/3 + pi_1/2).
    assert ch.stationary == pytest.approx([0.5, 1 / 3, 1 / 6], abs=1e-12)


@pytest.mark.parametrize(
    "section",
    [
        '[channel]\nkind = "bernoulli"\nlam = 0.5\n',
        '[channel]\nkind = "markov"\nP = [[1.0]]\nlow = [0.5]\n',
        '[channel]\nkind = "markov"\nP = [[1.0]]\nlow = ["1/2"]\nhigh = [1]\n',
    ],
)
def test_paper_channel_spellings_are_the_short_form(section):
    short = parse(SYSTEM + "lam = 0.5\n" + ENERGY)
    cfg = parse(SYSTEM + section + ENERGY)
    assert cfg.paper_channel and cfg.channel is None and cfg.channel_arg == 0.5
    assert (cfg.lam, cfg.online, cfg.designed, cfg.ratio) == (short.lam, short.online, True, Fraction(1, 7))


def test_channel_table_round_trips():
    for ch in (
        fa.BernoulliChannel(0.25),
        fa.GilbertElliott(0.1, 0.3, 0.9, 0.2, 0.8, 0.5),
        fa.MarkovChannel([[0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]], [0.9, 0.5, 0.1], [1, 1, 0.5]),
        fa.MarkovChannel([[1.0]], [0.4], [0.9]),
    ):
        assert read_channel(channel_table(ch)) == ch


def test_channel_option():
    assert parse_channel_option("ge:0.1,0.3,0.9,0.2") == fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    assert parse_channel_option("GE: 1/10, 0.3, 1, 0, 1, 0.5") == fa.GilbertElliott(0.1, 0.3, 1, 0, 1, 0.5)
    assert parse_channel_option("gilbert-elliott:0.1,0.3,0.9,0.2") == fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    assert parse_channel_option("bernoulli:0.25") == fa.BernoulliChannel(0.25)


@pytest.mark.parametrize(
    "text, message",
    [
        ("0.5", "--channel: expected ge:"),
        ("gauss:0.5", "--channel: expected ge:"),
        ("ge:0.1,0.3,0.9", "--channel: ge takes 4 values"),
        ("ge:0.1,0.3,0.9,0.2,1", "--channel: ge takes 4 values"),
        ("bernoulli:0.1,0.2", "--channel: bernoulli takes one value"),
        ("bernoulli:1", "--channel lam: must lie in (0, 1)"),
        ("ge:1.5,0.3,0.9,0.2", "--channel p: must lie in [0, 1]"),
        ("ge:0.1,0.3,0.9,-0.2", "--channel lam_bad: must lie in [0, 1]"),
        ("ge:0.1,0.3,0.9,0.2,1,2", "--channel high_bad: must lie in [0, 1]"),
        ("ge:0.1,x,0.9,0.2", "--channel q: cannot read 'x'"),
        ("ge:0,0.3,0.9,0.2", "--channel p: must be positive"),
        ("ge:0.1,0,0.9,0.2", "--channel q: must be positive"),
    ],
)
def test_channel_option_errors_name_the_value(text, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        parse_channel_option(text)


# ------------------------------------------------------------------------------ errors


@pytest.mark.parametrize(
    "text, expected",
    [
        (SYSTEM + "lam = 0.5\n" + GE + ENERGY, "[system] lam: give either [system] lam"),
        (SYSTEM + ENERGY, "[system] lam: missing (arrival probability at low power, or give a [channel]"),
        (SYSTEM + GE.replace("lam_good", "lam_god") + ENERGY, "[channel] lam_god: unknown key"),
        (SYSTEM + GE + "P = [[1.0]]\n" + ENERGY, '[channel] P: not a key of kind = "gilbert-elliott"'),
        (SYSTEM + GE.replace('kind = "gilbert-elliott"\n', "") + ENERGY, "[channel] kind: missing"),
        (SYSTEM + GE.replace('"gilbert-elliott"', '"ge"') + ENERGY, "[channel] kind: must be"),
        (SYSTEM + GE.replace("q = 0.3\n", "") + ENERGY, "[channel] q: missing"),
        ("channel = 0.5\n" + SYSTEM + ENERGY, "[channel]: must be a table"),
        (SYSTEM + GE.replace("p = 0.1", "p = 1.1") + ENERGY, "[channel] p: must lie in [0, 1], got 1.1"),
        (SYSTEM + GE.replace("q = 0.3", "q = -0.3") + ENERGY, "[channel] q: must lie in [0, 1]"),
        (
            SYSTEM + GE.replace("lam_good = 0.9", "lam_good = 2") + ENERGY,
            "[channel] lam_good: must lie in [0, 1]",
        ),
        (
            SYSTEM + GE.replace("lam_bad = 0.2", "lam_bad = true") + ENERGY,
            "[channel] lam_bad: must be a probability",
        ),
        (SYSTEM + GE + "high_bad = 1.5\n" + ENERGY, "[channel] high_bad: must lie in [0, 1]"),
        (SYSTEM + GE + "high_good = 'x'\n" + ENERGY, "[channel] high_good: cannot read 'x'"),
        (SYSTEM + GE.replace("p = 0.1", "p = 0") + ENERGY, "[channel] p: must be positive"),
        (SYSTEM + GE.replace("q = 0.3", "q = 0.0") + ENERGY, "[channel] q: must be positive"),
        (SYSTEM + '[channel]\nkind = "bernoulli"\nlam = 1.0\n' + ENERGY, "[channel] lam: must lie in (0, 1)"),
        (SYSTEM + '[channel]\nkind = "bernoulli"\nlam = 0.5\np = 0.1\n' + ENERGY, "[channel] p: not a key"),
    ],
)
def test_config_errors_name_the_key(capsys, tmp_path, text, expected):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(config.ConfigError, match=re.escape("config: " + expected)):
        config.load_config(path)
    for command in (["analyze", path], ["sweep", "--config", path], ["game", path]):
        rc, out, err = run(capsys, *command)
        assert rc == 2 and out == "" and "Traceback" not in err
        assert err.startswith("fakeack: error: config: " + expected), err


MARKOV = '[channel]\nkind = "markov"\n'


@pytest.mark.parametrize(
    "body, expected",
    [
        ("P = [[0.9, 0.1], [0.3, 0.7]]\n", "[channel] low: missing"),
        ("P = 0.5\nlow = [0.5]\n", "[channel] P: must be a non-empty array of rows"),
        ("P = [0.5, 0.5]\nlow = [0.5]\n", "[channel] P: must be a non-empty array of rows"),
        ("P = [[0.9, 0.1]]\nlow = [0.5]\n", "[channel] P: must be square"),
        (
            "P = [[0.9, 0.1], [1.3, -0.3]]\nlow = [0.5, 0.5]\n",
            "[channel] P[1][0]: must lie in [0, 1], got 1.3",
        ),
        ("P = [[0.9, 0.2], [0.3, 0.7]]\nlow = [0.5, 0.5]\n", "[channel] P[0]: must sum to 1"),
        (
            "P = [[0.9, 0.1], [0.3, 0.7]]\nlow = [0.5]\n",
            "[channel] low: must have one entry per channel state (2",
        ),
        ("P = [[0.9, 0.1], [0.3, 0.7]]\nlow = 0.5\n", "[channel] low: must be an array"),
        ("P = [[0.9, 0.1], [0.3, 0.7]]\nlow = [0.5, 1.5]\n", "[channel] low[1]: must lie in [0, 1]"),
        (
            "P = [[0.9, 0.1], [0.3, 0.7]]\nlow = [0.5, 0.5]\nhigh = [-1, 1]\n",
            "[channel] high[0]: must lie in",
        ),
        (
            "P = [[1, 0], [0, 1]]\nlow = [0.5, 0.5]\n",
            "[channel] P: the channel is reducible: its states split into 2",
        ),
        (
            "P = [[1, 0], [0.5, 0.5]]\nlow = [0.5, 0.5]\n",
            "[channel] P: the channel is reducible: state(s) 1 cannot",
        ),
        ("P = [[0.5, 0.5, 0], [0.5, 0.5, 0], [0, 0.5, 0.5]]\nlow = [0.5, 0.5, 0.5]\n", "state(s) 2 cannot"),
        ("P = [[1.0]]\nlow = [1.0]\n", "[channel] low[0]: must lie in (0, 1)"),
    ],
)
def test_markov_errors_name_the_key(capsys, tmp_path, body, expected):
    path = tmp_path / "bad.toml"
    path.write_text(SYSTEM + MARKOV + body + ENERGY)
    rc, out, err = run(capsys, "analyze", path)
    assert rc == 2 and out == "" and "Traceback" not in err
    assert err.startswith("fakeack: error: config: [channel]") and expected in err, err


def test_state_mode_needs_the_paper_channel(capsys, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(SYSTEM + GE + ENERGY + '[montecarlo]\nruns = 10\nmode = "state"\n')
    rc, _, err = run(capsys, "analyze", path)
    assert rc == 2 and err.startswith('fakeack: error: config: [montecarlo] mode: must be "covariance"')
    rc, _, err = run(capsys, "simulate", "--channel", "ge:0.1,0.3,0.9,0.2", "--mode", "state", "--runs", 10)
    assert rc == 2 and "--mode state needs the paper's channel" in err


# ------------------------------------------------------------------------------ the example


def _uncomment(text: str, first: str, stop: str) -> str:
    """Uncomment the `key = value` lines from `first` up to the line starting with `stop`, and
    drop [system] lam."""
    out, inside = [], False
    for line in text.splitlines():
        if line.startswith("lam = 0.5"):
            continue
        if line == first:
            inside = True
        elif inside and line.startswith(stop):
            inside = False
        if inside and line.startswith("# ") and " = " in line:
            line = line[2:]
        out.append(line)
    return "\n".join(out) + "\n"


def test_example_shows_the_channel_commented():
    text = config.example_text()
    assert "\n# [channel]\n" in text and "\n[channel]" not in text
    assert parse(text).paper_channel  # as shipped: the paper's lam
    ge = _uncomment(text, "# [channel]", "# Or kind").replace("# [channel]", "[channel]")
    assert parse(ge).channel == fa.GilbertElliott(0.1, 0.1, 1.0, 0.0)
    markov = _uncomment(text, '# kind = "markov"', "# Every state").replace("# [channel]", "[channel]")
    ch = parse(markov).channel
    assert ch == fa.MarkovChannel([[0.9, 0.1], [0.3, 0.7]], [0.8, 0.2], [1.0, 0.9])


def test_override_replaces_the_channel_and_redesigns():
    base = config.loads(SYSTEM + "lam = 0.5\n" + ENERGY)
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    cfg = config.parse_config(base, channel=ge)
    assert cfg.channel == ge and cfg.online == parse(SYSTEM + GE + ENERGY).online
    assert "channel" not in base and base["system"]["lam"] == 0.5  # the document is not modified
    fixed = config.loads(SYSTEM + GE + ENERGY + "[online]\nz0 = 3\n")
    cfg = config.parse_config(fixed, channel=fa.BernoulliChannel(0.6))
    assert cfg.paper_channel and cfg.lam == 0.6 and tuple(cfg.online) == (3, 1.0)
    assert float(fa.LinearSystem(**PAPER).A[0, 0]) == float(cfg.system.A[0, 0])
