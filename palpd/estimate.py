"""Lumps from stiffness points by the seed paper's §3.4 method.

A stiffness threshold splits lump from tissue points (here learned from the
data by a two-group split, with a test that the contrast is real so plain
tissue never grows a lump); each connected group of lump points is a lump
whose centre is the mean of its points and whose radius is the distance
threshold a linear SVM finds between its points and the rest.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

# Stiff readings the tissue's own scatter would give this often per scan are not taken for a lump
# (the paper's method here, and the learner's lump evidence).
FALSE_LUMP_RATE = 1e-3
BOUNDARY_VERTICES = 48


@dataclass(frozen=True)
class LumpEstimate:
    center_mm: tuple[float, float]
    radius_mm: float  # an ellipse's is its equal-area radius, √(major·minor)
    center_sd_mm: float
    radius_sd_mm: float
    boundary_mm: list[list[float]]
    axes_mm: tuple[float, float] | None = None  # ellipse: (major, minor) semi-axes
    axes_sd_mm: tuple[float, float] | None = None
    angle_deg: float | None = None  # ellipse: major axis from +x, in [0, 180)
    angle_sd_deg: float | None = None
    edge_mm: float | None = None  # where modelled: 75 % to 25 % of the lump's height along a radius
    edge_sd_mm: float | None = None
    boundary_sd_mm: float | None = None  # free-form or cut: the boundary's position sd, RMS along it (on the tissue)
    cut_by_edge: bool = False  # mostly off the tissue: centre and radius are of its part on the tissue
    depth_mm: float | None = None  # where modelled: its top below the surface, from how it is felt (learner.depth)
    depth_sd_mm: float | None = None

    def as_dict(self) -> dict:
        out = {
            "center_mm": [round(v, 3) for v in self.center_mm],
            "radius_mm": round(self.radius_mm, 3),
            "center_sd_mm": round(self.center_sd_mm, 3),
            "radius_sd_mm": round(self.radius_sd_mm, 3),
            "boundary_mm": [[round(x, 3), round(y, 3)] for x, y in self.boundary_mm],
        }
        for name in ("axes_mm", "axes_sd_mm"):
            if getattr(self, name) is not None:
                out[name] = [round(v, 3) for v in getattr(self, name)]
        for name in ("angle_deg", "angle_sd_deg", "edge_mm", "edge_sd_mm", "boundary_sd_mm", "depth_mm", "depth_sd_mm"):
            if getattr(self, name) is not None:
                out[name] = round(getattr(self, name), 3)
        if self.cut_by_edge:
            out["cut_by_edge"] = True
        return out


def stiffness_threshold(k: np.ndarray, min_contrast: float) -> float | None:
    """The stiffness splitting lump from tissue, or None when there is no real contrast."""
    k = np.sort(np.asarray(k, dtype=float))
    if k.size < 3:
        return None
    split = _best_two_group_split(k)
    low, high = k[:split], k[split:]
    if high.mean() < (1.0 + min_contrast) * low.mean() or not _groups_differ(low, high):
        return None
    return 0.5 * (low.max() + high.min())


def estimate_lumps(xy_mm, k, min_contrast: float = 0.3) -> list[LumpEstimate]:
    xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    k = np.asarray(k, dtype=float)
    threshold = stiffness_threshold(k, min_contrast)
    if threshold is None:
        return []
    is_lump = k > threshold
    spacing = _typical_spacing(xy)
    groups = _connected_groups(xy[is_lump], 1.6 * spacing)
    centres = np.array([g.mean(axis=0) for g in groups])
    owner = np.argmin(np.linalg.norm(xy[:, None, :] - centres[None, :, :], axis=2), axis=1)
    return [
        _one_lump(xy[owner == i], is_lump[owner == i], group, spacing) for i, group in enumerate(groups)
    ]


def unfelt_radius_mm(xy_mm, size_mm, step_mm: float = 0.5) -> float:
    """The farthest any spot of the tissue (on a step_mm lattice, edges included) lies from a reading: a lump
    whose disc holds no reading may be felt by none, so "no lump" rules out only lumps wider than this. (The
    learner keeps the same distance up to date reading by reading, coverage.Readings; this is a fixed plan's,
    once at its end.)"""
    readings = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    if not len(readings):
        return math.inf
    xs = np.linspace(-size_mm[0] / 2, size_mm[0] / 2, max(2, round(size_mm[0] / step_mm) + 1))
    ys = np.linspace(-size_mm[1] / 2, size_mm[1] / 2, max(2, round(size_mm[1] / step_mm) + 1))
    gx, gy = np.meshgrid(xs, ys)
    spots = np.column_stack([gx.ravel(), gy.ravel()])
    distance = np.full(len(spots), np.inf)
    for x, y in readings:  # a few hundred readings at most: no tree needed
        np.minimum(distance, np.hypot(spots[:, 0] - x, spots[:, 1] - y), out=distance)
    return float(distance.max())


def circle_polygon(center: tuple[float, float], radius: float, vertices: int = BOUNDARY_VERTICES) -> list[list[float]]:
    """A closed polygon (first vertex repeated last) approximating a circle."""
    angles = np.linspace(0.0, 2.0 * math.pi, vertices + 1)
    return [[center[0] + radius * math.cos(a), center[1] + radius * math.sin(a)] for a in angles]


def _one_lump(xy: np.ndarray, is_lump: np.ndarray, group: np.ndarray, spacing: float) -> LumpEstimate:
    centre = group.mean(axis=0)
    distance = np.linalg.norm(xy - centre, axis=1)
    inside, outside = distance[is_lump], distance[~is_lump]
    if outside.size == 0:  # every nearby probe is stiff: the lump reaches past what was probed
        radius, gap = float(inside.max() + spacing / 2), spacing
    else:
        radius = _svm_radius(distance, is_lump, spacing)
        if not 0.0 < radius <= float(distance.max()):
            # The stiff points are not the ones nearest their centre (lumps a coarse grid linked into one group,
            # around a soft point): no distance separates them, and the SVM's boundary lies anywhere (a raster
            # of 35 on 80 mm tissue with three lumps gave -17 462 mm). The disc that holds them all instead.
            radius = float(inside.max() + spacing / 2)
        gap = max(float(outside.min() - inside.max()), 0.0) or spacing / 2
    centre_sd = max(float(group.std(axis=0).mean() / math.sqrt(len(group))), spacing / math.sqrt(12 * len(group)))
    return LumpEstimate(
        (float(centre[0]), float(centre[1])), radius, centre_sd, gap / math.sqrt(12.0), circle_polygon(tuple(centre), radius)
    )


def _svm_radius(distance: np.ndarray, is_lump: np.ndarray, spacing: float) -> float:
    """The distance at which a linear SVM separates lump points from the rest (paper §3.4)."""
    # In units of the probe spacing the margin is order one, so a hard-ish C gives the max-margin midpoint.
    from sklearn.svm import SVC  # here: sklearn costs a scan process a third of a second to import

    scale = spacing
    svm = SVC(kernel="linear", C=1e4).fit((distance / scale)[:, None], is_lump.astype(int))
    return float(-svm.intercept_[0] / svm.coef_[0, 0] * scale)


def _best_two_group_split(sorted_k: np.ndarray) -> int:
    """Index splitting sorted values into two groups of least total within-group variance."""
    n = sorted_k.size
    cumsum, cumsq = np.cumsum(sorted_k), np.cumsum(sorted_k**2)
    best, best_cost = 1, math.inf
    for i in range(1, n):
        low_var = cumsq[i - 1] - cumsum[i - 1] ** 2 / i
        high_sum, high_sq = cumsum[-1] - cumsum[i - 1], cumsq[-1] - cumsq[i - 1]
        cost = low_var + high_sq - high_sum**2 / (n - i)
        if cost < best_cost:
            best, best_cost = i, cost
    return best


def _groups_differ(low: np.ndarray, high: np.ndarray) -> bool:
    """Whether every stiff point is one the tissue's own scatter could not give: above the soft group's
    level by more than z robust sds, with z set by the learner's false-lump rate over all the points.
    (A test of the two means asked the wrong question: four probes on a 6x lump among 45 on tissue
    failed it, p = 0.002 with three degrees of freedom, and a raster scan reported no lump.)"""
    level = float(np.median(low))
    spread = 1.4826 * float(np.median(np.abs(low - level)))  # boundary values in the soft group leave it be
    if spread == 0.0 and low.size >= 2:
        spread = float(low.std(ddof=1))
    if spread == 0.0:  # noise-free tissue: any stiffer point passed the contrast check already
        return bool(high.min() > level)
    z = NormalDist().inv_cdf(1.0 - FALSE_LUMP_RATE / (low.size + high.size))
    return bool(high.min() - level > z * spread)


def _typical_spacing(xy: np.ndarray) -> float:
    if len(xy) < 2:
        return 1.0
    from scipy.spatial import cKDTree

    distances, _ = cKDTree(xy).query(xy, k=2)
    return float(np.median(distances[:, 1])) or 1.0


def _connected_groups(points: np.ndarray, link_mm: float) -> list[np.ndarray]:
    if len(points) == 1:
        return [points]
    from scipy.cluster.hierarchy import fcluster, linkage  # here: scipy.cluster imports scipy.stats (slow)

    labels = fcluster(linkage(points, method="single"), t=link_mm, criterion="distance")
    return [points[labels == label] for label in np.unique(labels)]
