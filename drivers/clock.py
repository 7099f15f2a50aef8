"""Clocks for the servo loop: wall time on a bench, virtual time in simulation.

Both expose now() and sleep_until(deadline); with the virtual clock, sleeping
is what makes time pass, so a simulated scan runs as fast as the CPU allows
and is deterministic.
"""
from __future__ import annotations

import time


class RealClock:
    def now(self) -> float:
        return time.monotonic()

    def sleep_until(self, deadline_s: float) -> None:
        remaining = deadline_s - time.monotonic()
        if remaining > 0:
            time.sleep(remaining)


class VirtualClock:
    def __init__(self, start_s: float = 0.0) -> None:
        self._now = start_s

    def now(self) -> float:
        return self._now

    def sleep_until(self, deadline_s: float) -> None:
        if deadline_s > self._now:
            self._now = deadline_s
