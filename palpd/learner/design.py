"""Where to palpate before anything is known: a covering design sized to the tissue.

"No lump of radius R" is a claim about every spot of the tissue, and a sharp-edged
lump is felt only a little beyond its radius, so the readings must leave no spot
farther than a reach from one of them. The design that does it with the fewest
readings is a covering lattice: rows of points, each row staggered by half a
step against the next (hexagonal when the tissue's proportions allow: the
densest covering of the plane), sized so that the farthest spot of the
rectangle is within the reach. Going to the farthest unread spot in turn
instead took 29–33 readings to cover 60 × 60 mm at 10 mm; the lattice at 11 mm
takes 16.

The first design is the lattice's checkerboard half (every other point of each
row), which already covers at about twice the reach; the other half is probed
only where no reading has come within the reach once a hypothesis is chosen
(decision.py). A scan's seed mirrors the lattice and picks which half comes
first, so seeds do not all read the same spots first.

On a larger tissue the reach widens (none_reach) so that the lattice keeps the
points of a 60 mm square at 11 mm: "no lump" costs the same ~18 palpations on
any tissue, and what it rules out (the verdict's unfelt radius) grows with it.
"""
from __future__ import annotations

import functools
import math

import numpy as np

CHECK_STEP_MM = 0.5  # the rectangle is checked for its farthest spot on a grid this fine (at most MAX_CHECK per side)
MAX_CHECK = 241
INSETS = 6  # outer rows tried at this many distances from the edge
ROW_TRIES = 4  # row counts tried once one covers
TRIES = 4  # point counts tried beyond the fewest that could cover
NONE_POINTS = 16  # the covering lattice of a 60 mm square at 11 mm: `none` in about 18 palpations with the centre
REACH_STEP_MM = 0.25  # none_reach's resolution


def covering_lattice(size_mm: tuple[float, float], reach_mm: float) -> np.ndarray:
    """The fewest points (n × 2, centred frame, rows in order) found among staggered-row lattices over the
    rectangle that leave no spot of it farther than `reach_mm` (rows along x or along y, whichever needs fewer)."""
    width, height = float(size_mm[0]), float(size_mm[1])
    return _covering(width, height, float(reach_mm)).copy()


def none_reach(size_mm: tuple[float, float], reach_mm: float, widest_mm: float, points: int = NONE_POINTS) -> float:
    """The reach of a "no lump" claim: `reach_mm`, or on a tissue whose covering lattice at it has more than
    `points` points, the smallest reach (to REACH_STEP_MM, at most `widest_mm`) whose lattice has no more.
    The claim a fixed reach makes grows in cost with the tissue's area (11 mm: 16 points on 60 x 60 mm,
    27 on 80 x 80, 38 on 100 x 100: `none` at 28 and 40 palpations); at a fixed cost it rules out a
    little less on a larger tissue, and the verdict says how much (decision.unfelt_radius_mm)."""
    width, height = float(size_mm[0]), float(size_mm[1])
    steps = max(0, math.ceil((float(widest_mm) - reach_mm) / REACH_STEP_MM))
    reaches = [min(reach_mm + i * REACH_STEP_MM, max(widest_mm, reach_mm)) for i in range(steps + 1)]
    low, high = 0, len(reaches) - 1  # the count falls as the reach grows: bisect to the first that has few enough
    if len(_covering(width, height, reaches[high])) > points:
        return reaches[high]
    while low < high:
        middle = (low + high) // 2
        if len(_covering(width, height, reaches[middle])) <= points:
            high = middle
        else:
            low = middle + 1
    return reaches[low]


@functools.lru_cache(maxsize=32)
def _covering(width: float, height: float, reach: float) -> np.ndarray:
    along_x = _rows_lattice(width, height, reach)
    along_y = _rows_lattice(height, width, reach)[:, ::-1]
    return along_x if len(along_x) <= len(along_y) else along_y


def _rows_lattice(width: float, height: float, reach: float) -> np.ndarray:
    """The fewest points over row counts from the fewest that could reach every spot up to ROW_TRIES more
    (the best is usually among the first few: more rows need fewer points each)."""
    spots = _check_spots(width, height)
    best, rows, tried = None, max(1, math.ceil(height / (2.0 * reach))), 0
    while tried < ROW_TRIES or best is None:
        for inset in _insets(height, rows):
            found = _fewest_in_rows(width, height, reach, rows, inset, spots, best)
            best = best if found is None else found
        rows, tried = rows + 1, tried + (best is not None)
    return best


def _insets(height: float, rows: int) -> np.ndarray:
    """Distances of the outer rows from the edge: from on the edge to evenly spread cells' centres."""
    if rows == 1:
        return np.array([height / 2.0])
    return np.linspace(0.0, height / (2.0 * rows), INSETS)


def _fewest_in_rows(width, height, reach, rows, inset, spots, best) -> np.ndarray | None:
    """The smallest staggered lattice of `rows` rows that covers, fewer points than `best`, or None."""
    gap = 0.0 if rows == 1 else (height - 2.0 * inset) / (rows - 1)
    if max(inset if rows > 1 else height / 2.0, gap / 2.0) >= reach:
        return None  # rows this far apart leave a spot out of reach however dense each row is
    ys = np.array([0.0]) if rows == 1 else np.linspace(inset - height / 2.0, height / 2.0 - inset, rows)
    first = max(1, math.ceil(width / _widest_step(reach, gap, inset if rows > 1 else height / 2.0)))
    for per_row in range(first, first + TRIES):
        for odd in _odd_rows(width, per_row):
            layout = [_cells(width, per_row) if i % 2 == 0 else odd for i in range(rows)]
            if best is not None and sum(row[2] for row in layout) >= len(best):
                continue
            if _reach(ys, layout, spots) <= reach:
                return _points(ys, layout)
    return None


def _cells(width: float, count: int) -> tuple[float, float, int]:
    """A row at the centres of `count` equal cells across the width: (first x, step, count)."""
    return width / (2.0 * count) - width / 2.0, width / count, count


def _odd_rows(width: float, per_row: int) -> list[tuple[float, float, int]]:
    """What the rows between `per_row`-point rows may hold: one point fewer, as many or one more at cell
    centres, or one more staggered by half a step (a hexagonal lattice; its end points on the edges)."""
    rows = [_cells(width, count) for count in (per_row - 1, per_row, per_row + 1) if count >= 1]
    return rows + [(-width / 2.0, width / per_row, per_row + 1)]


def _widest_step(reach: float, gap: float, inset: float) -> float:
    """The widest step along a row that can cover: a spot between two staggered rows `gap` apart lies on
    the circle through three points, radius ((step/2)² + gap²) / (2·gap); a spot on the edge `inset`
    beyond the outer row, halfway between two of its points, at √((step/2)² + inset²)."""
    across = math.sqrt(max(reach**2 - inset**2, 0.0))
    between = math.sqrt(max(2.0 * gap * reach - gap**2, 0.0)) if gap > 0 else across
    return 2.0 * max(min(across, between), 1e-3)


def _points(ys: np.ndarray, layout) -> np.ndarray:
    return np.asarray([(x0 + i * step, y) for y, (x0, step, count) in zip(ys, layout) for i in range(count)])


def _check_spots(width: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """The x and y coordinates of the grid the rectangle is checked on."""
    return tuple(np.linspace(-side / 2.0, side / 2.0, min(MAX_CHECK, int(side / CHECK_STEP_MM) + 1))
                 for side in (width, height))


def _reach(ys: np.ndarray, layout, spots) -> float:
    """How far the grid spot farthest from the lattice lies from its nearest point: along an evenly
    spaced row the nearest point is the rounded index, so each row costs one pass over the grid."""
    gx, gy = spots
    nearest = np.full((len(gy), len(gx)), np.inf)
    for y, (x0, step, count) in zip(ys, layout):
        index = np.clip(np.rint((gx - x0) / step), 0, count - 1)
        across = (gx - (x0 + index * step)) ** 2
        np.minimum(nearest, across[None, :] + ((gy - y) ** 2)[:, None], out=nearest)
    return float(np.sqrt(nearest.max()))


def lattice_reach(lattice: np.ndarray, size_mm) -> float:
    """How far the spot of the rectangle farthest from a lattice of covering_lattice's lies from it."""
    spots = _check_spots(float(size_mm[0]), float(size_mm[1]))
    gx, gy = np.meshgrid(*spots)
    nearest = np.full(gx.shape, np.inf)
    for x, y in lattice:
        np.minimum(nearest, (gx - x) ** 2 + (gy - y) ** 2, out=nearest)
    return float(np.sqrt(nearest.max()))


def first_design(size_mm, lattice: np.ndarray, count: int, seed: int) -> list[tuple[float, float]]:
    """The first `count` palpations: the lattice (lattice_order), then scrambled Halton points if more are asked."""
    if count <= 0:
        return []
    points = lattice_order(lattice, seed, count)
    return points + halton(size_mm, count - len(points), seed) if len(points) < count else points


def halton(size_mm, count: int, seed: int) -> list[tuple[float, float]]:
    """`count` scrambled Halton points over the area, in a short nearest-neighbour tour."""
    if count <= 0:
        return []
    half = np.asarray(size_mm, dtype=float) / 2.0
    from scipy.stats import qmc  # here: scipy.stats takes half a second to import, and is rarely needed

    unit = qmc.Halton(d=2, scramble=True, seed=seed).random(count)
    return tour(qmc.scale(unit, -half, half), start=np.zeros(2))


def lattice_order(lattice: np.ndarray, seed: int, count: int | None = None) -> list[tuple[float, float]]:
    """The lattice (its first `count` points) in the order to palpate it: one checkerboard half, then the
    other, each in a short nearest-neighbour tour; the seed mirrors the lattice (a mirror image covers as
    well) and picks the half."""
    mirror = np.where([seed & 2, seed & 4], -1.0, 1.0)
    points = lattice * mirror
    rows = np.unique(np.round(lattice[:, 1], 6), return_inverse=True)[1]
    order = np.lexsort((lattice[:, 0], rows))
    parity = np.zeros(len(points), dtype=int)
    for row in np.unique(rows):
        in_row = order[rows[order] == row]
        parity[in_row] = (np.arange(len(in_row)) + row) % 2
    first = parity == seed % 2
    start = tour(points[first], np.zeros(2), count)
    rest = None if count is None else count - len(start)
    return start + tour(points[~first], np.asarray(start[-1]) if start else np.zeros(2), rest)


def tour(points: np.ndarray, start: np.ndarray, count: int | None = None) -> list[tuple[float, float]]:
    """The points (the first `count` of them) in a nearest-neighbour tour from `start`; each step one
    vectorised pass, as a tissue hundreds of millimetres across has thousands of lattice points."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    left = np.ones(len(points), dtype=bool)
    here, order = np.asarray(start, dtype=float), []
    for _ in range(len(points) if count is None else min(count, len(points))):
        distance = np.where(left, np.hypot(points[:, 0] - here[0], points[:, 1] - here[1]), np.inf)
        nearest = int(np.argmin(distance))
        left[nearest] = False
        here = points[nearest]
        order.append((float(here[0]), float(here[1])))
    return order
