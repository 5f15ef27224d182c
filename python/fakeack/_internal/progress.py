"""The progress bar of long computations: a tqdm bar that appears only if a run lasts longer than a
second and only where it can be seen."""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from tqdm import tqdm as Bar


class Progress:
    """A tqdm bar that appears only if a run lasts longer than a second."""

    def __init__(
        self, total: int, enabled: bool | None, desc: str = "fakeack simulate", unit: str = "run"
    ) -> None:
        self.total, self.start = total, time.monotonic()
        self.desc, self.unit = desc, unit
        self.bar: Bar[NoReturn] | None = None  # a bar over no iterable
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)

    def __call__(self, done: int) -> None:
        if not self.enabled:
            return
        bar = self.bar
        if bar is None:
            if time.monotonic() - self.start < 1.0:
                return
            try:
                from tqdm.auto import tqdm
            except ImportError:  # the bar is optional (pip install fakeack[progress])
                self.enabled = False
                return
            bar = tqdm(total=self.total, unit=self.unit, desc=self.desc)
            self.bar = bar
        bar.update(done - bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
