"""Servo timing statistics: lateness and compute time per tick, kept without allocating per tick.

Compute is split into the host's own work and the simulator's share (the simulated
bridge and DAQ run inside the tick on a simulated bench; on hardware the share is 0).
"""
from __future__ import annotations

from array import array

import numpy as np
import numpy.ma  # noqa: F401  np.percentile imports it on first use: not in a servo process's loop (15 ms cold)

WINDOW_TICKS = 1 << 16  # about a minute at 1 kHz; older ticks are overwritten


class TimingStats:
    def __init__(self, rate_hz: float, window: int = WINDOW_TICKS) -> None:
        self.rate_hz = rate_hz
        self.ticks = 0
        self.overruns = 0
        self._lateness_s = array("d", bytes(8 * window))
        self._compute_s = array("d", bytes(8 * window))
        self._sim_s = array("d", bytes(8 * window))
        self._window = window

    def reset(self) -> None:
        """Start the statistics afresh (a benchmark's warm-up is not its result)."""
        self.ticks = 0
        self.overruns = 0

    def record(self, lateness_s: float, compute_s: float, sim_s: float = 0.0) -> None:
        i = self.ticks % self._window
        self._lateness_s[i] = lateness_s
        self._compute_s[i] = compute_s
        self._sim_s[i] = sim_s
        self.ticks += 1

    def summary(self) -> dict:
        """The Bench JSON ``loop`` figures (DESIGN.md), plus the host's and the simulator's shares."""
        n = min(self.ticks, self._window)
        late, compute, sim = (np.frombuffer(a, dtype=float)[:n] * 1e6 if n else np.zeros(1)
                              for a in (self._lateness_s, self._compute_s, self._sim_s))
        host = compute - sim
        return {
            "rate_hz": self.rate_hz,
            "ticks": self.ticks,
            "lateness_us": {"p50": _pct(late, 50), "p99": _pct(late, 99), "p999": _pct(late, 99.9),
                            "max": round(float(late.max()), 1)},
            "overruns": self.overruns,
            "compute_us": {"p50": _pct(compute, 50), "p99": _pct(compute, 99), "max": round(float(compute.max()), 1)},
            "host_us": {"p50": _pct(host, 50), "p99": _pct(host, 99)},
            "sim_us": {"p50": _pct(sim, 50), "p99": _pct(sim, 99)},
        }


def _pct(values: np.ndarray, q: float) -> float:
    return round(float(np.percentile(values, q)), 1)
