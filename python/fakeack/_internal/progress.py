"""Schedules as objects, Monte Carlo of the real protocol, and exact finite-horizon curves."""

from __future__ import annotations

import sys
import time


class Progress:
    """A tqdm bar that appears only if a run lasts longer than a second."""

    def __init__(self, total: int, enabled: bool | None):
        self.total, self.bar, self.start = total, None, time.monotonic()
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)

    def __call__(self, done: int) -> None:
        if not self.enabled:
            return
        if self.bar is None:
            if time.monotonic() - self.start < 1.0:
                return
            try:
                from tqdm.auto import tqdm
            except ImportError:  # the bar is optional (pip install fakeack[progress])
                self.enabled = False
                return
            self.bar = tqdm(total=self.total, unit="run", desc="fakeack simulate")
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
