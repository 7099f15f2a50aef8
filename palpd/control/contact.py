"""Contact thresholds that scale with the sensor: what the tare measured, not a fixed number of newtons.

The tare (samples read out of contact) measures the force noise, as a standard deviation about a straight
line through the samples, and the drift, that line's slope. Contact is detected on the force low-passed
over `contact_filter_s`, whose noise is the raw noise times sqrt((1 - a) / (1 + a)) for a first-order filter
with a = exp(-period / contact_filter_s): the thresholds are `contact_on_sd` and `contact_off_sd` of those
filtered standard deviations (hysteresis), never below the configured `contact_on_n` and `contact_off_n`.
A quiet sensor keeps the configured thresholds; a noisy one (0.3 N) raises them above what its noise can
reach, and the contact point is then found again from the whole trace (palpd.control.onset).
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SensorNoise:
    """What a tare measured: force noise sd (N, per axis) and drift (N/s, the largest axis)."""

    sd_n: float
    drift_n_per_s: float
    samples: int

    def as_dict(self) -> dict:
        return {"noise_sd_n": round(self.sd_n, 5), "drift_n_per_s": round(self.drift_n_per_s, 5),
                "samples": self.samples}


@dataclass(frozen=True)
class ContactThresholds:
    on_n: float
    off_n: float
    filter_s: float
    noise_sd_n: float | None = None  # the raw noise they were scaled from (None: the configured floors)


def measure_noise(samples) -> SensorNoise | None:
    """Noise and drift of tare samples (ForceSample-like: t_s, force_n), each axis detrended by a line."""
    finite = [s for s in samples if all(math.isfinite(v) for v in s.force_n) and math.isfinite(s.t_s)]
    if len(finite) < 10:
        return None
    t = [s.t_s for s in finite]
    variances, slopes = [], []
    for axis in range(3):
        slope, residual_var = _line(t, [s.force_n[axis] for s in finite])
        variances.append(residual_var)
        slopes.append(abs(slope))
    return SensorNoise(math.sqrt(sum(variances) / 3.0), max(slopes), len(finite))


def _line(t: list[float], y: list[float]) -> tuple[float, float]:
    """Least-squares slope and residual variance of y against t."""
    n = len(t)
    t_mean, y_mean = sum(t) / n, sum(y) / n
    stt = sum((ti - t_mean) ** 2 for ti in t)
    slope = sum((ti - t_mean) * (yi - y_mean) for ti, yi in zip(t, y)) / stt if stt > 0 else 0.0
    rss = sum((yi - y_mean - slope * (ti - t_mean)) ** 2 for ti, yi in zip(t, y))
    return slope, rss / max(n - 2, 1)


def filtered_sd(noise_sd_n: float, filter_s: float, rate_hz: float) -> float:
    """The sd of white noise after a first-order low-pass of time constant filter_s, sampled at rate_hz."""
    if filter_s <= 0:
        return noise_sd_n
    a = math.exp(-1.0 / (rate_hz * filter_s))
    return noise_sd_n * math.sqrt((1.0 - a) / (1.0 + a))


def contact_thresholds(palpation, noise: SensorNoise | None, rate_hz: float) -> ContactThresholds:
    """palpation: PalpationSettings. Without a measured noise, the configured thresholds as they are."""
    p = palpation
    if noise is None:
        return ContactThresholds(p.contact_on_n, p.contact_off_n, p.contact_filter_s)
    sd = filtered_sd(noise.sd_n, p.contact_filter_s, rate_hz)
    return ContactThresholds(max(p.contact_on_n, p.contact_on_sd * sd), max(p.contact_off_n, p.contact_off_sd * sd),
                             p.contact_filter_s, noise.sd_n)


def tare_summary(forces, palpation, rate_hz: float) -> dict:
    """What a tare found (the zero per axis, the noise and drift it measured) and the contact thresholds those
    set: the scan report's `sensor.tare`, so a reader sees why contact was judged where it was."""
    th = contact_thresholds(palpation, forces.noise, rate_hz)
    measured = forces.noise.as_dict() if forces.noise is not None else {"noise_sd_n": None, "drift_n_per_s": None}
    return {"bias_n": [round(v, 5) for v in forces.bias_n], **measured,
            "contact_on_n": round(th.on_n, 4), "contact_off_n": round(th.off_n, 4)}
