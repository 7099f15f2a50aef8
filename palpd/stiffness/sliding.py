"""Stiffness points along a sliding palpation: one per modulation cycle, the slope of normal force against
indentation over that cycle (least squares), at the cycle's mean position, with its standard error widened
by how much the stiffness changes over the span the cycle covers.

The slope needs no contact point: an offset in depth (contact found a little late, a surface that is not
flat under the path) moves the line, not its slope. A cycle spans sliding_speed / modulation_hz of path, so
the points are that far apart and each averages the tissue over that length.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpd.stiffness.samples import straight_slope

MIN_SAMPLES = 20
MIN_SWING_FRACTION = 0.5  # a cycle must sweep at least this share of the commanded ±modulation


@dataclass(frozen=True)
class SlidingPoint:
    xy_mm: tuple[float, float]
    stiffness_n_per_mm: float
    stiffness_se_n_per_mm: float
    samples: int
    model: str = "sliding-linear"  # a probe's fit: F = k·(d + δ) over one modulation cycle


def stiffness_points(record, settings) -> list[SlidingPoint]:
    """settings: palpd.config.PalpationSettings (the modulation the record was taken with)."""
    if len(record.t_s) < MIN_SAMPLES:
        return []
    t = np.asarray(record.t_s)
    cycle = np.floor((t - t[0]) * settings.modulation_hz).astype(int)
    xy, depth, force = np.asarray(record.xy_mm), np.asarray(record.depth_mm), np.asarray(record.force_n)
    points = []
    for n in range(int(cycle.max()) + 1):
        mine = cycle == n
        point = _cycle_point(xy[mine], depth[mine], force[mine], 2.0 * settings.modulation_mm * MIN_SWING_FRACTION)
        if point is not None:
            points.append(point)
    return points


def _cycle_point(xy, depth, force, min_swing_mm: float) -> SlidingPoint | None:
    """F = (k + k'·s)·(d + δ) to first order, s the position along the path from the cycle's mean: across an
    edge the stiffness changes within one cycle, and a plain slope of F on d would mix that change in."""
    if len(depth) < MIN_SAMPLES or np.ptp(depth) < min_swing_mm:
        return None  # a cut-short last cycle: too little of the line to read a slope
    along = _along_path(xy)
    design = np.column_stack([depth, depth * along, along, np.ones_like(depth)])
    coef, _, rank, _ = np.linalg.lstsq(design, force, rcond=None)
    if rank < design.shape[1]:  # standing still: no change along the path to separate
        design = design[:, [0, 3]]
        coef, *_ = np.linalg.lstsq(design, force, rcond=None)
    residual = force - design @ coef
    covariance = np.linalg.pinv(design.T @ design) * float(residual @ residual) / (len(depth) - design.shape[1])
    # The reading stands for one spot but averages the cycle's span, over which the stiffness changes by
    # k'·span: that spread (as a uniform one, /√12) is part of its error. Without it a reading across an edge
    # claimed the precision of one on flat tissue, no lump model fitted the stream to that precision, and
    # the learner never judged its choice adequate (two-lumps ran to its 40-path budget).
    spread = abs(float(coef[1])) * float(np.ptp(along)) / np.sqrt(12.0) if design.shape[1] == 4 else 0.0
    spread = max(spread, _halves_spread(depth, force))
    return SlidingPoint(tuple(float(v) for v in xy.mean(axis=0)), float(coef[0]),
                        float(np.hypot(np.sqrt(covariance[0, 0]), spread)), len(depth))


def _halves_spread(depth, force) -> float:
    """The stiffness spread over the cycle's span that its two halves (in time, so in path) show beyond their
    noise. The first-order term above sees a change that grows along the span; an edge the cycle runs onto
    near its end is a step, which a straight line in s spreads thin: a path stopped at the force limit on a
    12 N/mm lump's edge read 2.66 ± 0.08 N/mm on tissue of 2.0 to 2.17 there, and the learner drew false
    lumps to explain four such readings. Halves whose centres lie half the span apart differ by Δ where the
    stiffness changes by 2Δ over the span; as a uniform spread, its sd is 2Δ/√12. Only the part of Δ² beyond
    the halves' own noise counts (their difference's variance subtracted: a moment estimate, as
    meta-analysis takes the spread between studies), so that a cycle on even linear tissue keeps its precision.

    The halves also swing over different depths (the first deeper, the second shallower), so on curved tissue
    their slopes differ where it is even, and one cycle cannot tell that from a change along the path: the
    spread covers either (a slope over the swing of curved tissue is no one number). Taking a parabola's
    curvature out first was tried: random sliding scans of touching-lumps then drew a false lump."""
    half = len(depth) // 2
    slopes = [_slope(depth[part], force[part]) for part in (slice(None, half), slice(half, None))]
    if any(slope is None for slope in slopes):
        return 0.0
    (k1, var1), (k2, var2) = slopes
    excess = (k2 - k1) ** 2 - (var1 + var2)
    return float(np.sqrt(max(excess, 0.0) / 3.0))


def _slope(depth, force) -> tuple[float, float] | None:
    """The least-squares slope of force on depth and its variance; None where it cannot be read."""
    if len(depth) < MIN_SAMPLES // 2 or np.ptp(depth) <= 0.0:
        return None
    slope, se = straight_slope(depth, force)
    return slope, se * se


def _along_path(xy) -> np.ndarray:
    centred = xy - xy.mean(axis=0)
    direction = xy[-1] - xy[0]
    length = float(np.hypot(*direction))
    return centred @ (direction / length) if length > 1e-6 else np.zeros(len(xy))
