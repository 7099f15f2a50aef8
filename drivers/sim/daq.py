"""A simulated DAQ: the Nano17's gauge voltages as a 16-bit DAQ would digitise them.

The simulator knows the load on the sensor; the inverse of the calibration
turns it into the six gauge voltages a real Nano17 would put out, so the host
side runs the same calibration code as on the bench.
"""
from __future__ import annotations

import random
import time
from pathlib import Path

import numpy as np

from drivers.nano17.calfile import load_calibration
from drivers.nano17.calibration import Calibration
from drivers.sim.nano17 import FORCE_STEP_N
from drivers.nano17.daq import DaqSensor, GaugeSource

# The simulated Nano17 is calibrated like the real one on the seed paper's bench.
SIM_CALIBRATION = Path(__file__).with_name("FT8577.cal")
ADC_BITS = 16
# A real sensor and DAQ are never quieter than about one count: a scene's noise_n is the noise seen at the output,
# and one quieter than a count (noise_n = 0 included) gets one LSB of conversion noise, so the codes keep moving
# as on the bench, where palpd takes readings repeated exactly for milliseconds as a frozen sensor.
ADC_NOISE_LSB = 1.0
ADC_SEED = 0x0DA0
_NO_NOISE = (0.0,) * 6


class SimDaq(GaugeSource):
    def __init__(self, world, calibration: Calibration, rail_v: float = 10.0) -> None:
        self.world, self.rail_v = world, rail_v
        inverse = np.linalg.inv(calibration.in_units("N", "N-mm").matrix)
        self._inverse = tuple(tuple(float(v) for v in row) for row in inverse)
        self._step_v = 2.0 * rail_v / (1 << ADC_BITS)
        quiet = world.scene.sensor.noise_n < FORCE_STEP_N
        self._adc_noise_v = ADC_NOISE_LSB * self._step_v if quiet else 0.0
        self._rng = random.Random(ADC_SEED)
        self._codes: tuple[float, ...] = ()

    def read_voltages(self) -> tuple[float, tuple[float, ...]]:
        started = time.perf_counter()
        world = self.world
        world.advance_to(world.clock.now())
        t_s, load = world.sensor_reading()
        if not (world.faults.sensor_frozen and self._codes):  # frozen: the same codes, freshly stamped
            self._codes = self._digitise(load)
        world.cpu_s += time.perf_counter() - started  # the device's share of the host's tick
        return t_s, self._codes

    def _digitise(self, load) -> tuple[float, ...]:
        f0, f1, f2, f3, f4, f5 = load
        low, high, step = -self.rail_v, self.rail_v - self._step_v, self._step_v
        noise = [self._rng.gauss(0.0, self._adc_noise_v) for _ in range(6)] if self._adc_noise_v else _NO_NOISE
        volts = []
        for r, e in zip(self._inverse, noise):  # inlined digitisation: six gauges every servo tick
            v = r[0] * f0 + r[1] * f1 + r[2] * f2 + r[3] * f3 + r[4] * f4 + r[5] * f5 + e
            if v == v:  # NaN: a broken conversion stays broken, for the host to flag
                v = round((high if v > high else low if v < low else v) / step) * step
            volts.append(v)
        return tuple(volts)


def open_sim_sensor(url: str = "sim", world=None, clock=None, calibration: Calibration | None = None,
                    stale_after_s: float = 0.01, **_ignored) -> DaqSensor:
    """The simulated Nano17 through the DAQ layer (registered as the ``sim`` sensor backend)."""
    from drivers.errors import DriverInitializationError

    if world is None:
        raise DriverInitializationError(f"{url}: the simulated sensor needs a simulated world (a scene)")
    calibration = calibration or load_calibration(SIM_CALIBRATION)
    return DaqSensor(SimDaq(world, calibration), calibration, clock or world.clock, stale_after_s)
