"""The DAQ layer: gauge voltages from some acquisition backend, turned into flagged force samples.

A GaugeSource (the simulator, NI-DAQmx, ...) gives timestamped gauge voltages;
DaqSensor applies the calibration, the software bias (tare on voltages, as
ATI does) and flags what it cannot vouch for: gauges near the DAQ rails or
loads beyond the calibrated range (saturated), NaN (invalid), no new
conversion for too long (stale).
"""
from __future__ import annotations

import abc
import math
import time

from drivers.interfaces import (
    SAMPLE_INVALID, SAMPLE_REPEAT, SAMPLE_SATURATED, SAMPLE_STALE, ForceSample, ForceSensor,
)
from drivers.nano17.calibration import Calibration

RAIL_FRACTION = 0.995  # a gauge this close to the DAQ's rail is clipping, whatever it reads


class GaugeSource(abc.ABC):
    rail_v: float = 10.0

    @abc.abstractmethod
    def read_voltages(self) -> tuple[float, tuple[float, ...]]:
        """(device time in s, voltages): six gauges, then an optional thermistor channel."""

    def close(self) -> None:
        """Release the acquisition device."""


class _HostClock:
    def now(self) -> float:
        return time.monotonic()


class DaqSensor(ForceSensor):
    def __init__(self, source: GaugeSource, calibration: Calibration, clock=None, stale_after_s: float = 0.01) -> None:
        cal = calibration.in_units("N", "N-mm")
        self.source, self.clock, self.stale_after_s = source, clock or _HostClock(), stale_after_s
        self.gauges = cal.gauges
        self._rows = tuple(tuple(float(v) for v in row) for row in cal.matrix)
        self._ranges = cal.ranges
        self._bias_load = (0.0,) * 6
        self.thermistor_v: float | None = None
        self._last_device_t: float | None = None
        self._last_new_s = self.clock.now()

    def tare(self, readings: int = 100) -> None:
        """Software bias: the mean gauge voltages now (out of contact) become the zero."""
        total = [0.0] * self.gauges
        for _ in range(readings):
            _, volts = self.source.read_voltages()
            total = [a + b for a, b in zip(total, volts)]
        self._bias_load = self._load([v / readings for v in total])

    def read(self) -> ForceSample:
        device_t, volts = self.source.read_voltages()
        now = self.clock.now()
        flags = self._staleness(device_t, now)
        gauges = volts[:self.gauges]
        if len(volts) > self.gauges:
            self.thermistor_v = volts[self.gauges]
        load = self._load(gauges)
        if not all(map(math.isfinite, load)):
            flags |= SAMPLE_INVALID
        elif self._saturated(gauges, load):
            flags |= SAMPLE_SATURATED
        b = self._bias_load
        return ForceSample(now, (load[0] - b[0], load[1] - b[1], load[2] - b[2]),
                           (load[3] - b[3], load[4] - b[4], load[5] - b[5]), flags)

    def close(self) -> None:
        self.source.close()

    def _load(self, volts) -> list[float]:
        if self.gauges == 6:  # unrolled: this runs every servo tick
            v0, v1, v2, v3, v4, v5 = volts
            return [r[0] * v0 + r[1] * v1 + r[2] * v2 + r[3] * v3 + r[4] * v4 + r[5] * v5 for r in self._rows]
        return [sum(m * v for m, v in zip(row, volts)) for row in self._rows]

    def _saturated(self, gauges, load) -> bool:
        """A gauge near the DAQ's rail, or a load beyond the calibrated range (plain loops: every tick)."""
        rail = RAIL_FRACTION * self.source.rail_v
        if max(gauges) >= rail or min(gauges) <= -rail:  # (finite here: a NaN load is flagged invalid first)
            return True
        for value, limit in zip(load, self._ranges):
            if value > limit or value < -limit:
                return True
        return False

    def _staleness(self, device_t: float, now: float) -> int:
        if device_t != self._last_device_t:
            self._last_device_t, self._last_new_s = device_t, now
            return 0
        return SAMPLE_REPEAT | (SAMPLE_STALE if now - self._last_new_s > self.stale_after_s else 0)
