"""The simulated tissue: a felt stiffness field and the Hunt-Crossley contact law."""
from __future__ import annotations

import math

import numpy as np

from drivers.sim.scene import Scene, map_rows

MAP_GRID_MM = 0.5
OVERSHOOT_SHARE = 0.1  # of a measured map's range: how far past the readings around it a cell may lie


def lump_profile(r_mm: float, radius_mm: float, sharpness: float) -> float:
    """1 over the centre, exactly 0.5 at the radius, smoothly down to 0 outside."""
    return 1.0 / (1.0 + (r_mm / radius_mm) ** sharpness)


def lump_sharpness(radius_mm: float, depth_mm: float) -> float:
    # The edge is about (1 + depth) mm wide: a deeper lump is felt through more tissue, so it blurs.
    return max(2.0, 4.0 * radius_mm / (1.0 + depth_mm))


class StiffnessField:
    """Felt stiffness k(x, y) in the tissue's own frame (N/mm^n)."""

    def __init__(self, scene: Scene) -> None:
        self.background_n_per_mm = scene.tissue.stiffness_n_per_mm
        self._lumps = [
            (l.center_mm[0], l.center_mm[1], l.radius_mm, lump_sharpness(l.radius_mm, l.depth_mm), l.stiffness_n_per_mm)
            for l in scene.lump
        ]
        self._map = _GridMap(map_rows(scene.tissue), scene.tissue.size_mm) if scene.tissue.map else None

    def background_at(self, x_mm: float, y_mm: float) -> float:
        return self._map.value(x_mm, y_mm) if self._map else self.background_n_per_mm

    def k_at(self, x_mm: float, y_mm: float) -> float:
        base = self.background_at(x_mm, y_mm)
        strongest = 0.0
        for cx, cy, radius, sharpness, k_lump in self._lumps:
            contribution = (k_lump - base) * lump_profile(math.hypot(x_mm - cx, y_mm - cy), radius, sharpness)
            if abs(contribution) > abs(strongest):
                strongest = contribution
        return base + strongest


def hunt_crossley_n(k: float, exponent: float, damping: float, depth_mm: float, rate_mm_s: float) -> float:
    """Contact force (N) for indentation depth_mm at rate_mm_s; the tissue pushes, never pulls."""
    if depth_mm <= 0.0:
        return 0.0
    power = depth_mm if exponent == 1.0 else depth_mm**exponent
    return max(0.0, k * power + damping * power * rate_mm_s)


def sliding_friction_n(normal_n: float, friction: float, vx_mm_s: float, vy_mm_s: float) -> tuple[float, float]:
    """Lateral drag (N) on a tip moving at (vx, vy) while pressing with normal_n: Coulomb friction against the
    motion, smoothed below SLIP_MM_S so that a tip at rest feels none (and the physics step stays stable)."""
    speed = math.hypot(vx_mm_s, vy_mm_s)
    if speed == 0.0 or normal_n <= 0.0 or friction == 0.0:
        return 0.0, 0.0
    scale = -friction * normal_n / math.hypot(speed, SLIP_MM_S)
    return scale * vx_mm_s, scale * vy_mm_s


SLIP_MM_S = 1.0


def _within_the_readings_around(interpolant, values: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """The Clough-Tocher interpolant at the grid's points, each held to within OVERSHOOT_SHARE of the map's range
    of the readings at the corners of the triangle it lies in (NaN outside the hull, as the interpolant gives).
    A C¹ interpolant overshoots where readings crowd: through a sliding raster's (rows 3 mm apart, read every
    0.2 mm along them, some spots read twice with other values) it drew 8 N/mm, and below zero, where no reading
    was over 0.44 N/mm, and a raster scan of it ended on the force cap at its second palpation. Through the
    shipped maps, sampled on grids, it goes past its corners by at most 9 % of the range (textured-no-lump):
    their fields are as they were, cell for cell; a crowded raster's went 10-20 times the range past."""
    flat = np.column_stack([gx.ravel(), gy.ravel()])
    field = interpolant(flat)
    simplex = interpolant.tri.find_simplex(flat)
    inside = simplex >= 0
    corners = values[interpolant.tri.simplices[simplex[inside]]]
    slack = OVERSHOOT_SHARE * float(np.ptp(values))
    field[inside] = np.clip(field[inside], corners.min(axis=1) - slack, corners.max(axis=1) + slack)
    return field.reshape(gx.shape)


class _GridMap:
    """A measured map resampled once onto a fine grid, then read bilinearly each tick."""

    def __init__(self, rows: list[tuple[float, float, float]], size_mm: tuple[float, float]) -> None:
        from scipy.interpolate import CloughTocher2DInterpolator, NearestNDInterpolator

        points = np.array([(x, y) for x, y, _ in rows])
        values = np.array([k for _, _, k in rows])
        half_w, half_h = size_mm[0] / 2 + 5.0, size_mm[1] / 2 + 5.0
        self._x0, self._y0 = -half_w, -half_h
        xs = np.arange(-half_w, half_w + MAP_GRID_MM, MAP_GRID_MM)
        ys = np.arange(-half_h, half_h + MAP_GRID_MM, MAP_GRID_MM)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        smooth = _within_the_readings_around(CloughTocher2DInterpolator(points, values), values, gx, gy)
        nearest = NearestNDInterpolator(points, values)(gx, gy)  # outside the measured hull
        grid = np.where(np.isfinite(smooth), smooth, nearest)
        self._grid = np.maximum(grid, values.min() * 0.1).tolist()
        self._nx, self._ny = len(xs), len(ys)

    def value(self, x_mm: float, y_mm: float) -> float:
        fx = min(max((x_mm - self._x0) / MAP_GRID_MM, 0.0), self._nx - 1.000001)
        fy = min(max((y_mm - self._y0) / MAP_GRID_MM, 0.0), self._ny - 1.000001)
        i, j = int(fx), int(fy)
        ax, ay = fx - i, fy - j
        g = self._grid
        return (g[i][j] * (1 - ax) * (1 - ay) + g[i + 1][j] * ax * (1 - ay)
                + g[i][j + 1] * (1 - ax) * ay + g[i + 1][j + 1] * ax * ay)
