"""Servo timing statistics: lateness and compute time per tick, kept without allocating per tick."""
from __future__ import annotations

from array import array

import numpy as np

WINDOW_TICKS = 1 << 16  # about a minute at 1 kHz; older ticks are overwritten


class TimingStats:
    def __init__(self, rate_hz: float, window: int = WINDOW_TICKS) -> None:
        self.rate_hz = rate_hz
        self.ticks = 0
        self.overruns = 0
        self._lateness_s = array("d", bytes(8 * window))
        self._compute_s = array("d", bytes(8 * window))
        self._window = window

    def reset(self) -> None:
        """Start the statistics afresh (a benchmark's warm-up is not its result)."""
        self.ticks = 0
        self.overruns = 0

    def record(self, lateness_s: float, compute_s: float) -> None:
        i = self.ticks % self._window
        self._lateness_s[i] = lateness_s
        self._compute_s[i] = compute_s
        self.ticks += 1

    def summary(self) -> dict:
        """The Bench JSON ``loop`` figures (DESIGN.md)."""
        n = min(self.ticks, self._window)
        late = np.frombuffer(self._lateness_s, dtype=float)[:n] * 1e6
        compute = np.frombuffer(self._compute_s, dtype=float)[:n] * 1e6
        if n == 0:
            late = compute = np.zeros(1)
        return {
            "rate_hz": self.rate_hz,
            "ticks": self.ticks,
            "lateness_us": {"p50": _pct(late, 50), "p99": _pct(late, 99), "p999": _pct(late, 99.9),
                            "max": round(float(late.max()), 1)},
            "overruns": self.overruns,
            "compute_us": {"p50": _pct(compute, 50), "p99": _pct(compute, 99), "max": round(float(compute.max()), 1)},
        }


def _pct(values: np.ndarray, q: float) -> float:
    return round(float(np.percentile(values, q)), 1)
