"""Stiffness from one palpation's force-displacement samples.

The foundation fits the seed paper's model (§3.1): a straight line by least
squares, whose slope is the stiffness. A fit that cannot be trusted is
rejected with a named reason rather than returned as a number.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MIN_SAMPLES = 3
MIN_RANGE_MM = 1e-3  # below a micrometre of travel, the slope is noise


class FitRejected(ValueError):
    """The samples cannot give a stiffness; str() names the reason."""


@dataclass(frozen=True, slots=True)
class LinearFit:
    stiffness_n_per_mm: float
    intercept_n: float
    stiffness_se_n_per_mm: float
    residual_rms_n: float
    samples: int


def fit_linear(depth_mm, force_n) -> LinearFit:
    """Least-squares line force = k * depth + c; k is the stiffness."""
    d = np.asarray(depth_mm, dtype=float)
    f = np.asarray(force_n, dtype=float)
    if d.shape != f.shape or d.ndim != 1:
        raise FitRejected("depth and force must be 1-D sequences of equal length")
    keep = np.isfinite(d) & np.isfinite(f)
    d, f = d[keep], f[keep]
    if d.size < MIN_SAMPLES:
        raise FitRejected(f"too few samples ({d.size}, need {MIN_SAMPLES})")
    if np.ptp(d) < MIN_RANGE_MM:
        raise FitRejected(f"displacement range {np.ptp(d):.2g} mm is too small")
    centred = d - d.mean()  # centring keeps the normal equations well conditioned
    sxx = float(centred @ centred)
    slope = float(centred @ (f - f.mean())) / sxx
    intercept = float(f.mean() - slope * d.mean())
    residuals = f - (slope * d + intercept)
    dof = d.size - 2
    sigma2 = float(residuals @ residuals) / dof if dof > 0 else 0.0
    if slope <= 0:
        raise FitRejected(f"force does not rise with depth (slope {slope:.3g} N/mm)")
    return LinearFit(slope, intercept, math.sqrt(sigma2 / sxx), math.sqrt(float(residuals @ residuals) / d.size), int(d.size))
