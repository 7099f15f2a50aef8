"""Lumps from the learner's map: connected regions where P(lump) > 0.5.

Each region that an observed stiff point supports (the model alone never makes
a lump) becomes a lump with its 50 % boundary as a closed polygon, its centroid
and equal-area radius (a free-form region has no circle to report), and
uncertainties from how well the boundary is pinned down: δ = σ/|∇μ| across it,
carried to the centroid and the area of that region. Lumps sit in tissue: when the
stiff part runs along the whole edge of the area, it is the tissue and there is
no lump.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import contourpy
import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix, csgraph

from palpd.estimate import LumpEstimate
from palpd.learner.hypotheses import Region
from palpd.learner.threshold import EIGHT_CONNECTED

MIN_REGION_CELLS = 2


@dataclass(frozen=True)
class Map:
    xs: np.ndarray      # grid columns (mm)
    ys: np.ndarray      # grid rows (mm)
    mean: np.ndarray    # (ny, nx) posterior mean stiffness
    std: np.ndarray     # (ny, nx) posterior sd
    tau: np.ndarray     # (ny, nx) threshold
    length_mm: float    # kernel length scale: how far one probe informs
    tissue_tau: float   # the global τ (min_contrast above the tissue level), where no region's own holds

    # The grid has as many cells along y as along x, so on a tissue that is not square its cells are not
    # either: every distance and area on it takes both steps (a 58 x 20 mm map's cells are 0.97 x 0.33 mm).
    @property
    def dx_mm(self) -> float:
        return float(self.xs[1] - self.xs[0]) if len(self.xs) > 1 else 1.0

    @property
    def dy_mm(self) -> float:
        return float(self.ys[1] - self.ys[0]) if len(self.ys) > 1 else 1.0

    @property
    def cell_mm(self) -> float:
        """The coarser of the two steps: what the grid can resolve at best."""
        return max(self.dx_mm, self.dy_mm)

    @property
    def cell_area_mm2(self) -> float:
        return self.dx_mm * self.dy_mm

    def at(self, field: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """A (ny, nx) field's values at the cells nearest the points (n, 2)."""
        cols = np.clip(np.rint((xy[:, 0] - self.xs[0]) / self.dx_mm).astype(int), 0, len(self.xs) - 1)
        rows = np.clip(np.rint((xy[:, 1] - self.ys[0]) / self.dy_mm).astype(int), 0, len(self.ys) - 1)
        return field[rows, cols]


def find_lumps(m: Map, stiff_xy: np.ndarray) -> list[LumpEstimate]:
    """Lumps where the map says P > 0.5, each backed by at least one observed stiff point."""
    labels, regions = _backed_regions(m, stiff_xy)
    lumps = []
    for region in regions:
        lump = _one_lump(m, region, (labels > 0) & ~region)
        if lump is not None:
            lumps.append(lump)
    return lumps


def regions_of(m: Map, stiff_xy: np.ndarray, stiff_k: np.ndarray, tissue_n_per_mm: float) -> list[Region]:
    """The map's backed regions as starts for the parametric hypotheses: centre, size, stretch, contrast."""
    _, regions = _backed_regions(m, stiff_xy)
    gx, gy = np.meshgrid(m.xs, m.ys)
    out = []
    for region in regions:
        x, y = gx[region], gy[region]
        inside = _inside(m, region, stiff_xy)
        peak = float(stiff_k[inside].max()) if inside.any() else float(m.mean[region].max())
        out.append(Region((float(x.mean()), float(y.mean())), math.sqrt(x.size * m.cell_area_mm2 / math.pi),
                          _stretch(np.cov(np.vstack([x, y])) if x.size > 2 else np.eye(2)),
                          peak / tissue_n_per_mm - 1.0))
    return out


def count_spread(m: Map, stiff_xy: np.ndarray, p_lump: np.ndarray) -> dict[int, float]:
    """The map's count of backed regions over its posterior, {count: probability}: regions drawn apart at
    P(lump) = ½ may be one where the cells between them are in doubt. Two regions are one if some path
    between them runs through lump all the way; along a path, cells a kernel length ℓ apart are taken as
    independent and those closer as one, so a path's chance is the product of P over it, each cell's
    P raised to its step over ℓ, and the join's chance is its likeliest path's (a shortest path in
    −log P, `_join_chances`). Joins along the strongest tree of them are taken as independent. So a count
    drawn across an unread gap is not a count decided (a stiff strip along a real phantom's edge was drawn
    as two regions at its ends, `lumps` at weight 1.000, one of them false), while a long way round through
    plain tissue in doubt joins nothing."""
    labels, regions = _backed_regions(m, stiff_xy)
    count = len(regions)
    if count < 2:
        return {count: 1.0}
    chances = _join_chances(m, regions, p_lump)
    spread = np.zeros(count + 1)  # by the number of joins
    spread[0] = 1.0
    for chance in _strongest_tree(chances):
        spread[1:] = spread[1:] * (1.0 - chance) + spread[:-1] * chance
        spread[0] *= 1.0 - chance
    return {count - j: float(p) for j, p in enumerate(spread) if p > 0.0}


def _join_chances(m: Map, regions: list[np.ndarray], p_lump: np.ndarray) -> np.ndarray:
    """chance[i, j]: the likeliest path's chance that regions i and j are one (count_spread)."""
    ny, nx = p_lump.shape
    inside = np.zeros(p_lump.shape, dtype=bool)
    for region in regions:
        inside |= region
    cost = np.where(inside, 0.0, -np.log(np.clip(p_lump, 1e-12, 1.0)))  # per ℓ of path
    index = np.arange(ny * nx).reshape(ny, nx)
    rows, cols, weights = [], [], []
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):  # each neighbour pair once, the graph undirected
        a = index[:ny - dy, max(0, -dx):nx - max(0, dx)].ravel()
        b = index[dy:, max(0, dx):nx - max(0, -dx)].ravel()
        step = math.hypot(dx * m.dx_mm, dy * m.dy_mm) / m.length_mm
        rows.append(a)
        cols.append(b)
        weights.append(0.5 * (cost.ravel()[a] + cost.ravel()[b]) * step + 1e-12)  # > 0: csgraph drops zeros
    graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(ny * nx, ny * nx)).tocsr()
    count = len(regions)
    chances = np.zeros((count, count))
    for i, region in enumerate(regions[:-1]):
        distance = csgraph.dijkstra(graph, directed=False, indices=np.flatnonzero(region.ravel()), min_only=True)
        for j in range(i + 1, count):
            chances[i, j] = chances[j, i] = math.exp(-float(distance[regions[j].ravel()].min()))
    return chances


def _strongest_tree(chances: np.ndarray) -> list[float]:
    """The join chances along the maximum spanning tree of the regions (Kruskal): each region joined to the
    others by its likeliest joins, count − 1 of them."""
    count = len(chances)
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    pairs = sorted(((chances[i, j], i, j) for i in range(count) for j in range(i + 1, count)), reverse=True)
    tree = []
    for chance, i, j in pairs:
        if root(i) != root(j):
            parent[root(i)] = root(j)
            tree.append(float(chance))
    return tree


def _inside(m: Map, region: np.ndarray, xy: np.ndarray) -> np.ndarray:
    return m.at(region, xy)


def _stretch(cov: np.ndarray) -> tuple[float, float]:
    """(e1, e2) of shapes.py for the ellipse with these second moments."""
    values, vectors = np.linalg.eigh(cov)
    ratio = 0.5 * math.log(max(values[1], 1e-9) / max(values[0], 1e-9))  # log(major / minor)
    angle = math.atan2(vectors[1, 1], vectors[0, 1])
    return ratio * math.cos(2.0 * angle), ratio * math.sin(2.0 * angle)


def _backed_regions(m: Map, stiff_xy: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    above = m.mean > m.tau
    if _surrounds_the_tissue(m.mean > m.tissue_tau):  # stiffer than the tissue at all, all along the edge
        return np.zeros(above.shape, dtype=int), []
    labels, count = ndimage.label(above, EIGHT_CONNECTED)
    supported = _supported_labels(m, labels, stiff_xy)
    regions = [labels == label for label in range(1, count + 1) if label in supported]
    return labels, [r for r in regions if np.count_nonzero(r) >= MIN_REGION_CELLS]


def _surrounds_the_tissue(above: np.ndarray) -> bool:
    """The stiff part runs all along the area's edge: lumps sit in tissue, so the stiff material is the
    tissue itself and what lies below it a soft region in it, not lumps around it (τ came from the
    soft readings' level, and an active learner reads a soft region as often as a lump)."""
    return bool(above[0].all() and above[-1].all() and above[:, 0].all() and above[:, -1].all())


def _supported_labels(m: Map, labels: np.ndarray, stiff_xy: np.ndarray) -> set[int]:
    if len(stiff_xy) == 0:
        return set()
    near = ndimage.grey_dilation(labels, footprint=np.ones((5, 5), dtype=bool))  # a probe a cell or two outside
    return {int(v) for v in m.at(near, stiff_xy) if v > 0}


def _one_lump(m: Map, region: np.ndarray, others: np.ndarray) -> LumpEstimate | None:
    polygon = _boundary(m, region, others)
    if polygon is None:
        return None
    # A free-form region has no circle to report: its centroid and equal-area radius (within the area).
    gx, gy = np.meshgrid(m.xs, m.ys)
    centre = np.array([gx[region].mean(), gy[region].mean()])
    area = np.count_nonzero(region) * m.cell_area_mm2
    centre_sd, radius_sd, boundary_sd = _region_uncertainty(m, polygon, centre, area)
    return LumpEstimate((float(centre[0]), float(centre[1])), math.sqrt(area / math.pi), centre_sd, radius_sd,
                        polygon.tolist(), boundary_sd_mm=boundary_sd)


def _boundary(m: Map, region: np.ndarray, others: np.ndarray) -> np.ndarray | None:
    """The region's μ = τ contour, closed along the area's edge by a soft frame around the grid."""
    # 2ℓ and a cell around the region, along each axis in its own step
    grow = [int(math.ceil(2.0 * m.length_mm / step)) + 1 for step in (m.dy_mm, m.dx_mm)]
    own = ndimage.maximum_filter(region, size=(2 * grow[0] + 1, 2 * grow[1] + 1)) & ~others
    z = np.where(own, m.mean - m.tau, -1.0)
    z = np.pad(z, 1, constant_values=-1.0)
    eps = 1e-6 * m.cell_mm  # the frame sits just outside the area, so the polygon follows its edge
    xs = np.concatenate([[m.xs[0] - eps], m.xs, [m.xs[-1] + eps]])
    ys = np.concatenate([[m.ys[0] - eps], m.ys, [m.ys[-1] + eps]])
    lines = contourpy.contour_generator(xs, ys, z).lines(0.0)
    if not lines:
        return None
    line = max(lines, key=len)
    if len(line) < 4:
        return None
    if not np.array_equal(line[0], line[-1]):
        line = np.vstack([line, line[:1]])
    return np.clip(line, [m.xs[0], m.ys[0]], [m.xs[-1], m.ys[-1]])


def boundary_stretches(m: Map, polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The boundary's stretches inside the area (those along its edge do not move): their midpoints, lengths
    ds and how far each moves across itself, δ = σ / |∇(μ − τ)| (capped at the area's size); None if none."""
    a, b = polygon[:-1], polygon[1:]
    mid, ds = 0.5 * (a + b), np.hypot(*(b - a).T)
    margin = 0.5 * m.cell_mm
    moving = ((mid[:, 0] > m.xs[0] + margin) & (mid[:, 0] < m.xs[-1] - margin)
              & (mid[:, 1] > m.ys[0] + margin) & (mid[:, 1] < m.ys[-1] - margin) & (ds > 0))
    if not moving.any():
        return None
    mid, ds = mid[moving], ds[moving]
    gy, gx = np.gradient(m.mean - m.tau, m.dy_mm, m.dx_mm)
    slope = np.maximum(np.hypot(m.at(gx, mid), m.at(gy, mid)), 1e-12)
    span = max(m.xs[-1] - m.xs[0], m.ys[-1] - m.ys[0])
    return mid, ds, np.minimum(m.at(m.std, mid) / slope, span)


def _region_uncertainty(m: Map, polygon: np.ndarray, centre: np.ndarray, area: float) -> tuple[float, float, float]:
    """The sd of the region's centroid and equal-area radius, and the RMS sd of its boundary's position.

    The boundary inside the area moves across itself by δ = σ / |∇(μ − τ)| (capped at the area's size),
    neighbouring stretches together: about one independent move per kernel length ℓ of boundary. A move
    δ over a stretch ds changes the area by δ·ds and the centroid by (p − c)·δ·ds / A, so
    Var A = ℓ Σ δ² ds and E|Δc|² = ℓ Σ |p − c|² δ² ds / A² (the centroid's distance, both axes, as a
    parametric lump's centre sd is), and r = √(A/π) moves by δA / (2πr). For a circle these are a circle
    fit's δ/√N and δ·√(4/N), N = 2πr/ℓ; but a circle fitted
    to the boundary (what was reported before) has no centre to speak of where the boundary is nearly
    straight, as across a stiff half of the tissue. Stretches along the area's edge do not move."""
    floor = m.cell_mm / math.sqrt(12.0)  # the grid cannot say better than this
    stretches = boundary_stretches(m, polygon)
    if stretches is None:
        return floor, floor, floor
    mid, ds, delta = stretches
    spread = delta**2 * ds  # δ² ds
    length = min(m.length_mm, float(ds.sum()))  # a boundary shorter than ℓ moves as one
    area_sd = math.sqrt(length * float(spread.sum()))
    centre_sd = math.sqrt(length * float(np.sum((mid - centre) ** 2, axis=1) @ spread)) / area
    radius_sd = area_sd / (2.0 * math.pi * math.sqrt(area / math.pi))
    boundary_sd = math.sqrt(float(spread.sum() / ds.sum()))
    return max(centre_sd, floor), max(radius_sd, floor), max(boundary_sd, floor)
