"""Levels for the free-form map: the tissue's stiffness and the threshold τ a lump's boundary lies at.

Whether there is a lump is decided by the evidence (hypotheses.py), not here.
Here the free-form map (the GP) gets its levels: the tissue level is the soft
group's robust median (the readings split into the two groups of least
within-group variance, with the boundary's in-between values clipped away, as
an active learner probes the boundary a lot); a region is a candidate lump
where the map rises `min_contrast` above it, and each region's boundary is its
own half-height, halfway between the tissue and its stiffest reading, so a soft
lump next to a hard one is neither shrunk nor grown by the other.

Supervised (τ learned from a training set, see training.py), τ is that one
value everywhere, and a reading backs a lump only when it lies above τ by more
than its own noise could explain (a false-lump rate of FALSE_LUMP_RATE per scan).
"""
from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
from scipy import ndimage

from palpd.estimate import FALSE_LUMP_RATE

EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class Levels:
    tissue_n_per_mm: float
    tau_n_per_mm: float  # global τ: where a candidate lump region starts
    supervised: bool = False  # τ came from a training set: one τ everywhere, no per-lump half-height


def free_form_levels(k: np.ndarray, min_contrast: float) -> Levels:
    tissue = tissue_level(np.asarray(k, dtype=float))
    return Levels(tissue, tissue * (1.0 + min_contrast))


def supervised_levels(k: np.ndarray, tau_n_per_mm: float) -> Levels:
    k = np.asarray(k, dtype=float)
    below = k[k <= tau_n_per_mm]
    tissue = float(np.median(below)) if below.size else min(float(k.min()), tau_n_per_mm)
    return Levels(tissue, tau_n_per_mm, supervised=True)


def lump_points(k: np.ndarray, sd: np.ndarray, lv: Levels) -> np.ndarray:
    """Which readings count as evidence of a lump (a region needs one to be a candidate)."""
    return surely_above(k, sd, lv.tau_n_per_mm) if lv.supervised else np.asarray(k) > lv.tau_n_per_mm


def surely_above(k: np.ndarray, sd: np.ndarray, tau_n_per_mm: float) -> np.ndarray:
    z = NormalDist().inv_cdf(1.0 - FALSE_LUMP_RATE / max(np.size(k), 1))
    return np.asarray(k) - z * np.asarray(sd) > tau_n_per_mm


def tissue_level(k: np.ndarray) -> float:
    """The soft group's median with the boundary's in-between values clipped away from above."""
    soft = _two_groups(np.sort(k))[0] if k.size >= 3 else k
    keep = soft
    for _ in range(10):
        level = float(np.median(keep))
        spread = 1.4826 * float(np.median(np.abs(keep - level)))
        clipped = soft[soft <= level + 3.0 * spread]
        if clipped.size == keep.size or clipped.size < 3:
            break
        keep = clipped
    return level


def _two_groups(sorted_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The split of sorted values into two groups of least total within-group sum of squares."""
    n = sorted_k.size
    i = np.arange(1, n)
    cumsum, cumsq = np.cumsum(sorted_k), np.cumsum(sorted_k**2)
    low_ss = cumsq[:-1] - cumsum[:-1] ** 2 / i
    high_ss = (cumsq[-1] - cumsq[:-1]) - (cumsum[-1] - cumsum[:-1]) ** 2 / (n - i)
    split = int(i[np.argmin(low_ss + high_ss)])
    return sorted_k[:split], sorted_k[split:]


def tau_field(mean: np.ndarray, lv: Levels, reach_mm: float, steps_mm: tuple[float, float], obs_cells: np.ndarray,
              obs_k: np.ndarray) -> np.ndarray:
    """τ on the grid (its cells `steps_mm` = (dy, dx) apart): each region's half-height within `reach_mm` of it,
    the global τ elsewhere.

    A region's peak is its stiffest reading (obs_cells are (row, col) grid indices), not the
    map's maximum: a GP overshoots a flat top with a sharp edge.
    """
    tau = np.full(mean.shape, lv.tau_n_per_mm)
    if lv.supervised:
        return tau
    labels, count = ndimage.label(mean > lv.tau_n_per_mm, EIGHT_CONNECTED)
    if count == 0:
        return tau
    peaks = np.asarray(ndimage.maximum(mean, labels, index=np.arange(1, count + 1)))
    observed = np.full(count + 1, -np.inf)
    np.maximum.at(observed, labels[obs_cells[:, 0], obs_cells[:, 1]], obs_k)
    peaks = np.where(np.isfinite(observed[1:]), observed[1:], peaks)
    half_heights = np.concatenate([[lv.tau_n_per_mm], 0.5 * (lv.tissue_n_per_mm + np.asarray(peaks))])
    distance, (iy, ix) = ndimage.distance_transform_edt(labels == 0, sampling=steps_mm, return_indices=True)
    nearest = labels[iy, ix]
    return np.where(distance <= reach_mm, half_heights[nearest], tau)
