"""What a parametric hypothesis says about each lump, with the uncertainties its posterior gives.

Centre, radius (an ellipse's equal-area radius, plus its axes and angle), edge
width and their standard deviations come from the Laplace covariance through
the Jacobian of each reported quantity; the boundary is the lump's 50 % contour
(or, with a supervised τ, its contour at τ), on the tissue. The depth of its
top follows from its contrast, radius and edge (depth.py).

A lump with most of its boundary off the tissue (a stiff region running past
the tissue's edge, as a measured map may have) is reported by its part on the
tissue: that part's centroid and equal-area radius, and the sd of its boundary
there, which is what readings on the tissue pin down (an ellipse's axes and
angle are still the whole shape's, as fitted, and the stop rule does not hold
them to the tolerance). The whole shape's centre and size are extrapolation: a stiff half of an 80 × 40 mm tissue fitted as
an ellipse centred 6 mm off the half's centroid with axes of 40 and 113 mm,
their sds never within any tolerance, and a boundary mostly where no tissue is.
"""
from __future__ import annotations

import math

import contourpy
import numpy as np

from dataclasses import replace

from palpd.estimate import LumpEstimate
from palpd.learner import depth, evidence, shapes
from palpd.learner.evidence import Fit
from palpd.learner.priors import profile_branch

MOSTLY_OFF = 0.5  # a lump with less than this share of its boundary on the tissue is reported by its part there
STEP = 1e-5  # central-difference step on a lump's shape parameters (centre in mm; log radius and stretch)
CUT_VERTICES = 360  # a cut lump's boundary: its part on the tissue may be a short arc of a large shape
UNION_GRID_MM = 0.2  # the grid a union of overlapping lumps is outlined on (union_of)


def lumps_of(fit: Fit, tau_n_per_mm: float | None = None, size_mm=None) -> list[LumpEstimate]:
    """Each lump of a parametric fit as reported; with the tissue's size, on the tissue (see above)."""
    return [lump for _, lump in parts_of(fit, tau_n_per_mm, size_mm)]


def parts_of(fit: Fit, tau_n_per_mm: float | None = None, size_mm=None) -> list[tuple[int, LumpEstimate]]:
    """(index in the fit, lump) of each lump of a parametric fit that reaches τ (every lump without one)."""
    half = None if size_mm is None else np.asarray(size_mm, dtype=float) / 2.0
    out = []
    for j in range(fit.family.k):
        part = fit.family.lump_slice(j)
        scale = 1.0 if tau_n_per_mm is None else _level_scale(fit, part, tau_n_per_mm)
        if scale is not None:
            lump = _one(fit.theta[part], fit.cov[part, part], fit.family.kind == "ellipses", scale, half)
            out.append((j, _with_depth(lump, fit.theta[part], fit.cov[part, part])))
    return out


def regions_of(fit: Fit, parts: list[tuple[int, LumpEstimate]], size_mm=None) -> list[LumpEstimate]:
    """The reported lumps: the parts (parts_of) gathered into connected stiff regions (evidence.regions), a
    region of several parts as one lump (its outline, centroid and equal-area radius: union_of)."""
    by_index = dict(parts)
    out = []
    for group in evidence.regions(fit.family, fit.theta):
        members = [by_index[j] for j in group if j in by_index]
        if members:
            out.append(members[0] if len(members) == 1 else union_of(members, size_mm))
    return out


def union_of(parts: list[LumpEstimate], size_mm=None) -> LumpEstimate:
    """One lump of overlapping parts, as a free-form region is reported (lumps.py): the outline of their union
    on the tissue, its centroid and equal-area radius. Their sds are carried as if the parts moved
    independently: the centroid moves by each part's centre move weighted by its share of the area, the area by
    2πr·dr of each part. Its top is the shallowest part's; an edge profile belongs to no union, so none."""
    polygons = [np.asarray(part.boundary_mm, dtype=float) for part in parts]
    low = np.min([p.min(axis=0) for p in polygons], axis=0) - UNION_GRID_MM
    high = np.max([p.max(axis=0) for p in polygons], axis=0) + UNION_GRID_MM
    if size_mm is not None:
        half = np.asarray(size_mm, dtype=float) / 2.0
        low, high = np.maximum(low, -half), np.minimum(high, half)
    xs = np.arange(low[0], high[0] + UNION_GRID_MM / 2, UNION_GRID_MM)
    ys = np.arange(low[1], high[1] + UNION_GRID_MM / 2, UNION_GRID_MM)
    gx, gy = np.meshgrid(xs, ys)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    inside = np.zeros(len(points), dtype=bool)
    for polygon in polygons:
        inside |= inside_polygon(points, polygon)
    area = max(np.count_nonzero(inside), 1) * UNION_GRID_MM ** 2
    centre = points[inside].mean(axis=0) if inside.any() else polygons[0].mean(axis=0)
    radius = math.sqrt(area / math.pi)
    areas = np.array([math.pi * part.radius_mm ** 2 for part in parts])
    centre_sd = math.sqrt(float(np.sum((areas / areas.sum()) ** 2 * [p.center_sd_mm ** 2 for p in parts])))
    radius_sd = math.sqrt(sum((p.radius_mm * p.radius_sd_mm) ** 2 for p in parts)) / radius
    outline = _outline(xs, ys, inside.reshape(gx.shape))
    top = min((p for p in parts if p.depth_mm is not None), key=lambda p: p.depth_mm, default=None)
    return LumpEstimate((float(centre[0]), float(centre[1])), radius, centre_sd, radius_sd, outline.tolist(),
                        boundary_sd_mm=math.sqrt(float(np.mean([p.radius_sd_mm ** 2 for p in parts]))),
                        cut_by_edge=any(p.cut_by_edge for p in parts),
                        depth_mm=None if top is None else top.depth_mm, depth_sd_mm=None if top is None else top.depth_sd_mm)


def inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Which points (n, 2) lie inside a closed polygon (its vertices, first repeated last): the even-odd rule,
    a ray along +x crossing the sides. (palpd.metrics asks matplotlib's Path, which the learner, running in
    the daemon, does not import for this.) Side by side, never points × sides at once: a union of two ellipses
    across a 140 × 100 mm tissue, 350 000 points on its grid against 200 sides, took 500 MB that way."""
    px, py = points[:, 0], points[:, 1]
    inside = np.zeros(len(points), dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for (ax, ay), (bx, by) in zip(polygon[:-1], polygon[1:]):
            spans = (ay > py) != (by > py)
            inside ^= spans & (px < ax + (py - ay) * (bx - ax) / (by - ay))
    return inside


def _outline(xs: np.ndarray, ys: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """The closed outer outline of a region on a grid (its longest contour at half way between in and out)."""
    z = np.pad(inside.astype(float), 1)
    step = xs[1] - xs[0] if len(xs) > 1 else UNION_GRID_MM
    lines = contourpy.contour_generator(np.concatenate([[xs[0] - step], xs, [xs[-1] + step]]),
                                        np.concatenate([[ys[0] - step], ys, [ys[-1] + step]]), z).lines(0.5)
    line = max(lines, key=len)
    return line if np.array_equal(line[0], line[-1]) else np.vstack([line, line[:1]])


def _with_depth(lump: LumpEstimate, params: np.ndarray, cov: np.ndarray) -> LumpEstimate:
    """The lump with its top's depth from its profile: contrast, size and edge (depth.py). The size is the
    profile's own radius, an ellipse's minor semi-axis, and the edge is read along it: across a rod, where its
    depth shows, not along it (in units of ρ the edge is the same all round, in mm it scales with the axis)."""
    radius = math.exp(params[2])
    ellipse = lump.axes_mm is not None
    size = shapes.axes_and_angle(params, ellipse)[1]
    size_sd = radius * math.sqrt(max(cov[2, 2], 0.0)) if not ellipse else _sd(_axes_jacobian(params)[1], cov)
    across = size / radius
    sds = (math.sqrt(max(cov[-1, -1], 0.0)), size_sd, across * (lump.edge_sd_mm or 0.0))
    top, sd = depth.surrogate().estimate(math.exp(params[-1]), size, across * shapes.edge_width_mm(params), sds)
    return replace(lump, depth_mm=top, depth_sd_mm=sd)


def soft_regions_of(fit: Fit | None) -> list[dict]:
    """The soft region of a fit that has one (shapes.py: no lump, tissue softer there), as the model reports
    it: centre, radius where the stiffness is halfway between the tissue's around and its core's, that boundary,
    and how many times softer its core is."""
    if fit is None or not fit.family.soft:
        return []
    params = fit.theta[fit.family.soft_slice]
    return [{"center_mm": [round(float(params[0]), 3), round(float(params[1]), 3)],
             "radius_mm": round(math.exp(params[2]), 3), "softer": round(1.0 + math.exp(params[-1]), 2),
             "boundary_mm": np.round(shapes.boundary_polygon(params, False), 3).tolist()}]


def quantities(fit: Fit, size_mm=None) -> np.ndarray:
    """Rows of the Jacobian of every reported centre coordinate and radius (or axis) w.r.t. θ (with the tissue's
    size, a lump mostly off it by its part on it)."""
    half = None if size_mm is None else np.asarray(size_mm, dtype=float) / 2.0
    ellipse = fit.family.kind == "ellipses"
    rows = []
    for j in range(fit.family.k):
        part = fit.family.lump_slice(j)
        params = fit.theta[part]
        cut = _cut(params, ellipse, 1.0, half)
        for local in (_tissue_part_rows(params, ellipse, 1.0, half) if cut else _local_rows(params, ellipse)):
            row = np.zeros(fit.family.size)
            row[part] = local
            rows.append(row)
    return np.array(rows).reshape(-1, fit.family.size)


def mostly_off(polygon: np.ndarray, half: np.ndarray) -> bool:
    """Less than MOSTLY_OFF of the closed polygon's length lies on the tissue (|x|, |y| within half its size)."""
    mid, ds = 0.5 * (polygon[:-1] + polygon[1:]), np.hypot(*(polygon[1:] - polygon[:-1]).T)
    on = np.all(np.abs(mid) <= half, axis=1)
    return bool(ds[on].sum() < MOSTLY_OFF * ds.sum())


def clip_to_tissue(polygon: np.ndarray, half: np.ndarray) -> np.ndarray:
    """A closed convex polygon's part on the tissue (Sutherland–Hodgman against its four sides), closed;
    empty if none of it is on the tissue."""
    points = polygon[:-1]
    for axis in (0, 1):
        for sign in (1.0, -1.0):
            if len(points) == 0:
                return points
            inside = sign * points[:, axis] <= half[axis]
            after, after_inside = np.roll(points, -1, axis=0), np.roll(inside, -1)
            crosses = inside != after_inside
            step = after[:, axis] - points[:, axis]
            t = np.where(crosses, (sign * half[axis] - points[:, axis]) / np.where(crosses, step, 1.0), 0.0)
            crossing = points + t[:, None] * (after - points)
            # each vertex kept if inside, then where its side crosses the line: the clipped polygon in order
            points = np.stack([points, crossing], axis=1)[np.stack([inside, crosses], axis=1)]
    return np.vstack([points, points[:1]]) if len(points) else points


def _cut(params: np.ndarray, ellipse: bool, scale: float, half: np.ndarray | None) -> bool:
    """Reported by its part on the tissue: most of its boundary lies off the tissue, and some on it."""
    if half is None or _wholly_on(params, ellipse, scale, half):
        return False
    polygon = _polygon(params, ellipse, scale)
    return mostly_off(polygon, half) and len(clip_to_tissue(polygon, half)) > 0


def _wholly_on(params: np.ndarray, ellipse: bool, scale: float, half: np.ndarray) -> bool:
    """The lump's boundary lies within the tissue by its major axis alone (most lumps: no polygon to make,
    which is most of what describing a lump costs on each update)."""
    major = shapes.axes_and_angle(params, ellipse)[0] * scale
    return abs(params[0]) + major <= half[0] and abs(params[1]) + major <= half[1]


def _polygon(params: np.ndarray, ellipse: bool, scale: float = 1.0, vertices: int = 72) -> np.ndarray:
    polygon = shapes.boundary_polygon(params, ellipse, vertices)
    return params[:2] + (polygon - params[:2]) * scale


def _tissue_part(params: np.ndarray, ellipse: bool, scale: float, half: np.ndarray) -> np.ndarray:
    """[centroid x, centroid y, equal-area radius] of the lump's part on the tissue (zeros if it has none)."""
    part = clip_to_tissue(_polygon(params, ellipse, scale, CUT_VERTICES), half)
    if len(part) < 4:
        return np.zeros(3)
    x, y, x1, y1 = part[:-1, 0], part[:-1, 1], part[1:, 0], part[1:, 1]
    cross = x * y1 - x1 * y
    area = 0.5 * cross.sum()
    if abs(area) < shapes.TINY:
        return np.zeros(3)
    return np.array([((x + x1) * cross).sum() / (6.0 * area), ((y + y1) * cross).sum() / (6.0 * area),
                     math.sqrt(abs(area) / math.pi)])


def _shape_params(params: np.ndarray, ellipse: bool) -> range:
    """The parameters the 50 % boundary depends on: centre, log radius (and an ellipse's stretch)."""
    return range(5 if ellipse else 3)


def _tissue_part_rows(params: np.ndarray, ellipse: bool, scale: float, half: np.ndarray) -> np.ndarray:
    """Jacobian (3 × len(params)) of the part on the tissue's centroid and equal-area radius, by central
    differences (the clipped part moves smoothly with the shape)."""
    rows = np.zeros((3, len(params)))
    for i in _shape_params(params, ellipse):
        step = np.zeros(len(params))
        step[i] = STEP
        rows[:, i] = (_tissue_part(params + step, ellipse, scale, half)
                      - _tissue_part(params - step, ellipse, scale, half)) / (2.0 * STEP)
    return rows


def _boundary_sd_on_tissue(params: np.ndarray, cov: np.ndarray, ellipse: bool, scale: float,
                           half: np.ndarray) -> float:
    """RMS along the boundary's stretch on the tissue of its position's sd across itself."""
    polygon = _polygon(params, ellipse, scale, CUT_VERTICES)[:-1]
    tangent = np.roll(polygon, -1, axis=0) - np.roll(polygon, 1, axis=0)
    length = np.maximum(np.hypot(*tangent.T), shapes.TINY)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]]) / length[:, None]
    across = np.zeros((len(polygon), len(params)))
    for i in _shape_params(params, ellipse):
        step = np.zeros(len(params))
        step[i] = STEP
        moved = (_polygon(params + step, ellipse, scale, CUT_VERTICES)[:-1]
                 - _polygon(params - step, ellipse, scale, CUT_VERTICES)[:-1]) / (2.0 * STEP)
        across[:, i] = np.sum(moved * normal, axis=1)
    on = np.all(np.abs(polygon) <= half, axis=1)
    if not on.any():
        return math.inf
    variance = np.einsum("ni,ij,nj->n", across[on], cov, across[on])
    return math.sqrt(max(float(np.sum(variance * length[on]) / np.sum(length[on])), 0.0))


def _local_rows(params: np.ndarray, ellipse: bool) -> list[np.ndarray]:
    size = len(params)
    cx, cy = np.eye(size)[0], np.eye(size)[1]
    if not ellipse:
        return [cx, cy, math.exp(params[2]) * np.eye(size)[2]]
    return [cx, cy, *_axes_jacobian(params)]


def _axes_jacobian(params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    major, minor, _ = shapes.axes_and_angle(params, ellipse=True)
    e1, e2 = params[3], params[4]
    eps = max(math.hypot(e1, e2), 1e-6)
    d_major, d_minor = np.zeros(len(params)), np.zeros(len(params))
    d_major[2], d_minor[2] = major, minor
    d_major[3:5] = 0.5 * major * np.array([e1, e2]) / eps
    d_minor[3:5] = -0.5 * minor * np.array([e1, e2]) / eps
    return d_major, d_minor


def _one(params: np.ndarray, cov: np.ndarray, ellipse: bool, scale: float, half: np.ndarray | None) -> LumpEstimate:
    edge, edge_sd = _edge(params, cov)
    if _cut(params, ellipse, scale, half):
        return _part_on_tissue(params, cov, ellipse, scale, half, edge, edge_sd)
    # The centre's sd is its distance from the truth (RMS over both axes), what `--tolerance-mm` bounds: per
    # axis, a lump the scan stopped on at 0.43 mm was 0.56 mm off (touching-lumps seed 2), as a 2-D error is.
    centre_sd = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
    radius = math.exp(params[2]) * scale
    radius_sd = radius * math.sqrt(max(cov[2, 2], 0.0))
    polygon = _polygon(params, ellipse, scale)
    if half is not None and not _wholly_on(params, ellipse, scale, half):
        on_tissue = clip_to_tissue(polygon, half)
        polygon = on_tissue if len(on_tissue) >= 4 else polygon  # a shape wholly off the tissue stays as fitted
    extra = _ellipse_extras(params, cov, scale) if ellipse else {}
    return LumpEstimate((float(params[0]), float(params[1])), radius, centre_sd, radius_sd, polygon.tolist(),
                        edge_mm=edge, edge_sd_mm=edge_sd, **extra)


def _part_on_tissue(params, cov, ellipse: bool, scale: float, half: np.ndarray, edge: float,
                    edge_sd: float) -> LumpEstimate:
    centre_x, centre_y, radius = _tissue_part(params, ellipse, scale, half)
    rows = _tissue_part_rows(params, ellipse, scale, half)
    centre_sd = math.sqrt(_sd(rows[0], cov) ** 2 + _sd(rows[1], cov) ** 2)
    boundary = clip_to_tissue(_polygon(params, ellipse, scale, CUT_VERTICES), half)
    # an ellipse keeps its axes and angle (the shape fitted, DESIGN.md's report), held to no tolerance (_sds)
    extra = _ellipse_extras(params, cov, scale) if ellipse else {}
    return LumpEstimate((float(centre_x), float(centre_y)), float(radius), centre_sd, _sd(rows[2], cov),
                        boundary.tolist(), edge_mm=edge, edge_sd_mm=edge_sd,
                        boundary_sd_mm=_boundary_sd_on_tissue(params, cov, ellipse, scale, half), cut_by_edge=True,
                        **extra)


def _sd(row: np.ndarray, cov: np.ndarray) -> float:
    return math.sqrt(max(float(row @ cov @ row), 0.0))


def _ellipse_extras(params: np.ndarray, cov: np.ndarray, scale: float) -> dict:
    major, minor, angle = shapes.axes_and_angle(params, ellipse=True)
    d_major, d_minor = _axes_jacobian(params)
    e1, e2 = params[3], params[4]
    eps2 = max(e1 * e1 + e2 * e2, 1e-12)
    d_angle = np.zeros(len(params))
    d_angle[3:5] = math.degrees(0.5) * np.array([-e2, e1]) / eps2
    return {"axes_mm": (major * scale, minor * scale),
            "axes_sd_mm": (_sd(d_major, cov) * scale, _sd(d_minor, cov) * scale),
            "angle_deg": angle, "angle_sd_deg": min(_sd(d_angle, cov), 90.0)}


def _edge(params: np.ndarray, cov: np.ndarray) -> tuple[float, float]:
    edge = shapes.edge_width_mm(params)
    row = np.zeros(len(params))
    tails, _ = profile_branch(params[-3])
    for i in (2, len(params) - 3, len(params) - 2):  # size, tail, sharpness: numerically, it is one number
        up, down = params.copy(), params.copy()
        up[i] += 1e-6
        down[i] -= 1e-6
        if i == len(params) - 3:  # within the tail's branch (they meet at a kink: shapes.py)
            up[i], down[i] = min(up[i], tails[1]), max(down[i], tails[0])
        row[i] = (shapes.edge_width_mm(up) - shapes.edge_width_mm(down)) / 2e-6
    return edge, _sd(row, cov)


def _level_scale(fit: Fit, part: slice, tau_n_per_mm: float) -> float | None:
    """How far out (in units of the 50 % boundary) the lump's stiffness falls to τ; None if it never reaches τ."""
    params = fit.theta[part]
    base = math.exp(float(shapes.background(fit.theta, params[None, :2], fit.family.scale_mm)[0]))
    p = (tau_n_per_mm / base - 1.0) / math.exp(params[-1])
    if p >= 1.0:
        return None
    if p <= 0.0:
        return 1.0
    return shapes.rho_at(params, math.log((1.0 - p) / p))
