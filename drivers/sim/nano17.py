"""A simulated ATI Nano17: what the DAQ would report for a force on the tool."""
from __future__ import annotations

import random

import numpy as np

from drivers.interfaces import SAMPLE_SATURATED, ForceSample

FORCE_RANGE_N = (25.0, 25.0, 35.0)  # SI-25-0.25 calibrated range
TORQUE_RANGE_N_MM = 250.0
FORCE_STEP_N = 1.0 / 160.0  # one count of the 16-bit DAQ
TORQUE_STEP_N_MM = 1.0 / 32.0
TOOL_LENGTH_MM = 10.0  # from the sensor origin to the probe tip, along -z


NOISE_BLOCK = 1024  # noise drawn this many readings at a time: one numpy call instead of six gauss() a tick


class SimNano17:
    def __init__(self, noise_n: float, bias_n: float, rng: random.Random) -> None:
        self.noise_n = noise_n
        self._bias = tuple(rng.uniform(-bias_n, bias_n) for _ in range(6))
        self._normal = np.random.default_rng(rng.getrandbits(64))
        self._sd = np.array([noise_n] * 3 + [noise_n * TOOL_LENGTH_MM] * 3)
        self._noise = iter(())

    def wrench(self, force_sensor_frame: tuple[float, float, float]) -> list[float]:
        """What the gauges feel, as (Fx, Fy, Fz) N and (Tx, Ty, Tz) N*mm: true load, bias and noise."""
        fx, fy, fz = force_sensor_frame
        b0, b1, b2, b3, b4, b5 = self._bias
        # The probe tip lies TOOL_LENGTH_MM below the sensor, so a lateral force makes a moment.
        values = [fx + b0, fy + b1, fz + b2, TOOL_LENGTH_MM * fy + b3, -TOOL_LENGTH_MM * fx + b4, b5]
        if self.noise_n:
            n0, n1, n2, n3, n4, n5 = self._next_noise()
            values = [values[0] + n0, values[1] + n1, values[2] + n2, values[3] + n3, values[4] + n4, values[5] + n5]
        return values

    def _next_noise(self) -> list[float]:
        noise = next(self._noise, None)
        if noise is None:
            self._noise = iter((self._normal.standard_normal((NOISE_BLOCK, 6)) * self._sd).tolist())
            noise = next(self._noise)
        return noise

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
