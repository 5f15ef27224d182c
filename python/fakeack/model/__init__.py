"""The model: the process and its Kalman filter, and the power schedules without attack (offline and
ACK-based online) with their costs and the online design."""

from .channels import BernoulliChannel, Channel, GilbertElliott, MarkovChannel, as_channel
from .offline import OfflineSearch, offline_search
from .schedules import (
    OfflineSchedule,
    OnlineDesign,
    OnlineSchedule,
    design_online,
    energy_ratio,
    j_max,
    j_offline,
    j_online,
    offline_schedule,
)
from .system import LinearSystem

__all__ = [
    "LinearSystem",
    "Channel",
    "BernoulliChannel",
    "MarkovChannel",
    "GilbertElliott",
    "as_channel",
    "energy_ratio",
    "offline_schedule",
    "j_offline",
    "j_online",
    "OnlineDesign",
    "design_online",
    "j_max",
    "OfflineSchedule",
    "OnlineSchedule",
    "offline_search",
    "OfflineSearch",
]
