"""Wall-clock scheduling at a fixed period, shared by the real-time ECU daemon and simulator.

Sleeps until just before the deadline and spins the rest (``time.sleep`` alone overshoots by
~0.1 ms, a fifth of a 500 µs tick). A tick that starts more than one period late is a deadline
miss; the schedule then skips ahead instead of bursting to catch up.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

SPIN_S = 150e-6


@dataclass
class Ticker:
    period: float
    lateness: list[float] = field(default_factory=list)
    misses: int = 0
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
        late = time.perf_counter() - self._next
        self.lateness.append(late)
        missed = int(late // self.period)
        if missed:
            self.misses += missed
            self._next += missed * self.period
        self._next += self.period
        self._k += 1
        return missed


def percentiles_us(samples, qs=(50, 99, 99.9)) -> dict[str, float]:
    """Percentiles of durations (s) in µs, with max and count; empty input gives {}."""
    if len(samples) == 0:
        return {}
    a = np.asarray(samples) * 1e6
    out = {f"p{q:g}": float(np.percentile(a, q)) for q in qs}
    out["max"] = float(a.max())
    out["n"] = int(a.size)
    return out
