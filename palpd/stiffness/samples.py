"""Checking one palpation's samples before any fit: keep what can be trusted, or reject with a reason.

Every rejection names its reason with a short code (`FitRejected.reason`) and a
sentence (str()), so a caller can count them and a person can read them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_SAMPLES = 3
MIN_RANGE_MM = 1e-4  # a tenth of a micrometre: below this the displacement is numerical dust
MAX_SAMPLES = 20_000  # longer traces are thinned evenly, so a fit's time stays bounded
MIN_SLOPE_T = 3.0  # the rise of force with depth must stand 3 standard errors clear of zero

REASONS = ("bad_shape", "too_few_samples", "saturated", "no_range", "constant_force", "reversed", "no_rise",
           "not_converged")


class FitRejected(ValueError):
    """The samples cannot give a stiffness; `reason` is a code from REASONS, str() a sentence."""

    def __init__(self, message: str, reason: str = "bad_shape") -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class Samples:
    """Finite, unsaturated samples, scaled to order one for well-conditioned fits."""

    depth_mm: np.ndarray
    force_n: np.ndarray
    rate_mm_s: np.ndarray | None
    depth_scale_mm: float
    force_scale_n: float
    rate_scale_mm_s: float

    @property
    def n(self) -> int:
        return int(self.depth_mm.size)

    def scaled(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        rate = None if self.rate_mm_s is None else self.rate_mm_s / self.rate_scale_mm_s
        return self.depth_mm / self.depth_scale_mm, self.force_n / self.force_scale_n, rate


def prepare(depth_mm, force_n, rate_mm_s=None, saturated=None) -> Samples:
    d, f = _as_vector(depth_mm, "depth"), _as_vector(force_n, "force")
    if d.shape != f.shape:
        raise FitRejected(f"depth ({d.size}) and force ({f.size}) differ in length", "bad_shape")
    rate = None if rate_mm_s is None else _as_vector(rate_mm_s, "rate")
    if rate is not None and rate.shape != d.shape:
        raise FitRejected(f"rate ({rate.size}) and depth ({d.size}) differ in length", "bad_shape")
    keep = np.isfinite(d) & np.isfinite(f) & (np.abs(d) < 1e12) & (np.abs(f) < 1e12)
    if rate is not None:
        keep &= np.isfinite(rate) & (np.abs(rate) < 1e12)
    if saturated is not None:
        sat = np.asarray(saturated, dtype=bool).reshape(-1)
        if sat.shape != d.shape:
            raise FitRejected(f"saturated mask ({sat.size}) and depth ({d.size}) differ in length", "bad_shape")
        if np.count_nonzero(keep & ~sat) < MIN_SAMPLES <= np.count_nonzero(keep):
            raise FitRejected(f"{np.count_nonzero(sat)} of {d.size} samples saturated the sensor", "saturated")
        keep &= ~sat
    return _checked(d[keep], f[keep], None if rate is None else rate[keep])


def _as_vector(values, what: str) -> np.ndarray:
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise FitRejected(f"{what} samples are not numbers", "bad_shape") from None
    if array.ndim != 1:
        raise FitRejected(f"{what} samples must be a 1-D sequence", "bad_shape")
    return array


def _checked(d: np.ndarray, f: np.ndarray, rate: np.ndarray | None) -> Samples:
    if d.size < MIN_SAMPLES:
        raise FitRejected(f"too few samples ({d.size}, need {MIN_SAMPLES})", "too_few_samples")
    if d.size > MAX_SAMPLES:
        pick = np.linspace(0, d.size - 1, MAX_SAMPLES).astype(int)
        d, f, rate = d[pick], f[pick], None if rate is None else rate[pick]
    d_range = float(np.ptp(d))
    if d_range < MIN_RANGE_MM:
        raise FitRejected(f"displacement range {d_range:.2g} mm is too small", "no_range")
    f_scale = float(np.max(np.abs(f)))
    if np.ptp(f) <= 1e-12 * max(f_scale, 1e-300) or f_scale == 0.0:
        raise FitRejected("force is constant over the palpation", "constant_force")
    d_scale = float(max(np.max(np.abs(d)), d_range))
    r_scale = 1.0 if rate is None else float(np.max(np.abs(rate))) or 1.0
    return Samples(d, f, rate, d_scale, f_scale, r_scale)


def check_rise(samples: Samples) -> None:
    """Reject force that does not rise with depth, judged on a plain straight line."""
    d, f, _ = samples.scaled()
    slope, se = straight_slope(d, f)
    t = slope / se if se > 0 else np.inf * np.sign(slope)
    physical = slope * samples.force_scale_n / samples.depth_scale_mm
    if t < -MIN_SLOPE_T:
        raise FitRejected(f"force does not rise with depth: it falls (slope {physical:.3g} N/mm), reversed loading", "reversed")
    if not t > MIN_SLOPE_T:
        raise FitRejected(f"force does not rise with depth (slope {physical:.3g} N/mm, t = {t:.2g})", "no_rise")


def straight_slope(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """The least-squares slope of y on x (x not constant) and its standard error."""
    xc = x - x.mean()
    sxx = float(xc @ xc)
    slope = float(xc @ (y - y.mean())) / sxx
    residual = y - y.mean() - slope * xc
    return slope, float(np.sqrt(max(float(residual @ residual) / max(x.size - 2, 1), 0.0) / sxx))
