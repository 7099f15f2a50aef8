"""The stiffness threshold τ between lump and tissue, learned from the data (unsupervised).

Whether there is a lump at all is decided by a test, never by a fraction of
the range: the stiffness values are split into the two groups of least
within-group variance, and the split is a real contrast only when the stiff
group is at least `min_contrast` stiffer and its median lies so far above the
soft group's that the soft group's own spread (robust: median absolute
deviation, as the soft group holds the boundary's in-between values) would put
it there less than once in a thousand scans (normal tail, corrected for the
number of points). An active learner probes few lump points, so a test on the
stiff group's spread (a t-test) would miss real lumps for lack of them. With contrast, the tissue level is the median of
the soft group and each lump gets its own τ halfway between the tissue and
its own peak: its 50 % (half-height) boundary, so a soft lump next to a hard
one is neither shrunk nor grown by the other. Without contrast, τ is the
softest stiffness that would count as a lump, so P(lump) tells how sure we
are that none hides where we have not probed.

Supervised (τ learned from a training set, see training.py), τ is that one
value everywhere, and there is a lump only where a point lies above it by more
than its own noise could explain (same false-lump rate).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.special import ndtri

FALSE_LUMP_RATE = 1e-3

EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class Levels:
    tissue_n_per_mm: float
    tau_n_per_mm: float  # global τ: lump detection
    contrast: bool       # the contrast test found real lump and tissue groups
    supervised: bool = False  # τ came from a training set: one τ everywhere, no per-lump half-height


def levels(k: np.ndarray, min_contrast: float) -> Levels:
    k = np.sort(np.asarray(k, dtype=float))
    soft, stiff = _two_groups(k)
    if not _real_contrast(soft, stiff, min_contrast):
        tissue = float(np.median(k))
        return Levels(tissue, tissue * (1.0 + min_contrast), False)
    tissue, _ = _tissue_level(soft)
    return Levels(tissue, 0.5 * (tissue + float(np.median(stiff))), True)


def supervised_levels(k: np.ndarray, sd: np.ndarray, tau_n_per_mm: float) -> Levels:
    """Levels at a τ learned from a training set; contrast when some point is surely above it."""
    k, sd = np.asarray(k, dtype=float), np.asarray(sd, dtype=float)
    below = k[k <= tau_n_per_mm]
    tissue = float(np.median(below)) if below.size else min(float(k.min()), tau_n_per_mm)
    return Levels(tissue, tau_n_per_mm, bool(np.any(_surely_above(k, sd, tau_n_per_mm))), supervised=True)


def lump_points(k: np.ndarray, sd: np.ndarray, lv: Levels) -> np.ndarray:
    """Which observed points count as evidence of a lump (a region needs one to be reported)."""
    return _surely_above(k, sd, lv.tau_n_per_mm) if lv.supervised else np.asarray(k) > lv.tau_n_per_mm


def _surely_above(k: np.ndarray, sd: np.ndarray, tau_n_per_mm: float) -> np.ndarray:
    z = float(ndtri(1.0 - FALSE_LUMP_RATE / max(np.size(k), 1)))
    return np.asarray(k) - z * np.asarray(sd) > tau_n_per_mm


def _tissue_level(soft: np.ndarray) -> tuple[float, float]:
    """Level and robust spread of plain tissue: the soft group with the boundary's in-between values
    clipped away from above (an active learner probes the boundary a lot, which would pull the median up)."""
    keep = soft
    for _ in range(10):
        level = float(np.median(keep))
        spread = 1.4826 * float(np.median(np.abs(keep - level)))
        clipped = soft[soft <= level + 3.0 * spread]
        if clipped.size == keep.size or clipped.size < 3:
            break
        keep = clipped
    return level, spread


def _two_groups(sorted_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The split of sorted values into two groups of least total within-group sum of squares."""
    n = sorted_k.size
    if n < 2:
        return sorted_k, sorted_k[:0]
    i = np.arange(1, n)
    cumsum, cumsq = np.cumsum(sorted_k), np.cumsum(sorted_k**2)
    low_ss = cumsq[:-1] - cumsum[:-1] ** 2 / i
    high_ss = (cumsq[-1] - cumsq[:-1]) - (cumsum[-1] - cumsum[:-1]) ** 2 / (n - i)
    split = int(i[np.argmin(low_ss + high_ss)])
    return sorted_k[:split], sorted_k[split:]


def _real_contrast(soft: np.ndarray, stiff: np.ndarray, min_contrast: float) -> bool:
    if soft.size < 3 or stiff.size == 0:
        return False
    tissue, spread = _tissue_level(soft)
    if np.median(stiff) < (1.0 + min_contrast) * tissue:
        return False
    z = float(ndtri(1.0 - FALSE_LUMP_RATE / (soft.size + stiff.size)))
    return float(np.median(stiff)) - tissue > z * spread


def tau_field(mean: np.ndarray, lv: Levels, reach_cells: float, obs_cells: np.ndarray, obs_k: np.ndarray) -> np.ndarray:
    """τ on the grid: each lump's half-height within `reach_cells` of it, the global τ elsewhere.

    A lump's peak is its stiffest observed point (obs_cells are (row, col) grid indices), not the
    model's maximum: a GP overshoots a flat top with a sharp edge.
    """
    tau = np.full(mean.shape, lv.tau_n_per_mm)
    if not lv.contrast or lv.supervised:
        return tau
    labels, count = ndimage.label(mean > lv.tau_n_per_mm, EIGHT_CONNECTED)
    if count == 0:
        return tau
    peaks = np.asarray(ndimage.maximum(mean, labels, index=np.arange(1, count + 1)))
    observed = np.full(count + 1, -np.inf)
    np.maximum.at(observed, labels[obs_cells[:, 0], obs_cells[:, 1]], obs_k)
    peaks = np.where(np.isfinite(observed[1:]), observed[1:], peaks)
    half_heights = np.concatenate([[lv.tau_n_per_mm], 0.5 * (lv.tissue_n_per_mm + np.asarray(peaks))])
    distance, (iy, ix) = ndimage.distance_transform_edt(labels == 0, return_indices=True)
    nearest = labels[iy, ix]
    return np.where(distance <= reach_cells, half_heights[nearest], tau)
