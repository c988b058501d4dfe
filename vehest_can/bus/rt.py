"""Wall-clock scheduling at a fixed period, shared by the real-time ECU daemon and simulator.

Sleeps until just before the deadline and spins the rest (``time.sleep`` alone overshoots by
~0.1 ms, a fifth of a 500 µs tick). A tick that starts more than one period late is a deadline
miss; the schedule then skips ahead instead of bursting to catch up.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

SPIN_S = 150e-6


class Durations:
    """Durations (s) in fixed memory, for a process that runs for weeks: 1 µs bins up to 10 ms,
    then 64 bins per octave up to ~10 s (a bin's upper edge is reported: at most 1 µs or 1.1 %
    high), exact count and max. Percentiles as :func:`percentiles_us` gives them."""

    LINEAR_US = 10_000
    PER_OCTAVE = 64
    OCTAVES = 10

    def __init__(self) -> None:
        self.bins = np.zeros(self.LINEAR_US + self.PER_OCTAVE * self.OCTAVES + 1, dtype=np.int64)
        self.clear()

    def clear(self) -> None:
        """Empty again, in the same memory (a window of a long run)."""
        self.bins.fill(0)
        self.n = 0
        self.max_s = 0.0

    def _bin(self, us: float) -> int:
        if us < self.LINEAR_US:
            return max(0, int(us))
        k = int(math.log2(us / self.LINEAR_US) * self.PER_OCTAVE)
        return min(self.LINEAR_US + k, len(self.bins) - 1)

    def _upper_us(self, i: int) -> float:
        if i < self.LINEAR_US:
            return float(i + 1)
        return self.LINEAR_US * 2.0 ** ((i - self.LINEAR_US + 1) / self.PER_OCTAVE)

    def add(self, seconds: float) -> None:
        if not math.isfinite(seconds):
            return
        seconds = max(seconds, 0.0)
        self.bins[self._bin(seconds * 1e6)] += 1
        self.n += 1
        self.max_s = max(self.max_s, seconds)

    def extend(self, values) -> None:
        for v in values:
            self.add(v)

    def __len__(self) -> int:
        return self.n

    def percentiles_us(self, qs=(50, 99, 99.9)) -> dict[str, float]:
        if self.n == 0:
            return {}
        cum = np.cumsum(self.bins)
        out = {}
        for q in qs:
            i = int(np.searchsorted(cum, math.ceil(q / 100 * self.n)))
            out[f"p{q:g}"] = min(self._upper_us(i), self.max_s * 1e6)
        out["max"] = self.max_s * 1e6
        out["n"] = self.n
        return out


@dataclass
class Ticker:
    period: float
    lateness: Durations = field(default_factory=Durations)
    misses: int = 0
    late: float = 0.0  # how late the last tick started, s
    _next: float = 0.0
    _k: int = 0

    def start(self) -> None:
        self._next = time.perf_counter() + self.period
        self._k = 0

    def wait(self) -> int:
        """Block until the next tick is due; returns the number of ticks missed before it."""
        remaining = self._next - time.perf_counter()
        if remaining > SPIN_S:
            time.sleep(remaining - SPIN_S)
        while time.perf_counter() < self._next:
            pass
        late = self.late = time.perf_counter() - self._next
        self.lateness.add(late)
        missed = int(late // self.period)
        if missed:
            self.misses += missed
            self._next += missed * self.period
        self._next += self.period
        self._k += 1
        return missed


def percentiles_us(samples, qs=(50, 99, 99.9)) -> dict[str, float]:
    """Percentiles of durations (s) in µs, with max and count; empty input gives {}."""
    if isinstance(samples, Durations):
        return samples.percentiles_us(qs)
    if len(samples) == 0:
        return {}
    a = np.asarray(samples) * 1e6
    out = {f"p{q:g}": float(np.percentile(a, q)) for q in qs}
    out["max"] = float(a.max())
    out["n"] = int(a.size)
    return out
