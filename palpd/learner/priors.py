"""The priors of the parametric hypotheses: stated, proper, the same for every scene (docs/learner.md).

A lump's centre anywhere on the tissue (one centred off it could never be felt
from inside), its radius log-uniform from 0.5 mm to half the tissue's longer
side, its edge sharpness log-uniform, its tail shape uniform (from tails that
end at a finite distance through power-law to Gaussian-like ones), its contrast
log-uniform from `min_contrast` (the softest difference that counts as a lump)
to 1000×, an ellipse's log axis ratio up to log 8; the background's level and
slopes Gaussian (in evidence.py's prior residuals). A soft region (shapes.py) has a circle's
box: its core softer than the tissue around it as a lump's is stiffer, 1 + `min_contrast` to 1000×.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from palpd.learner import shapes

MAX_AXIS_RATIO = 8.0
EDGE_SHARPNESS = (2.0, 60.0)
# A lump felt through tissue has tails that never end (the simulator's, a hard inclusion's); tails that end
# (a cone, a plateau with a ramp: maps made by hand, or a lump at the surface) are the exception the prior
# says they are: each extra lump a hypothesis holds pays for a profile prior spread over both branches.
ENDING_TAILS = 0.1
COMPACT_SHARPNESS_FLOOR = 1.0  # tails that end may rise to a point (a cone: s = 1, c = ½); others stay smooth on top
# Tissue softer in one place (a cyst, a pocket of fat) is the exception, a stiff region what users palpate for:
# a hypothesis with a soft region holds these prior odds against its twin without one (the half-stiff map's
# first 13 readings gave a soft disc over its soft half 7 % at even odds, beside the stiff half's free-form map).
SOFT_REGION_ODDS = 0.1
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
        return _bounds(self.size_mm, self.min_contrast, family.kind, family.k, family.soft)

    def branch_bounds(self, family: shapes.Family, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The box a fit from `theta` (d, or S × d) searches: each lump's tail shape kept on the side of
        the Hill profile (λ = 0) it is on. The two branches meet there with their slopes of opposite
        sign (each thins the tails), so a step across is a kink the solver would stall on; a fit from
        each side competes by evidence instead (shapes.py)."""
        theta = np.asarray(theta, dtype=float)
        tails = theta[..., [part.stop - 3 for part in family.profile_slices()]] < 0.0  # [.., λ, log s, log a|d]
        key = (self.size_mm, self.min_contrast, family.kind, family.k, family.soft)
        if theta.ndim == 1:
            return _branch_bounds(*key, tuple(tails.tolist()))
        boxes = [_branch_bounds(*key, tuple(row)) for row in tails.tolist()]
        return np.array([lo for lo, _ in boxes]), np.array([hi for _, hi in boxes])

    def _lump_box(self, ellipse: bool) -> list[tuple[float, float]]:
        margin = CENTRE_MARGIN * max(self.size_mm)
        half_w, half_h = self.size_mm[0] / 2 + margin, self.size_mm[1] / 2 + margin
        radius = (math.log(MIN_RADIUS_MM), math.log(MAX_RADIUS_FRACTION * max(self.size_mm)))
        box = [(-half_w, half_w), (-half_h, half_h), radius]
        if ellipse:
            e = math.log(MAX_AXIS_RATIO)
            box += [(-e, e), (-e, e)]
        return box + [shapes.TAIL_RANGE, (math.log(COMPACT_SHARPNESS_FLOOR), math.log(EDGE_SHARPNESS[1])),
                      (math.log(self.min_contrast), math.log(MAX_CONTRAST))]

    def log_density(self, family: shapes.Family, theta: np.ndarray) -> float:
        """log p(θ) of the uniform lump boxes (the background's Gaussian prior is in its residuals); a lump's
        tail shape and sharpness uniform within their branch, which is one with tails that end with
        probability ENDING_TAILS; a soft region's prior odds SOFT_REGION_ODDS."""
        lo, hi = self.bounds(family)
        box = np.isfinite(lo)
        log_p = 0.0
        for part in family.profile_slices():
            tail = part.stop - 3
            box[tail:tail + 2] = False
            log_p += _log_profile_density(float(theta[tail]))
        log_p += family.soft * math.log(SOFT_REGION_ODDS)
        return float(log_p - np.sum(np.log(hi[box] - lo[box])))

    def precision(self, family: shapes.Family, theta: np.ndarray) -> np.ndarray:
        """Curvature a uniform prior stands for (1 / its variance) within the branch θ is on; zero where
        the prior is Gaussian."""
        lo, hi = self.branch_bounds(family, theta)
        box = np.isfinite(lo)
        out = np.zeros(family.size)
        out[box] = 12.0 / (hi[box] - lo[box]) ** 2
        return out


def profile_branch(tail: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """The ranges of λ and log s on the side of the Hill profile (λ = 0) that `tail` is on."""
    top = math.log(EDGE_SHARPNESS[1])
    if tail < 0.0:
        return (shapes.TAIL_RANGE[0], 0.0), (math.log(COMPACT_SHARPNESS_FLOOR), top)
    return (0.0, shapes.TAIL_RANGE[1]), (math.log(EDGE_SHARPNESS[0]), top)


@lru_cache(maxsize=2)
def _branch_log_density(compact: bool) -> float:
    (tail_lo, tail_hi), (sharp_lo, sharp_hi) = profile_branch(-1.0 if compact else 0.0)
    share = ENDING_TAILS if compact else 1.0 - ENDING_TAILS
    return math.log(share / ((tail_hi - tail_lo) * (sharp_hi - sharp_lo)))


def _log_profile_density(tail: float) -> float:
    """log p(λ, log s) of a lump's profile: uniform over its branch's box (`profile_branch`), the branches
    weighted by ENDING_TAILS."""
    return _branch_log_density(tail < 0.0)


@lru_cache(maxsize=256)
def _branch_bounds(size_mm, min_contrast, kind, k, soft, compact: tuple) -> tuple[np.ndarray, np.ndarray]:
    """`Priors.branch_bounds` for one parameter vector, its profiles' branches given (cached as `_bounds`:
    every fit, Kalman step and evidence asks for it)."""
    lo, hi = (array.copy() for array in _bounds(size_mm, min_contrast, kind, k, soft))
    family = shapes.Family(kind, k, 1.0, soft)
    for part, ending in zip(family.profile_slices(), compact):
        tail = part.stop - 3
        (lo[tail], hi[tail]), (lo[tail + 1], hi[tail + 1]) = profile_branch(-1.0 if ending else 0.0)
    for array in (lo, hi):
        array.flags.writeable = False
    return lo, hi


@lru_cache(maxsize=64)
def _bounds(size_mm, min_contrast, kind, k, soft) -> tuple[np.ndarray, np.ndarray]:
    """The parameter box of a family (cached: every refit and Kalman step asks for it)."""
    priors = Priors(size_mm, min_contrast, 0.0)
    lo, hi = [-np.inf] * 3, [np.inf] * 3
    for box in [priors._lump_box(kind == "ellipses")] * k + [priors._lump_box(False)] * soft:
        low, high = zip(*box)
        lo += low
        hi += high
    out = np.array(lo), np.array(hi)
    for array in out:
        array.flags.writeable = False
    return out
