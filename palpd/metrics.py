"""How far an estimate is from the truth (simulated scenes only)."""
from __future__ import annotations

import math

import numpy as np
from matplotlib.path import Path as PolygonPath

IOU_GRID_MM = 0.25


def compare(truth: list[dict], lumps: list[dict]) -> dict:
    """Match each true lump to the nearest unmatched estimate; report errors and IoU."""
    unmatched = list(range(len(lumps)))
    per_lump = []
    for true in truth:
        if not unmatched:
            per_lump.append({"found": False})
            continue
        best = min(unmatched, key=lambda i: math.dist(lumps[i]["center_mm"], true["center_mm"]))
        unmatched.remove(best)
        est = lumps[best]
        per_lump.append({
            "found": True,
            "center_error_mm": round(math.dist(est["center_mm"], true["center_mm"]), 3),
            "radius_error_mm": round(abs(est["radius_mm"] - true["radius_mm"]), 3),
            "iou": round(iou(est["boundary_mm"], true["center_mm"], true["radius_mm"]), 4),
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
        "per_lump": per_lump,
    }


def iou(boundary_mm: list[list[float]], center_mm, radius_mm: float) -> float:
    """Intersection over union of a polygon and a disc, counted on a fine grid."""
    polygon = np.asarray(boundary_mm, dtype=float)
    low = np.minimum(polygon.min(axis=0), np.asarray(center_mm) - radius_mm) - 1.0
    high = np.maximum(polygon.max(axis=0), np.asarray(center_mm) + radius_mm) + 1.0
    xs = np.arange(low[0], high[0], IOU_GRID_MM)
    ys = np.arange(low[1], high[1], IOU_GRID_MM)
    gx, gy = np.meshgrid(xs, ys)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    in_polygon = PolygonPath(polygon).contains_points(points)
    in_disc = np.hypot(points[:, 0] - center_mm[0], points[:, 1] - center_mm[1]) <= radius_mm
    union = np.count_nonzero(in_polygon | in_disc)
    return float(np.count_nonzero(in_polygon & in_disc) / union) if union else 0.0
