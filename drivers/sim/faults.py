"""Fault injection for the simulated bench: what can go wrong on a real one, on demand.

Tests switch these on through ``world.faults``; each hook is applied where the
real fault would show (the sensor sample, the encoder counts, the status bits,
the contact force, the host's clock), so palpd sees it through its ordinary
driver interfaces and nothing else.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from drivers.interfaces import STATUS_AMPLIFIER_FAULT, ForceSample


@dataclass(frozen=True)
class RigidObject:
    """Something hard hidden in the tissue: a flat-topped cylinder, top depth_mm below the surface."""

    center_mm: tuple[float, float]
    radius_mm: float
    depth_mm: float
    stiffness_n_per_mm: float = 60.0

    def force_n(self, x_mm: float, y_mm: float, indentation_mm: float) -> float:
        pressed = indentation_mm - self.depth_mm
        if pressed <= 0.0 or math.hypot(x_mm - self.center_mm[0], y_mm - self.center_mm[1]) > self.radius_mm:
            return 0.0
        return self.stiffness_n_per_mm * pressed


class SimFaults:
    """Every hook is off until a test turns it on; the world asks these on each read."""

    def __init__(self) -> None:
        self.rigid_objects: list[RigidObject] = []
        self.sensor_frozen = False  # the DAQ keeps handing out its last sample
        self.nan_samples = False
        self.encoder_jump_counts = (0, 0, 0)  # added to the counts from now on (a glitch or slipped cable)
        self.amplifier_fault = False
        self.sensor_drift_n_per_s = (0.0, 0.0, 0.0)  # a slowly wandering bias, as strain gauges warm up
        self._frozen_sample: ForceSample | None = None
        self._frozen_reading: tuple[float, list[float]] | None = None

    def sample(self, fresh: ForceSample) -> ForceSample:
        if self.sensor_frozen:
            if self._frozen_sample is None:
                self._frozen_sample = fresh
            return self._frozen_sample
        self._frozen_sample = None
        drift = self.sensor_drift_n_per_s
        if drift != (0.0, 0.0, 0.0):
            t = fresh.t_s
            f = fresh.force_n
            fresh = replace(fresh, force_n=(f[0] + drift[0] * t, f[1] + drift[1] * t, f[2] + drift[2] * t))
        if self.nan_samples:
            fresh = replace(fresh, force_n=(math.nan, math.nan, math.nan))
        return fresh

    def wrench(self, t_s: float, load: list[float]) -> tuple[float, list[float]]:
        """The same faults at the gauges, for the paths that carry raw readings (DAQ, Net F/T)."""
        if self.sensor_frozen:
            if self._frozen_reading is None:
                self._frozen_reading = (t_s, load)
            return self._frozen_reading
        self._frozen_reading = None
        drift = self.sensor_drift_n_per_s
        if drift != (0.0, 0.0, 0.0):
            load = [load[0] + drift[0] * t_s, load[1] + drift[1] * t_s, load[2] + drift[2] * t_s, *load[3:]]
        if self.nan_samples:
            load = [math.nan] * len(load)
        return t_s, load

    def counts(self, counts: tuple[int, int, int]) -> tuple[int, int, int]:
        j = self.encoder_jump_counts
        return (counts[0] + j[0], counts[1] + j[1], counts[2] + j[2]) if j != (0, 0, 0) else counts

    def status(self, bits: int) -> int:
        return bits | STATUS_AMPLIFIER_FAULT if self.amplifier_fault else bits

    def extra_normal_force_n(self, x_mm: float, y_mm: float, indentation_mm: float) -> float:
        return sum(obj.force_n(x_mm, y_mm, indentation_mm) for obj in self.rigid_objects)


def stall(clock, seconds: float) -> None:
    """The host stops running for a while (a page fault, a stuck syscall): simulated time jumps."""
    clock.sleep_until(clock.now() + seconds)
