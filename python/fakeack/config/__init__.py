"""TOML configurations of the command line: ``fakeack analyze`` (this package's names), ``fakeack
game`` (:mod:`fakeack.config.game`) and ``fakeack grid`` (:mod:`fakeack.config.grid`); the
``[channel]`` section and ``--channel`` are read by :mod:`fakeack.config.channel`."""

from .analyze import (
    Config,
    ConfigError,
    MonteCarloConfig,
    example_text,
    load_config,
    loads,
    parse_config,
)

__all__ = [
    "Config",
    "ConfigError",
    "MonteCarloConfig",
    "example_text",
    "load_config",
    "loads",
    "parse_config",
]
