"""Sliding paths for the learner: a segment through the point the learner would probe next, across the
current 50 % boundary, chosen among a few directions by what it is expected to teach per robot second.

What a reading teaches is taken as the binary entropy of P(lump) where it lands (the boundary is where the
map is least sure); a path earns the sum over the readings along it, divided by the robot time it costs
(travel there from where the probe is, the touch-down, the slide).
"""
from __future__ import annotations

import math

import numpy as np

TURNS_DEG = (0.0, 30.0, -30.0, 90.0)  # away from the gradient of P(lump): across the boundary first
TOUCH_DOWN_S = 1.0  # travel settling, approach and press before a path's first reading


def plan_path(learner, centre_xy, length_mm: float, here_xy, costs) -> tuple[tuple[float, float], tuple[float, float]]:
    """(start, end) of the path through centre_xy; costs: (travel_mm_s, sliding_mm_s, reading_spacing_mm)."""
    grid = learner.posterior_grid()
    heading = _across_boundary(grid, centre_xy)
    best, best_gain = None, -math.inf
    for turn in TURNS_DEG:
        angle = heading + math.radians(turn)
        path = _nearer_end_first(_clipped(centre_xy, angle, length_mm, learner.size_mm), here_xy)
        gain = _teaching(grid, path, costs[2]) / _robot_time_s(path, here_xy, costs)
        if gain > best_gain:
            best, best_gain = path, gain
    return best


def _across_boundary(grid, xy) -> float:
    """Direction (rad) of steepest change of P(lump) at xy; along x where the map is flat (or not yet there)."""
    if grid is None:
        return 0.0
    gy, gx = np.gradient(grid.p_lump, grid.ys, grid.xs)
    col = int(np.clip(np.searchsorted(grid.xs, xy[0]), 0, len(grid.xs) - 1))
    row = int(np.clip(np.searchsorted(grid.ys, xy[1]), 0, len(grid.ys) - 1))
    dx, dy = float(gx[row, col]), float(gy[row, col])
    return math.atan2(dy, dx) if math.hypot(dx, dy) > 1e-9 else 0.0


def _clipped(centre, angle: float, length_mm: float, size_mm):
    """The segment of that length and direction through the point, slid along its own line until it lies
    inside the tissue (cut at the edges where the tissue is narrower): it always passes through the point,
    so the spot asked for is read (slid sideways, the same unread spot would be asked for again and again)."""
    ux, uy = math.cos(angle), math.sin(angle)
    lo, hi = _chord(centre, (ux, uy), size_mm)
    half = length_mm / 2.0
    shift = min(max(0.0, lo + half), hi - half) if hi - lo > length_mm else (lo + hi) / 2.0
    a, b = max(lo, shift - half), min(hi, shift + half)
    return ((centre[0] + a * ux, centre[1] + a * uy), (centre[0] + b * ux, centre[1] + b * uy))


def _chord(point, direction, size_mm) -> tuple[float, float]:
    """(t_min, t_max): where the line point + t·direction runs inside the tissue (the point is inside)."""
    lo, hi = -math.inf, math.inf
    for p, d, half in zip(point, direction, (size_mm[0] / 2.0, size_mm[1] / 2.0)):
        p = min(max(p, -half), half)
        if abs(d) > 1e-12:
            t1, t2 = (-half - p) / d, (half - p) / d
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    return lo, hi


def _nearer_end_first(path, here_xy):
    if here_xy is not None and math.dist(here_xy, path[1]) < math.dist(here_xy, path[0]):
        return path[1], path[0]
    return path


def _teaching(grid, path, spacing_mm: float) -> float:
    if grid is None:
        return 1.0
    (x0, y0), (x1, y1) = path
    count = max(2, int(math.dist(path[0], path[1]) / spacing_mm) + 1)
    xs, ys = np.linspace(x0, x1, count), np.linspace(y0, y1, count)
    cols = np.clip(np.searchsorted(grid.xs, xs), 0, len(grid.xs) - 1)
    rows = np.clip(np.searchsorted(grid.ys, ys), 0, len(grid.ys) - 1)
    p = np.clip(grid.p_lump[rows, cols], 1e-9, 1 - 1e-9)
    return float(np.sum(-p * np.log2(p) - (1 - p) * np.log2(1 - p)))


def _robot_time_s(path, here_xy, costs) -> float:
    travel_mm_s, sliding_mm_s, _ = costs
    travel = 0.0 if here_xy is None else math.dist(here_xy, path[0])
    return TOUCH_DOWN_S + travel / travel_mm_s + math.dist(path[0], path[1]) / sliding_mm_s
