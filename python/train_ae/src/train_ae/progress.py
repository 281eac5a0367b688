"""A minimal progress bar on stderr (no dependency): redraws in place on a terminal; otherwise
(logs, CI) prints a line at each tenth of the way and one when the bar finishes."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class ProgressBar:
    """``with ProgressBar(total, "epoch 1/5") as bar: bar.update(n, loss=0.1)``."""

    def __init__(self, total: int, label: str, stream: TextIO | None = None,
                 enabled: bool = True, width: int = 30) -> None:
        self.total = max(int(total), 1)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.width = width
        self.done = 0
        self.info = ""
        self.start = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _line(self) -> str:
        frac = self.done / self.total
        filled = round(frac * self.width)
        elapsed = time.perf_counter() - self.start
        return (f"{self.label} [{'#' * filled}{'.' * (self.width - filled)}] "
                f"{self.done}/{self.total} {elapsed:6.1f}s {self.info}")

    def update(self, n: int = 1, **info: float | str) -> None:
        self.done += n
        self.info = " ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                             for k, v in info.items())
        if not self.enabled:
            return
        if self.tty:
            self.stream.write("\r" + self._line())
            self.stream.flush()
        elif self.done < self.total and (self.done * 10 // self.total
                                         > (self.done - n) * 10 // self.total):
            self.stream.write(self._line() + "\n")
            self.stream.flush()

    def close(self) -> None:
        if not self.enabled:
            return
        self.stream.write(("\r" if self.tty else "") + self._line() + "\n")
        self.stream.flush()
        self.enabled = False
