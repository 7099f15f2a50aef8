"""The priors of the parametric hypotheses: stated, proper, the same for every scene (docs/learner.md).

A lump's centre anywhere on the tissue (one centred off it could never be felt
from inside), its radius log-uniform from 0.5 mm to half the tissue's longer
side, its edge sharpness log-uniform, its tail shape uniform, its contrast
log-uniform from `min_contrast` (the softest difference that counts as a lump)
to 1000×, an ellipse's log axis ratio up to log 8; the background's level and
slopes Gaussian (in evidence.py's prior residuals).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from palpd.learner import shapes

MAX_AXIS_RATIO = 8.0
EDGE_SHARPNESS = (2.0, 60.0)
MAX_CONTRAST = 999.0
MIN_RADIUS_MM = 0.5
CENTRE_MARGIN = 0.0  # a lump is centred on the tissue (one centred off it could never be felt from inside)
MAX_RADIUS_FRACTION = 0.5  # of the tissue's longer side: a disc that covers most of it (larger: free-form)
LEVEL_SD, SLOPE_SD = 2.0, 0.25  # background prior: log level around the readings' median; log change per half-size


@dataclass(frozen=True)
class Priors:
    size_mm: tuple[float, float]
    min_contrast: float
    level: float  # centre of the background level's prior (log N/mm)

    @property
    def scale_mm(self) -> float:
        return 0.5 * max(self.size_mm)

    def bounds(self, family: shapes.Family) -> tuple[np.ndarray, np.ndarray]:
        return _bounds(self.size_mm, self.min_contrast, family.kind, family.k)

    def _lump_box(self, ellipse: bool) -> list[tuple[float, float]]:
        margin = CENTRE_MARGIN * max(self.size_mm)
        half_w, half_h = self.size_mm[0] / 2 + margin, self.size_mm[1] / 2 + margin
        radius = (math.log(MIN_RADIUS_MM), math.log(MAX_RADIUS_FRACTION * max(self.size_mm)))
        box = [(-half_w, half_w), (-half_h, half_h), radius]
        if ellipse:
            e = math.log(MAX_AXIS_RATIO)
            box += [(-e, e), (-e, e)]
        return box + [shapes.TAIL_RANGE, tuple(map(math.log, EDGE_SHARPNESS)),
                      (math.log(self.min_contrast), math.log(MAX_CONTRAST))]

    def log_density(self, family: shapes.Family, theta: np.ndarray) -> float:
        """log p(θ) of the uniform lump boxes (the background's Gaussian prior is in its residuals)."""
        lo, hi = self.bounds(family)
        box = np.isfinite(lo)
        return float(-np.sum(np.log(hi[box] - lo[box])))

    def precision(self, family: shapes.Family) -> np.ndarray:
        """Curvature a uniform prior stands for (1 / its variance); zero where the prior is Gaussian."""
        lo, hi = self.bounds(family)
        box = np.isfinite(lo)
        out = np.zeros(family.size)
        out[box] = 12.0 / (hi[box] - lo[box]) ** 2
        return out


@lru_cache(maxsize=64)
def _bounds(size_mm, min_contrast, kind, k) -> tuple[np.ndarray, np.ndarray]:
    """The parameter box of a family (cached: every refit and Kalman step asks for it)."""
    priors = Priors(size_mm, min_contrast, 0.0)
    lo, hi = [-np.inf] * 3, [np.inf] * 3
    for _ in range(k):
        low, high = zip(*priors._lump_box(kind == "ellipses"))
        lo += low
        hi += high
    out = np.array(lo), np.array(hi)
    for array in out:
        array.flags.writeable = False
    return out
