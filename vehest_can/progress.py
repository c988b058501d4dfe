"""Progress of a long run on stderr: a tqdm bar (rate, ETA, fits the terminal) on a terminal, a
plain line every 10 % otherwise (CI logs, pipes). Log records go around the bar while it runs."""
from __future__ import annotations

import logging
import sys
import time
from contextlib import ExitStack

from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm  # type: ignore[import-untyped]


class Progress:
    def __init__(self, label: str, stream=None, unit: str = "tick"):
        self.label = label
        self.stream = stream or sys.stderr
        self.unit = unit
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._bar: tqdm | None = None
        self._redirect = ExitStack()
        self._last_decile = -1
        self._t0 = time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        if self.tty:
            if self._bar is None:
                self._bar = tqdm(total=total, desc=self.label, unit=self.unit, unit_scale=True, file=self.stream,
                                 dynamic_ncols=True, leave=True)
                self._redirect.enter_context(logging_redirect_tqdm([logging.getLogger()]))
            if total != self._bar.total:
                self._bar.total = total
            self._bar.update(done - self._bar.n)
            return
        frac = done / total if total else 1.0
        if int(10 * frac) > self._last_decile:
            self._last_decile = int(10 * frac)
            self.stream.write(f"{self.label}: {100 * frac:.0f}% ({time.perf_counter() - self._t0:.1f} s)\n")
            self.stream.flush()

    def done(self, note: str = "") -> None:
        if self.tty:
            if self._bar is not None:
                self._bar.update(self._bar.total - self._bar.n)
                if note:
                    self._bar.set_postfix_str(note, refresh=True)
                self._bar.close()
                self._redirect.close()
                self._bar = None
            elif note:
                self.stream.write(f"{self.label}: {note}\n")
        else:
            self(1, 1)
            if note:
                self.stream.write(f"{self.label}: {note}\n")
        self.stream.flush()
