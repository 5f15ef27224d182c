"""The repeated game between the sensor and an attacker who must not be seen.

Time is cut into windows of n steps. The sensor runs the online schedule and tests each window's
flag-ACKs (:mod:`fakeack.detection`); after an alarm that triggers its fall-back it runs the
offline schedule for K windows, then returns online. The attacker picks one attack from a list and
keeps it. The payoff is the long-run average of Tr E[P_k] (zero-sum: the sensor minimises it,
the attacker maximises it).

**The payoff formula.** With J_att the stationary online cost under the attack, J_off the offline
cost and d the probability that a stationary online window ends with a triggering alarm, the
sequence of windows is a renewal process whose cycle is one online window followed, with
probability d, by K offline windows. By the renewal-reward theorem the long-run average cost is
the expected cost per cycle over the expected cycle length:

.. math::
   J = \frac{n J_{att} + d K n J_{off}}{n + d K n} = \frac{J_{att} + d K J_{off}}{1 + d K},

and the high-power rate (hence the energy) is the same average of the online rate under attack
and the offline one p/q. It neglects (i) transients at switches: the first online window after a
fall-back starts from the state the offline windows left (detector memory, attacker counter), not
the stationary one, so its cost and its alarm probability differ; (ii) dependence between
consecutive windows' alarms (the state at a window's end carries over, e.g. a long-period
attacker's phase); (iii) the normal approximations behind d. All three fade as windows grow;
:func:`simulate_game` measures the real protocol with the detector in the loop.

**Why two fall-back rules.** J rises with d when J_att < J_off, so an attacker too weak to make
online worse than offline (or one who only forges flags) *wants* to trip a sensor that falls back
on any alarm. A rational sensor falls back only from harmful attacks: rule ``"harmful"`` acts on
an alarm only when the budget estimated from the window's count (:func:`fakeack.estimate_beta`)
exceeds β̄, the threshold past which online is worse than offline.

**A sequential sensor.** With ``SensorPolicy("cusum", fallback=K, cusum=fa.CusumTest(...))`` the
sensor runs the flag-ACK CUSUM at every online step instead of testing windows; the cycle is then
the online time to an alarm followed by K offline windows, with the same renewal average.
:func:`delay_frontier` sets what an attack costs against how soon the CUSUM, or the count test at
the same false-alarm rate, sees it.
"""

from .delay import DELAY_FAMILIES, DelayFrontier, delay_frontier
from .frontier import FAMILIES, StealthyFrontier, stealthy_frontier
from .payoff import Payoff, game_payoff
from .policies import SensorPolicy
from .simulate import GameSimulation, simulate_game
from .solve import GameSolution, Stackelberg, solve_game

__all__ = [
    "SensorPolicy",
    "Payoff",
    "game_payoff",
    "Stackelberg",
    "GameSolution",
    "solve_game",
    "GameSimulation",
    "simulate_game",
    "FAMILIES",
    "StealthyFrontier",
    "stealthy_frontier",
    "DELAY_FAMILIES",
    "DelayFrontier",
    "delay_frontier",
]
