"""A simulated ATI Nano17: what the DAQ would report for a force on the tool."""
from __future__ import annotations

import random

from drivers.interfaces import SAMPLE_SATURATED, ForceSample

FORCE_RANGE_N = (25.0, 25.0, 35.0)  # SI-25-0.25 calibrated range
TORQUE_RANGE_N_MM = 250.0
FORCE_STEP_N = 1.0 / 160.0  # one count of the 16-bit DAQ
TORQUE_STEP_N_MM = 1.0 / 32.0
TOOL_LENGTH_MM = 10.0  # from the sensor origin to the probe tip, along -z


class SimNano17:
    def __init__(self, noise_n: float, bias_n: float, rng: random.Random) -> None:
        self.noise_n = noise_n
        self._rng = rng
        self._bias = tuple(rng.uniform(-bias_n, bias_n) for _ in range(6))

    def wrench(self, force_sensor_frame: tuple[float, float, float]) -> list[float]:
        """What the gauges feel, as (Fx, Fy, Fz) N and (Tx, Ty, Tz) N*mm: true load, bias and noise."""
        fx, fy, fz = force_sensor_frame
        # The probe tip lies TOOL_LENGTH_MM below the sensor, so a lateral force makes a moment.
        true = (fx, fy, fz, TOOL_LENGTH_MM * fy, -TOOL_LENGTH_MM * fx, 0.0)
        values = [true[axis] + self._bias[axis] for axis in range(6)]
        if self.noise_n:
            for axis in range(6):
                values[axis] += self._rng.gauss(0.0, self.noise_n if axis < 3 else self.noise_n * TOOL_LENGTH_MM)
        return values

    def sample(self, t_s: float, force_sensor_frame: tuple[float, float, float]) -> ForceSample:
        """The wrench as an ideal DAQ in force units would give it: clipped to the range, quantised."""
        values, flags = self.wrench(force_sensor_frame), 0
        for axis in range(6):
            value = values[axis]
            limit = FORCE_RANGE_N[axis] if axis < 3 else TORQUE_RANGE_N_MM
            if abs(value) > limit:
                value, flags = (limit if value > 0 else -limit), flags | SAMPLE_SATURATED
            step = FORCE_STEP_N if axis < 3 else TORQUE_STEP_N_MM
            values[axis] = round(value / step) * step
        return ForceSample(t_s, (values[0], values[1], values[2]), (values[3], values[4], values[5]), flags)
