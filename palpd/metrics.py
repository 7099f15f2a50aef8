"""How far an estimate is from the truth (simulated scenes only).

A scene's truth is its `[[lump]]` circles and, for a scene with a measured
map, the regions of the map itself: where the map rises above its tissue level
by at least half `min_contrast`, each region's half-height area (halfway
between the tissue level, the map's 10th percentile, and the region's top), as
a polygon with its centroid and equal-area radius; a region whose half-height
area falls apart (lumps that nearly touch, their tails joined) is a lump per
part (of at least a 0.5 mm lump's area). IoU is the overlap of the
reported boundary polygon with the true disc or polygon, on the tissue when its
size is given: a lump's part off the tissue is nothing a palpation could feel,
and what palpd reports is clipped to the tissue.
"""
from __future__ import annotations

import math

import numpy as np
from matplotlib.path import Path as PolygonPath

IOU_GRID_MM = 0.25
MAX_GRID_POINTS = 1_000_000
MAP_GRID_MM = 0.25
TISSUE_PERCENTILE = 10
SMOOTH_SPACINGS = 0.25  # a measured map is smoothed over this share of its sample spacing, at least
NOISE_SDS = 6.0  # ...and enough that its own noise stays this many sds under the rise that makes a region
MIN_LUMP_AREA_MM2 = math.pi * 0.5**2  # the smallest lump the learner's prior allows (radius 0.5 mm)


def scene_truth(scene, min_contrast: float = 0.3) -> list[dict]:
    """The scene's lumps as placed on the bench, and the measured map's regions."""
    from drivers.sim.scene import truth_lumps

    truth = truth_lumps(scene)
    if scene.tissue.map:
        truth += map_regions(scene.tissue.map, scene.tissue.size_mm, min_contrast, scene.tissue.map_baseline)
    return truth


def map_regions(path, size_mm, min_contrast: float, baseline: float | None = None) -> list[dict]:
    """The truth lumps of a measured map (a map of raw readings given its baseline: the tissue's map_baseline)."""
    from scipy import ndimage
    from scipy.interpolate import griddata

    from drivers.sim.scene import load_stiffness_map

    rows = np.array(load_stiffness_map(path, baseline))
    xs = np.arange(-size_mm[0] / 2, size_mm[0] / 2 + 1e-9, MAP_GRID_MM)
    ys = np.arange(-size_mm[1] / 2, size_mm[1] / 2 + 1e-9, MAP_GRID_MM)
    gx, gy = np.meshgrid(xs, ys)
    k = griddata(rows[:, :2], rows[:, 2], (gx, gy), method="linear")
    k = np.where(np.isfinite(k), k, griddata(rows[:, :2], rows[:, 2], (gx, gy), method="nearest"))
    # A measured map's own noise is not a boundary: smoothed over a quarter of its sample spacing (0.5 mm on
    # a 2 mm grid; a fixed 0.5 mm blurred finer maps' small lumps: a 1 mm lump on a 0.5 mm grid had a
    # half-height radius of 1.39 mm), and more where the samples are noisier than that leaves well below a
    # region's rise: a 60 mm map with 12 % noise per sample had 75 "regions" and no lump.
    spacing, noise = _spacing_and_noise(rows)
    smooth_mm = spacing * max(SMOOTH_SPACINGS, NOISE_SDS * noise / (2.0 * math.sqrt(math.pi) * 0.5 * min_contrast))
    k = ndimage.gaussian_filter(k, smooth_mm / MAP_GRID_MM)
    tissue = float(np.percentile(k, TISSUE_PERCENTILE))
    labels, count = ndimage.label(k > tissue * (1.0 + 0.5 * min_contrast))
    regions = []
    for label in range(1, count + 1):
        peak = float(k[labels == label].max())
        if peak < tissue * (1.0 + min_contrast):
            continue
        # Lumps that nearly touch share one region above the tissue level (their tails join) but not their
        # half-height areas: each of those is a lump of its own (three 5 mm lumps 2-4 mm apart had been one
        # region, its centroid between them). Specks of texture along a boundary are not lumps.
        parts, part_count = ndimage.label((labels == label) & (k >= 0.5 * (tissue + peak)))
        for part in range(1, part_count + 1):
            inside = parts == part
            area = np.count_nonzero(inside) * MAP_GRID_MM**2
            if area < MIN_LUMP_AREA_MM2:
                continue
            regions.append(_region(xs, ys, gx, gy, inside, area, float(k[inside].max())))
    return regions


def _spacing_and_noise(rows: np.ndarray) -> tuple[float, float]:
    """The map's typical distance between neighbouring samples (the median nearest-neighbour distance) and its
    samples' relative noise: each log stiffness against the mean of its four nearest neighbours (a linear
    trend cancels; edges are few), by the median absolute deviation. A Gaussian filter of sd w over samples
    h apart leaves white noise of sd σ·h / (2√π·w)."""
    from scipy.spatial import cKDTree

    from palpd.learner.likelihood import MAD_TO_SD

    points = rows[:, :2]
    distance, index = cKDTree(points).query(points, k=min(5, len(points)))
    nearest = distance[:, 1]
    spacing = float(np.median(nearest[nearest > 0])) if np.any(nearest > 0) else MAP_GRID_MM
    log_k = np.log(rows[:, 2])
    residual = log_k - log_k[index[:, 1:]].mean(axis=1)
    neighbours = index.shape[1] - 1
    return spacing, MAD_TO_SD * float(np.median(np.abs(residual))) / math.sqrt(1.0 + 1.0 / neighbours)


def _region(xs, ys, gx, gy, inside: np.ndarray, area: float, peak: float) -> dict:
    """A truth lump from its half-height area on the map's grid: centroid, equal-area radius, boundary."""
    import contourpy

    z = np.pad(np.where(inside, 1.0, 0.0), 1)
    pad_x = np.concatenate([[xs[0] - 1e-6], xs, [xs[-1] + 1e-6]])
    pad_y = np.concatenate([[ys[0] - 1e-6], ys, [ys[-1] + 1e-6]])
    line = max(contourpy.contour_generator(pad_x, pad_y, z).lines(0.5), key=len)
    return {"center_mm": [round(float(gx[inside].mean()), 3), round(float(gy[inside].mean()), 3)],
            "radius_mm": round(math.sqrt(area / math.pi), 3), "stiffness_n_per_mm": round(peak, 4),
            "boundary_mm": np.round(line, 3).tolist()}


def compare(truth: list[dict], lumps: list[dict], size_mm=None) -> dict:
    """Match true lumps to estimates with the least total centre distance; report errors and IoU (on the tissue,
    given its size). Matched in turn, each true lump taking the nearest estimate left, a scan that found a
    6 mm lump and missed a 1.5 mm one was scored as the small one found 22 mm off and the large one missed."""
    from scipy.optimize import linear_sum_assignment

    distance = np.array([[math.dist(est["center_mm"], true["center_mm"]) for est in lumps] for true in truth])
    distance = np.nan_to_num(distance.reshape(len(truth), len(lumps)), nan=1e9, posinf=1e9)  # the solver takes no NaN
    rows, cols = linear_sum_assignment(distance)
    match = dict(zip(rows.tolist(), cols.tolist()))
    unmatched = [i for i in range(len(lumps)) if i not in match.values()]
    per_lump = []
    for t, true in enumerate(truth):
        if t not in match:
            per_lump.append({"found": False, "radius_mm": true["radius_mm"]})
            continue
        est = lumps[match[t]]
        centre, radius = true["center_mm"], true["radius_mm"]
        if est.get("cut_by_edge") and size_mm is not None:
            centre, radius = part_on_tissue(true, size_mm)  # what such a lump reports
        per_lump.append({
            "found": True,
            "center_error_mm": round(math.dist(est["center_mm"], centre), 3),
            "radius_error_mm": round(abs(est["radius_mm"] - radius), 3),
            "iou": round(iou(est["boundary_mm"], true, size_mm), 4),
            **_depth_error(true, est),
        })
    found = [m for m in per_lump if m["found"]]
    return {
        "lumps_true": len(truth),
        "lumps_found": len(found),
        "lumps_missed": len(truth) - len(found),
        "false_lumps": len(unmatched),
        "max_center_error_mm": max((m["center_error_mm"] for m in found), default=None),
        "max_radius_error_mm": max((m["radius_error_mm"] for m in found), default=None),
        "min_iou": min((m["iou"] for m in found), default=None),
        **({"max_depth_error_mm": max(m["depth_error_mm"] for m in found if "depth_error_mm" in m)}
           if any("depth_error_mm" in m for m in found) else {}),
        "per_lump": per_lump,
    }


def wrong_beyond_claim(m: dict, unfelt_radius_mm: float | None) -> int:
    """How many lumps a scan got wrong beyond what its verdict claims (`m`: compare's): every false lump, and
    every true lump missed whose radius is at least the stated unfelt radius. A verdict of k lumps says "and no
    other larger than the unfelt radius": a smaller lump in the holes between the readings is outside that claim,
    a larger one missed is not (without a stated radius, every miss counts). The count right or wrong is
    compare's; this says which of the wrong ones the verdict itself had not already allowed for."""
    limit = 0.0 if unfelt_radius_mm is None else unfelt_radius_mm
    missed = sum(1 for p in m["per_lump"] if not p["found"] and p["radius_mm"] >= limit)
    return m["false_lumps"] + missed


def _depth_error(true: dict, est: dict) -> dict:
    """A 3-D scene's inclusion (its truth names its shape) against the reported depth: the error, and in sds.
    A 2-D scene's lump depth only widens a drawn edge: no depth to compare with."""
    if "shape" not in true or est.get("depth_mm") is None or true.get("depth_mm") is None:
        return {}
    error = est["depth_mm"] - true["depth_mm"]
    sd = est.get("depth_sd_mm") or 0.0
    return {"depth_error_mm": round(abs(error), 3), "depth_error_sd": round(abs(error) / sd, 2) if sd > 0 else None}


def part_on_tissue(true: dict, size_mm) -> tuple[list[float], float]:
    """The centroid and equal-area radius of a true lump's part on the tissue (its disc, or its outline where it
    has one: a map's region, an inclusion's footprint), as a lump reported `cut_by_edge` gives its own (a 6 mm
    lump centred 4 mm inside a corner was scored 0.94 mm off in centre against the whole circle, though its part
    on the tissue was found within 0.05 mm)."""
    half = np.asarray(size_mm, dtype=float) / 2
    centre, radius = np.asarray(true["center_mm"], dtype=float), float(true["radius_mm"])
    extent = np.asarray(true["boundary_mm"], dtype=float) if true.get("boundary_mm") else \
        np.array([centre - radius, centre + radius])
    low, high = np.maximum(extent.min(axis=0), -half), np.minimum(extent.max(axis=0), half)
    step = IOU_GRID_MM / 2.0
    gx, gy = np.meshgrid(np.arange(low[0] + step / 2, high[0], step), np.arange(low[1] + step / 2, high[1], step))
    points = np.column_stack([gx.ravel(), gy.ravel()])  # cell centres on the tissue
    inside = points[inside_truth(points, true)]
    if not len(inside):
        return [float(v) for v in centre], radius
    return [float(v) for v in inside.mean(axis=0)], math.sqrt(len(inside) * step * step / math.pi)


def iou(boundary_mm: list[list[float]], true: dict, size_mm=None) -> float:
    """Intersection over union of a polygon and the true lump (its polygon, else its disc), on a fine grid (over
    the tissue only, given its size)."""
    polygon = np.asarray(boundary_mm, dtype=float)
    centre, radius = np.asarray(true["center_mm"], dtype=float), float(true["radius_mm"])
    other = np.asarray(true["boundary_mm"], dtype=float) if true.get("boundary_mm") else None
    extent = other if other is not None else np.array([centre - radius, centre + radius])
    low = np.minimum(polygon.min(axis=0), extent.min(axis=0)) - 1.0
    high = np.maximum(polygon.max(axis=0), extent.max(axis=0)) + 1.0
    if size_mm is not None:
        half = np.asarray(size_mm, dtype=float) / 2
        low, high = np.maximum(low, -half), np.minimum(high, half + IOU_GRID_MM)
    points = _grid(low, high)
    return _ratio(PolygonPath(polygon).contains_points(points), inside_truth(points, true))


def region_iou(truth: list[dict], lumps: list[dict], size_mm) -> float:
    """IoU of all reported lump areas against all true ones over the palpable rectangle: a missed lump and a
    false one both cost area; no lump reported where there is none scores 1."""
    reported, true, _ = _regions_on_tissue(truth, lumps, size_mm)
    return _ratio(reported, true) if (reported | true).any() else 1.0


def boundary_error_mm(truth: list[dict], lumps: list[dict], size_mm) -> float | None:
    """The reported boundary's true error in mm, as the learner's expected one is stated: the area reported
    wrongly (inside a lump and not reported, or reported and not inside one) over the palpable rectangle,
    divided by the true boundary's length on it; None with no true lump on the tissue. The length is the
    Cauchy-Crofton estimate from the grid: π/4 × the step × the grid's crossings of the boundary."""
    reported, true, (step, shape) = _regions_on_tissue(truth, lumps, size_mm)
    inside = true.reshape(shape)
    crossings = np.count_nonzero(np.diff(inside, axis=0)) + np.count_nonzero(np.diff(inside, axis=1))
    if not crossings:
        return None
    return float(np.count_nonzero(reported ^ true) * step / (math.pi / 4 * crossings))


def _regions_on_tissue(truth: list[dict], lumps: list[dict], size_mm):
    """(reported, true, (step, grid shape)): which points of a grid over the palpable rectangle lie inside a
    reported lump and inside a true one."""
    half = np.asarray(size_mm, dtype=float) / 2
    points, step, shape = _grid(-half, half + IOU_GRID_MM, with_shape=True)
    reported = np.zeros(len(points), dtype=bool)
    for lump in lumps:
        reported |= PolygonPath(np.asarray(lump["boundary_mm"], dtype=float)).contains_points(points)
    true = np.zeros(len(points), dtype=bool)
    for lump in truth:
        true |= inside_truth(points, lump)
    return reported, true, (step, shape)


def _grid(low, high, with_shape: bool = False):
    # Coarser than IOU_GRID_MM only for a region larger than 250 mm square (a boundary gone astray), which would
    # otherwise need gigabytes
    step = max(IOU_GRID_MM, math.sqrt(float(np.prod(np.asarray(high) - np.asarray(low))) / MAX_GRID_POINTS))
    gx, gy = np.meshgrid(np.arange(low[0], high[0], step), np.arange(low[1], high[1], step))
    points = np.column_stack([gx.ravel(), gy.ravel()])
    return (points, step, gx.shape) if with_shape else points


def inside_truth(points: np.ndarray, true: dict) -> np.ndarray:
    """Which points [[x, y], ...] lie inside a true lump: its outline where it has one, else its disc."""
    if true.get("boundary_mm"):
        return PolygonPath(np.asarray(true["boundary_mm"], dtype=float)).contains_points(points)
    centre = np.asarray(true["center_mm"], dtype=float)
    return np.hypot(points[:, 0] - centre[0], points[:, 1] - centre[1]) <= float(true["radius_mm"])


def _ratio(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 0.0
