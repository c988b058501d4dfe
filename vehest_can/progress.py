"""A one-line progress display on stderr (redrawn on a terminal, every 10% otherwise)."""
from __future__ import annotations

import sys
import time


class Progress:
    def __init__(self, label: str, stream=None):
        self.label = label
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self._last_decile = -1
        self._t0 = time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        frac = done / total if total else 1.0
        if self.tty:
            bar = "#" * int(30 * frac)
            self.stream.write(f"\r{self.label:<28} [{bar:<30}] {100 * frac:5.1f}% {time.perf_counter() - self._t0:6.1f} s")
            self.stream.flush()
        elif int(10 * frac) > self._last_decile:
            self._last_decile = int(10 * frac)
            self.stream.write(f"{self.label}: {100 * frac:.0f}%\n")
            self.stream.flush()

    def done(self, note: str = "") -> None:
        self(1, 1)
        if self.tty:
            self.stream.write(f"  {note}\n")
        elif note:
            self.stream.write(f"{self.label}: {note}\n")
        self.stream.flush()
