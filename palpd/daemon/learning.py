"""The daemon's estimator: the one place where the online learner will replace the §3.4 batch estimate.

Anything with observe(xy_mm, stiffness_n_per_mm, sd) and estimate() -> dict fits
here; `make_estimator` is the single switch (the learner issue plugs its class in).
"""
from __future__ import annotations

from palpd.estimate import estimate_lumps


class BatchEstimator:
    """Re-runs the seed paper's §3.4 estimate over every good palpation so far."""

    def __init__(self, min_contrast: float) -> None:
        self.min_contrast = min_contrast
        self.xy_mm: list[tuple[float, float]] = []
        self.k_n_per_mm: list[float] = []

    def observe(self, xy_mm, stiffness_n_per_mm: float | None, sd_n_per_mm: float = 0.0) -> None:
        if stiffness_n_per_mm is not None:  # a rejected fit tells nothing about stiffness
            self.xy_mm.append(tuple(xy_mm))
            self.k_n_per_mm.append(stiffness_n_per_mm)

    def estimate(self) -> dict:
        """Fields of the bus `estimate` event (points, lumps)."""
        lumps = estimate_lumps(self.xy_mm, self.k_n_per_mm, self.min_contrast) if self.xy_mm else []
        return {"points": len(self.xy_mm), "lumps": [lump.as_dict() for lump in lumps]}


def make_estimator(settings) -> BatchEstimator:
    return BatchEstimator(settings.scan.min_contrast)
