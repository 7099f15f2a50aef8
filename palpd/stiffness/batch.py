"""Many palpations at once, for replays and studies.

`linear_batch` solves the straight-line fits of every trace in one set of
array operations (traces padded with NaN to a common length); `fit_batch`
runs model selection trace by trace and returns each result or its rejection.
"""
from __future__ import annotations

import numpy as np

from palpd.stiffness.samples import MIN_RANGE_MM, MIN_SAMPLES, MIN_SLOPE_T, FitRejected
from palpd.stiffness.selection import StiffnessResult, fit_stiffness


def linear_batch(depth_mm, force_n) -> dict[str, np.ndarray]:
    """Per row: k, intercept, se of k, samples used; NaN k where the row gives no stiffness."""
    d, f = np.atleast_2d(np.asarray(depth_mm, dtype=float)), np.atleast_2d(np.asarray(force_n, dtype=float))
    if d.shape != f.shape:
        raise ValueError(f"depth {d.shape} and force {f.shape} arrays differ in shape")
    keep = np.isfinite(d) & np.isfinite(f)
    n = keep.sum(axis=1)
    d0, f0 = np.where(keep, d, 0.0), np.where(keep, f, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        d_mean, f_mean = d0.sum(axis=1) / n, f0.sum(axis=1) / n
        dc = np.where(keep, d - d_mean[:, None], 0.0)
        fc = np.where(keep, f - f_mean[:, None], 0.0)
        sxx = (dc * dc).sum(axis=1)
        k = (dc * fc).sum(axis=1) / sxx
        resid = np.where(keep, fc - k[:, None] * dc, 0.0)
        se = np.sqrt((resid * resid).sum(axis=1) / np.maximum(n - 2, 1) / sxx)
        d_range = np.where(keep, d, -np.inf).max(axis=1) - np.where(keep, d, np.inf).min(axis=1)
        usable = (n >= MIN_SAMPLES) & (d_range >= MIN_RANGE_MM) & np.isfinite(k) & (k > MIN_SLOPE_T * se)
    k = np.where(usable, k, np.nan)
    return {"stiffness_n_per_mm": k, "intercept_n": np.where(usable, f_mean - k * d_mean, np.nan),
            "stiffness_se_n_per_mm": np.where(usable, se, np.nan), "samples": n}


def fit_batch(traces, **options) -> list[StiffnessResult | FitRejected]:
    """traces: (depth_mm, force_n) or (depth_mm, force_n, rate_mm_s) per palpation."""
    results: list[StiffnessResult | FitRejected] = []
    for trace in traces:
        try:
            results.append(fit_stiffness(*trace, **options))
        except FitRejected as exc:
            results.append(exc)
    return results
