"""When a parametric lump is pinned down by readings, not only by its model.

A few readings near one side of a lump can fit a circle (or two lumps side by
side can fit one) to a fraction of a millimetre in the Laplace approximation
while the rest of it is unexplored: the posterior is then many circles, not the
one Gaussian the approximation draws. A lump counts as pinned only when it has
been felt from inside (a reading within CONFIRM_RHO of its centre, in units of
its boundary, or within the probe spacing of a lump smaller than that) and its
edge band (where its profile is between 10 % and 90 % of its height, widened by
the probe spacing) holds readings on every side: no gap of a third of a turn or
more between them, around its own axes; the part of the edge outside the
palpable area needs none; then its top must have been read (where its
profile is within 10 % of its height under every edge the readings allow).
These say where to probe first.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from palpd.learner import shapes
from palpd.learner.priors import profile_branch

JOINT_SIGMA = 3.0  # readings around a hole this far above the chosen model together (mean shift, in sd): a lump there?
HOLE_FRACTION = 0.75  # of the `none` reach: a spot this far from every reading is a hole a lump can hide in
CONFIRM_RHO = 0.6
EDGE_LEVEL = math.log(9.0)  # the edge band: where the lump's profile is between 10 % and 90 % of its height
MAX_GAP_RAD = 2.0 * math.pi / 3.0  # no third of a turn of edge unread
OUTSIDE_STEPS = 36
CLUSTER_LUMPS = 2  # lumps found together, the closer look around them begins (satellite_holes)
SATELLITE_GAP = 1.0  # a satellite's edge within this many of its neighbour's radii of the neighbour's edge
UNFELT_RADII = 48  # radii the unfelt area is summed over, log-spaced (unfelt_area_mm2)
UNFELT_BLOCK = 256  # candidate spots weighed at once (best_unfelt_spot): a block's distances to every cell


def unconfirmed_centre(fit, readings_xy: np.ndarray, spacing_mm: float) -> np.ndarray | None:
    """The centre of the first lump no reading has felt from inside, or None. An ellipse is felt at its
    middle (within CONFIRM_RHO of its minor semi-axis of the centre): two round lumps side by side, read
    around but not between, fit one ellipse as well as two circles, its readings inside near either end,
    and only the middle tells them apart (two touching lumps: one ellipse at 0.9999, and the end)."""
    for params in lump_params(fit):
        if not np.any(_within(fit, params, readings_xy, CONFIRM_RHO, spacing_mm)):
            return params[:2]
    return None


def _within(fit, params: np.ndarray, readings_xy: np.ndarray, rho: float, spacing_mm: float) -> np.ndarray:
    """Which readings lie within ρ of a lump's centre (an ellipse's: within ρ of its minor semi-axis), or
    within the probe spacing of it (a lump smaller than that)."""
    if fit.family.kind == "ellipses":
        _, minor, _ = shapes.axes_and_angle(params, True)
        return np.hypot(*(readings_xy - params[:2]).T) <= max(rho * minor, spacing_mm)
    lr2, _ = shapes.log_rho2(params, readings_xy, False, derivatives=False)
    return lr2 <= 2.0 * math.log(max(rho, spacing_mm / math.exp(params[2])))


def unread_top(fit, readings_xy: np.ndarray, spacing_mm: float) -> np.ndarray | None:
    """The centre of the first lump whose top no reading has read, or None. Its radius is where the
    stiffness is halfway to its top, and only a reading at the top reads its height: one half the radius
    out (85 % of the height of a Gaussian rise) left the top to the family's profile, which readings
    farther out hardly constrain (gradual-lump, seeds 1 and 2: the radius 0.33 and 0.41 mm wide of its
    half-height at a stated sd of 0.2 mm). Read means within the reach where the lump's profile is at 90 %
    of its height under every edge its readings allow (tail shape and sharpness 2 sd either way); a sharp
    edge asks for no reading nearer than CONFIRM_RHO, where it was felt."""
    for j, params in enumerate(lump_params(fit)):
        reach = _top_reach(fit, j, params)
        if reach < CONFIRM_RHO and not np.any(_within(fit, params, readings_xy, reach, spacing_mm)):
            return params[:2]
    return None


def _top_reach(fit, j: int, params: np.ndarray) -> float:
    """ρ within which lump j's profile is at 90 % of its height under every edge its readings allow (its
    tail shape and sharpness each 2 sd either way), at most CONFIRM_RHO."""
    first = fit.family.lump_slice(j).stop - 3  # [λ, log s, log a] end each lump's parameters
    sd = np.sqrt(np.maximum(np.diag(fit.cov)[first:first + 2], 0.0))
    tails, sharpness = profile_branch(params[-3])
    reach = CONFIRM_RHO
    for tail_step in (-2.0, 2.0):
        for sharp_step in (-2.0, 2.0):
            edge = params.copy()
            edge[-3] = min(max(params[-3] + tail_step * sd[0], tails[0]), tails[1])
            edge[-2] = min(max(params[-2] + sharp_step * sd[1], sharpness[0]), sharpness[1])
            reach = min(reach, shapes.rho_at(edge, -EDGE_LEVEL))
    return reach


def uncovered_edge(fit, readings_xy: np.ndarray, size_mm, spacing_mm: float,
                   unsure: np.ndarray | None = None) -> np.ndarray | None:
    """The boundary point in the middle of the widest unread stretch of edge of any lump, or None. Widest
    first, not the first lump's: with several lumps and a budget, a lump whose edge no reading has touched
    (its radius then rests on its model alone) comes before a third of a turn left on another's (four
    lumps: the first three were closed all round while the fourth, read only at its centre, was reported
    at a third of its radius). Given which lumps are `unsure` (what is reported of them has a posterior sd
    over the tolerance), their gaps come first: a gap on a lump the readings already pin to a few hundredths
    of a millimetre is a check, one on a lump still 0.9 mm unsure is the answer the user waits for (four
    lumps: six probes went to gaps on three lumps at 0.03 mm sd while the fourth, at 0.9 mm, met the budget
    0.8 mm off)."""
    best_key, where = None, None
    for j, (gap, point) in enumerate(_edge_gaps(fit, readings_xy, size_mm, spacing_mm)):
        key = (unsure is not None and bool(unsure[j]), gap)
        if gap >= MAX_GAP_RAD and (best_key is None or key > best_key):
            best_key, where = key, point
    return where


def _edge_gaps(fit, readings_xy: np.ndarray, size_mm, spacing_mm: float):
    """For each lump: its widest unread stretch of edge (rad) and the boundary point in its middle."""
    half = np.asarray(size_mm, dtype=float) / 2.0
    for params in lump_params(fit):
        ellipse = fit.family.kind == "ellipses"
        lr2, _ = shapes.log_rho2(params, readings_xy, ellipse, derivatives=False)
        widen = spacing_mm / math.exp(params[2])
        inner = shapes.rho_at(params, -EDGE_LEVEL) - widen
        outer = shapes.rho_at(params, EDGE_LEVEL) + widen
        band = (lr2 >= 2.0 * math.log(max(inner, 1e-3))) & (lr2 <= 2.0 * math.log(outer))
        if np.all(np.abs(params[:2]) + shapes.axes_and_angle(params, ellipse)[0] <= half):
            outside = np.empty(0)  # the whole boundary on the tissue (its major semi-axis all round)
        else:
            steps = 2.0 * math.pi * np.arange(OUTSIDE_STEPS) / OUTSIDE_STEPS
            outside = steps[np.any(np.abs(_boundary_point(params, ellipse, steps)) > half, axis=1)]
        phases = np.sort(np.concatenate([_phase(params, readings_xy[band], ellipse), outside]))
        if phases.size == 0:
            yield 2.0 * math.pi, _boundary_point(params, ellipse, 0.0)
            continue
        gaps = np.diff(np.concatenate([phases, [phases[0] + 2.0 * math.pi]]))
        widest = int(np.argmax(gaps))
        yield float(gaps[widest]), _boundary_point(params, ellipse, phases[widest] + 0.5 * gaps[widest])


def hidden_lump_spot(excess: np.ndarray, readings_xy: np.ndarray, readings: "Readings",
                     reach_mm: float) -> np.ndarray | None:
    """Where an unseen lump would sit, or None. A lump in a hole between readings raises each of them a
    little (a 6 mm lump 10.6 mm from four readings: 1.7-2.8 sd each, too little for a hypothesis of its
    own, which wants one reading 3 sd off, evidence.supported), and all of them together: at each hole (a
    coverage cell at least HOLE_FRACTION of `reach_mm` from every palpation), the readings within `reach_mm`
    are tested for a common rise over the chosen model, Σz/√n; where that is a JOINT_SIGMA surprise, the
    hole with the largest is probed."""
    holes = readings.probe_distance_mm >= HOLE_FRACTION * reach_mm  # one there that gave no reading: looked at
    if not holes.any() or len(excess) == 0:
        return None
    cells = readings.cells_xy[holes]
    near = np.hypot(cells[:, None, 0] - readings_xy[None, :, 0], cells[:, None, 1] - readings_xy[None, :, 1]) <= reach_mm
    count = near.sum(axis=1)
    joint = (near @ excess) / np.sqrt(np.maximum(count, 1))
    best = int(np.argmax(joint))
    return cells[best] if joint[best] >= JOINT_SIGMA else None


def satellite_holes(discs, readings: "Readings", reach: float, spacing_mm: float) -> tuple[np.ndarray | None, float]:
    """(the middle of the widest satellite hole or None, the share of the cells beside the found lumps in one:
    where a lump as small as the smallest found could lie unfelt), at once.

    Lumps found together come close together (four-lumps, touching-lumps: edges 2-4 mm apart), and a lump
    with a sharp edge is felt only by a reading inside it, so the tissue-wide `coverage_mm` (a hole of up to
    18 mm radius between readings) passed over the third of three touching 5 mm lumps on three seeds of
    eight, and over a lump 7-9 mm beside two found ones on random scenes. Beside each found lump (radius R:
    cells outside every found lump within (2 + SATELLITE_GAP)·R of its centre, where the centre of a lump
    as large lies when its edge is within SATELLITE_GAP·R of this one's), no cell may be farther than
    reach·r from every probe (never below the probe spacing), r the smallest found lump's radius: lumps
    found together come in the sizes found, and one as small as the smallest of them hides in a hole of its
    own size whichever lump it lies beside. (Held to reach·R of the lump beside it, a 6.8 mm lump 6.9× as
    stiff lay unread 12.4 mm from every probe beside a 9.6 mm lump, under the 14.3 mm that allowed, while
    the tissue's third lump was 6.3 mm: random-2-12, `lumps` with two of its three.) Probes, not readings:
    a palpation there that gave no stiffness (no contact, a rejected trace) would give none again, and the
    hole would draw probe after probe. The cell farthest from every probe is the middle of the widest such
    hole."""
    cells_xy, distance = readings.cells_xy, readings.probe_distance_mm
    inside = np.zeros(len(cells_xy), dtype=bool)
    beside = np.zeros(len(cells_xy), dtype=bool)
    widest = max(reach * min(radius for _, radius in discs), spacing_mm)  # the hole a lump as small could lie in
    for centre, radius in discs:
        d = np.hypot(cells_xy[:, 0] - centre[0], cells_xy[:, 1] - centre[1])
        inside |= d <= radius
        beside |= d <= (2.0 + SATELLITE_GAP) * radius
    beside &= ~inside
    hole = beside & (distance > widest)
    if not hole.any():
        return None, 0.0
    return cells_xy[np.flatnonzero(hole)[int(np.argmax(distance[hole]))]], np.count_nonzero(hole) / np.count_nonzero(beside)


@functools.lru_cache(maxsize=8)
def _unfelt_radii(low_mm: float, high_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The radii the unfelt area is summed over (UNFELT_RADII, log-spaced over the range) and the mean π r²
    over the radii below each (index i: the first i); the same for every update of a scan, so made once."""
    radii = np.exp(np.linspace(math.log(low_mm), math.log(high_mm), UNFELT_RADII))
    radii.flags.writeable = False
    below = np.concatenate([[0.0], np.cumsum(math.pi * radii**2)]) / UNFELT_RADII
    below.flags.writeable = False
    return radii, below


def lump_params(fit) -> list[np.ndarray]:
    """Each lump's parameters of a parametric fit ([cx, cy, log R, ...], shapes.py)."""
    return [fit.theta[fit.family.lump_slice(j)] for j in range(fit.family.k)]


def _frame(params: np.ndarray, ellipse: bool) -> tuple[float, float, float]:
    major, minor, angle_deg = shapes.axes_and_angle(params, ellipse)
    return major, minor, math.radians(angle_deg)


def _phase(params: np.ndarray, xy: np.ndarray, ellipse: bool) -> np.ndarray:
    """Each point's angle around the lump in its own (ellipse-normalised) frame, in [0, 2π)."""
    major, minor, angle = _frame(params, ellipse)
    u = xy - params[:2]
    along = u[:, 0] * math.cos(angle) + u[:, 1] * math.sin(angle)
    across = -u[:, 0] * math.sin(angle) + u[:, 1] * math.cos(angle)
    return np.arctan2(across / minor, along / major) % (2.0 * math.pi)


def _boundary_point(params: np.ndarray, ellipse: bool, t) -> np.ndarray:
    """The boundary point(s) at the ellipse's own angle(s) t: (2,) for a number, (len(t), 2) for an array."""
    major, minor, angle = _frame(params, ellipse)
    along, across = major * np.cos(t), minor * np.sin(t)
    return params[:2] + np.stack([along * math.cos(angle) - across * math.sin(angle),
                                  along * math.sin(angle) + across * math.cos(angle)], axis=-1)


def near_edges(fit, xy: np.ndarray, spacing_mm: float) -> np.ndarray:
    """Which points lie in some lump's edge band (widened by the spacing): where a reading moves a
    reported centre or radius, so the only places worth scoring for them."""
    near = np.zeros(len(xy), dtype=bool)
    for params in lump_params(fit):
        lr2, _ = shapes.log_rho2(params, xy, fit.family.kind == "ellipses", derivatives=False)
        widen = 2.0 * spacing_mm / math.exp(params[2])
        inner = shapes.rho_at(params, -EDGE_LEVEL) - widen
        outer = shapes.rho_at(params, EDGE_LEVEL) + widen
        near |= (lr2 >= 2.0 * math.log(max(inner, 1e-3))) & (lr2 <= 2.0 * math.log(outer))
    return near


class Readings:
    """Where the readings are, kept up to date one reading at a time (O(cells) each, no tree to rebuild):
    each coverage cell's distance to the nearest reading, and how many readings sit at distinct spots
    (greedily, in arrival order, at least the probe spacing apart)."""

    def __init__(self, cells_xy: np.ndarray, spacing_mm: float) -> None:
        self.cells_xy = cells_xy
        self.distance_mm = np.full(len(cells_xy), np.inf)
        self.probe_distance_mm = np.full(len(cells_xy), np.inf)  # to any palpation, with a reading or not
        self.spacing_mm = spacing_mm
        self._spots = np.empty((0, 2))  # grown by doubling; the first `spots` rows are the spots
        self._spot_count = 0

    def probed(self, xy) -> None:
        """A palpation there, whatever came of it: a spot where one gave no reading would give none again."""
        np.minimum(self.probe_distance_mm, np.hypot(self.cells_xy[:, 0] - xy[0], self.cells_xy[:, 1] - xy[1]),
                   out=self.probe_distance_mm)

    def add(self, xy) -> None:
        """A reading there (a palpation too)."""
        x, y = float(xy[0]), float(xy[1])
        np.minimum(self.distance_mm, np.hypot(self.cells_xy[:, 0] - x, self.cells_xy[:, 1] - y), out=self.distance_mm)
        np.minimum(self.probe_distance_mm, self.distance_mm, out=self.probe_distance_mm)
        spots = self._spots[:self._spot_count]
        if not len(spots) or np.min(np.hypot(spots[:, 0] - x, spots[:, 1] - y)) >= self.spacing_mm:
            if self._spot_count == len(self._spots):
                self._spots = np.resize(self._spots, (max(16, 2 * len(self._spots)), 2))
            self._spots[self._spot_count] = (x, y)
            self._spot_count += 1

    @property
    def spots(self) -> int:
        return self._spot_count

    def unfelt_area_mm2(self, expected_lumps: float, radius_range_mm: tuple[float, float]) -> float:
        """The expected area of the lumps no reading has felt: what the tissue may still hold beside the lumps
        the hypotheses draw. A lump is felt when a reading lies within its radius (a sharp edge is felt only
        inside it; a blurred one a little beyond, so this is the upper end). Lumps no reading felt leave
        every reading as it is, so their posterior is their prior: `expected_lumps` on the tissue, centres
        anywhere, radii log-uniform over `radius_range_mm` (priors.py's), each of radius r hiding wherever its
        centre is farther than r from every reading. Hence the expected count of radius r unfelt is
        expected_lumps × the share of cells farther than r, and its area π r² each: a sum over the cells of
        what a centre there could hide (`_hidden_per_cell`). Before any reading: the prior's whole area."""
        return float(self._hidden_per_cell(self.distance_mm, expected_lumps, radius_range_mm).sum())

    def best_unfelt_spot(self, expected_lumps: float, radius_range_mm: tuple[float, float]) -> tuple[float, float]:
        """The cell where one reading takes the most off `unfelt_area_mm2`: the middle of the widest hole,
        weighed by how much each hole could hide (the farthest cell alone is on the tissue's edge or in a
        corner, where a reading rules out a quarter of what it would in a hole between readings)."""
        cells = self.cells_xy
        far = self.probe_distance_mm > self.spacing_mm  # not where a palpation was made
        candidates = cells[far] if far.any() else cells
        before = self._hidden_per_cell(self.distance_mm, expected_lumps, radius_range_mm).sum()
        after = np.empty(len(candidates))
        for start in range(0, len(candidates), UNFELT_BLOCK):
            block = candidates[start:start + UNFELT_BLOCK]
            distance = np.hypot(cells[None, :, 0] - block[:, None, 0], cells[None, :, 1] - block[:, None, 1])
            nearest = np.minimum(self.distance_mm[None, :], distance)
            after[start:start + UNFELT_BLOCK] = self._hidden_per_cell(nearest, expected_lumps, radius_range_mm).sum(axis=1)
        best = int(np.argmin(after))
        return (float(candidates[best][0]), float(candidates[best][1])) if after[best] < before else \
            tuple(map(float, cells[int(np.argmax(self.distance_mm))]))

    def _hidden_per_cell(self, distance_mm: np.ndarray, expected_lumps: float,
                         radius_range_mm: tuple[float, float]) -> np.ndarray:
        """Each cell's part of the unfelt area, given its distance to the nearest reading: expected_lumps over
        the cells, times the mean over the radii of π r² for every radius it is farther than."""
        radii, below = _unfelt_radii(*radius_range_mm)
        hidden = below[np.searchsorted(radii, distance_mm, side="left")]
        return expected_lumps * hidden / len(self.cells_xy)

    def farthest_beyond(self, reach_mm: float) -> tuple[float, float] | None:
        """The cell farthest from every reading, if it is beyond `reach_mm` (None before any reading)."""
        if not self._spot_count:
            return None
        far = int(np.argmax(self.distance_mm))
        return tuple(map(float, self.cells_xy[far])) if self.distance_mm[far] > reach_mm else None
