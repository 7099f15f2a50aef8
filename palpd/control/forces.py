"""From sensor samples to the force on the probe in the tissue frame.

``tissue`` rotates all three sensor axes through the arm's kinematics into the
tissue frame (the seed paper's §6.2 fix); ``sensor_z`` reads only the sensor's
z axis, as the paper did, so both can be compared on the same data.
"""
from __future__ import annotations

from drivers.geometry import TissueFrame
from drivers.interfaces import ForceSample
from drivers.phantom import model
from palpd.control.contact import SensorNoise, measure_noise

Vec3 = tuple[float, float, float]


def zero_of(samples: list[ForceSample]) -> Vec3:
    """The sensor's zero: the mean of samples read out of contact, per axis."""
    n = len(samples)
    return tuple(sum(s.force_n[i] for s in samples) / n for i in range(3))  # type: ignore[return-value]


class ForceReader:
    def __init__(self, axes: str, sensor_tilts: bool, q_aligned: Vec3) -> None:
        self.axes = axes
        self.sensor_tilts = sensor_tilts
        self.q_aligned = q_aligned
        self._tilt = model.SensorTilt(q_aligned)
        self.bias_n: Vec3 = (0.0, 0.0, 0.0)
        self.noise: SensorNoise | None = None  # measured at the last tare: contact thresholds scale with it

    def tare(self, samples: list[ForceSample]) -> None:
        """Take the mean of samples read out of contact as the sensor's zero, and measure their noise."""
        self.bias_n = zero_of(samples)
        self.noise = measure_noise(samples) or self.noise

    def tissue_force(self, sample: ForceSample, q: Vec3) -> Vec3:
        f, b = sample.force_n, self.bias_n
        unbiased = (f[0] - b[0], f[1] - b[1], f[2] - b[2])
        if not self.sensor_tilts:
            return unbiased  # a level sensor's axes are the tissue's
        in_base = self._tilt.to_base(q, TissueFrame.vector_to_robot(unbiased))
        return TissueFrame.vector_from_robot(in_base)

    def normal_force(self, sample: ForceSample, q: Vec3, tissue_force: Vec3) -> float:
        """The force pressing the probe out of the tissue, by the configured axes."""
        if self.axes == "sensor_z":
            return sample.force_n[2] - self.bias_n[2]
        return tissue_force[2]
