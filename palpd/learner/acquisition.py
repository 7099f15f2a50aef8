"""Where to palpate: a space-filling first design, then the 50 % boundary.

The acquisition is Bryan et al.'s straddle, z·σ − |μ − τ|, with z = Φ⁻¹(c) so
that it is positive exactly where P(lump) is between 1 − c and c: the learner
probes where it is least sure, and stops when little of that area is left.
It is divided by the robot time the move adds (travel at the travel speed,
in units of one palpation), and cells closer than the minimum spacing to a
probe are never chosen again.
"""
from __future__ import annotations

import numpy as np
from scipy.special import ndtri
from scipy.stats import qmc


def initial_design(size_mm: tuple[float, float], count: int, seed: int) -> list[tuple[float, float]]:
    """`count` scrambled Halton points over the area, in a short nearest-neighbour tour."""
    if count <= 0:
        return []
    half = np.asarray(size_mm, dtype=float) / 2.0
    unit = qmc.Halton(d=2, scramble=True, seed=seed).random(count)
    points = qmc.scale(unit, -half, half)
    return _tour(points, start=np.zeros(2))


def _tour(points: np.ndarray, start: np.ndarray) -> list[tuple[float, float]]:
    left = list(range(len(points)))
    here, order = start, []
    while left:
        nearest = min(left, key=lambda i: float(np.hypot(*(points[i] - here))))
        left.remove(nearest)
        here = points[nearest]
        order.append((float(here[0]), float(here[1])))
    return order


def straddle(mean: np.ndarray, std: np.ndarray, tau: np.ndarray, confidence: float) -> np.ndarray:
    return float(ndtri(confidence)) * std - np.abs(mean - tau)


def best_candidate(score: np.ndarray, grid_xy: np.ndarray, blocked: np.ndarray, here_mm,
                   travel_mm_per_palpation: float) -> tuple[float, float] | None:
    """The grid cell with the most straddle per unit of robot time, or None if nothing is ambiguous."""
    usable = (score > 0.0) & ~blocked
    if not usable.any():
        return None
    gain = np.where(usable, score, -np.inf)
    if here_mm is not None:
        travel = np.hypot(grid_xy[:, 0] - here_mm[0], grid_xy[:, 1] - here_mm[1])
        gain = gain / (1.0 + travel / travel_mm_per_palpation)
    best = int(np.argmax(gain))
    return float(grid_xy[best, 0]), float(grid_xy[best, 1])


def block_near(blocked: np.ndarray, grid_xy: np.ndarray, xy_mm, spacing_mm: float) -> None:
    """Mark the cells within the minimum spacing of a new probe."""
    near = np.hypot(grid_xy[:, 0] - xy_mm[0], grid_xy[:, 1] - xy_mm[1]) < spacing_mm
    blocked |= near
