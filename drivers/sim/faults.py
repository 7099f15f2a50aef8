"""Fault injection for the simulated bench: what can go wrong on a real one, on demand.

Tests switch these on through ``world.faults``, a scene through its ``[faults]`` table, and
``palpd simulate --fault KIND@T[=VALUE]`` from the command line; each hook is applied where the
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


# What a scene's [faults] table or `palpd simulate --fault KIND@T[=VALUE]` can switch on, with the VALUE's
# meaning and default.
FAULT_KINDS = {
    "sensor_frozen": ("the sensor's readings stop changing (stuck amplifier or DAQ)", None),
    "sensor_drift": ("the sensor's zero wanders at VALUE N/s along its z axis, as strain gauges warm up", -0.5),
    "nan_samples": ("the sensor's conversions fail (NaN)", None),
    "encoder_jump": ("joint 2's encoder jumps by VALUE counts (a glitch or a slipped cable)", 400.0),
    "amplifier_fault": ("the amplifiers report a fault", None),
}


class SimFaults:
    """Every hook is off until a test turns it on, or its time in the schedule comes (a scene's [faults]);
    the world asks these on each read."""

    def __init__(self, schedule: dict | None = None, start_s: float = 0.0) -> None:
        self.rigid_objects: list[RigidObject] = []
        self.sensor_frozen = False  # stuck gauges: the readings keep coming, fresh, with the same values
        self.nan_samples = False
        self.encoder_jump_counts = (0, 0, 0)  # added to the counts from now on (a glitch or slipped cable)
        self.amplifier_fault = False
        self.sensor_drift_n_per_s = (0.0, 0.0, 0.0)  # a slowly wandering bias, as strain gauges warm up
        self.drift_since_s = 0.0  # the drift is rate * (t - drift_since_s)
        self._frozen_sample: ForceSample | None = None
        self._frozen_reading: tuple[float, list[float]] | None = None
        self.pending = sorted(((start_s + f.at_s, kind, f.value) for kind, f in (schedule or {}).items()),
                              key=lambda item: item[0])

    def advance(self, t_s: float) -> None:
        """Switch on whatever the schedule says is due by t_s."""
        while self.pending and self.pending[0][0] <= t_s:
            at_s, kind, value = self.pending.pop(0)
            self.switch_on(kind, value, at_s)

    def switch_on(self, kind: str, value: float | None = None, at_s: float = 0.0) -> None:
        value = FAULT_KINDS[kind][1] if value is None else value
        if kind == "sensor_drift":
            self.sensor_drift_n_per_s, self.drift_since_s = (0.0, 0.0, value), at_s
        elif kind == "encoder_jump":
            self.encoder_jump_counts = (0, int(value), 0)
        else:
            setattr(self, kind, True)

    def sample(self, fresh: ForceSample) -> ForceSample:
        if self.pending:
            self.advance(fresh.t_s)
        if self.sensor_frozen:
            if self._frozen_sample is None:
                self._frozen_sample = fresh
            return replace(self._frozen_sample, t_s=fresh.t_s)
        self._frozen_sample = None
        drift = self.sensor_drift_n_per_s
        if drift != (0.0, 0.0, 0.0):
            t = fresh.t_s - self.drift_since_s
            f = fresh.force_n
            fresh = replace(fresh, force_n=(f[0] + drift[0] * t, f[1] + drift[1] * t, f[2] + drift[2] * t))
        if self.nan_samples:
            fresh = replace(fresh, force_n=(math.nan, math.nan, math.nan))
        return fresh

    def wrench(self, t_s: float, load: list[float]) -> tuple[float, list[float]]:
        """The same faults at the gauges, for the paths that carry raw readings (DAQ, Net F/T)."""
        if self.pending:
            self.advance(t_s)
        if self.sensor_frozen:
            if self._frozen_reading is None:
                self._frozen_reading = (t_s, load)
            return t_s, self._frozen_reading[1]
        self._frozen_reading = None
        drift = self.sensor_drift_n_per_s
        if drift != (0.0, 0.0, 0.0):
            t = t_s - self.drift_since_s
            load = [load[0] + drift[0] * t, load[1] + drift[1] * t, load[2] + drift[2] * t, *load[3:]]
        if self.nan_samples:
            load = [math.nan] * len(load)
        return t_s, load

    def counts(self, counts: tuple[int, int, int]) -> tuple[int, int, int]:
        j = self.encoder_jump_counts
        return (counts[0] + j[0], counts[1] + j[1], counts[2] + j[2]) if j != (0, 0, 0) else counts

    def status(self, bits: int) -> int:
        return bits | STATUS_AMPLIFIER_FAULT if self.amplifier_fault else bits

    def extra_normal_force_n(self, x_mm: float, y_mm: float, indentation_mm: float) -> float:
        if not self.rigid_objects:  # as nearly always: no generator to build twice per servo tick
            return 0.0
        return sum(obj.force_n(x_mm, y_mm, indentation_mm) for obj in self.rigid_objects)


def stall(clock, seconds: float) -> None:
    """The host stops running for a while (a page fault, a stuck syscall): simulated time jumps."""
    clock.sleep_until(clock.now() + seconds)
