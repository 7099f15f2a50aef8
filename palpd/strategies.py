"""Where to palpate next: fixed plans (raster, random) over the palpable rectangle."""
from __future__ import annotations

import math

import numpy as np

STRATEGIES = ("raster", "random", "active")


def raster_points(size_mm: tuple[float, float], max_points: int) -> list[tuple[float, float]]:
    """The largest square grid with at most max_points, edge to edge, in serpentine order."""
    side = max(1, math.isqrt(max_points))
    xs = _axis(size_mm[0], side)
    ys = _axis(size_mm[1], side)
    points = []
    for row, y in enumerate(ys):
        for x in (xs if row % 2 == 0 else xs[::-1]):  # serpentine: no long travel back
            points.append((x, y))
    return points


def raster_note(max_points: int) -> str | None:
    """What a raster makes of a budget that is not a square number (a square grid keeps the spacing the same
    along both sides, as the seed paper's 9 x 9 did), said to the user; None when the budget is all used."""
    side = max(1, math.isqrt(max_points))
    if side * side == max_points:
        return None
    return (f"raster: {side} x {side} = {side * side} point{'s' if side > 1 else ''} "
            f"(the largest square grid within {max_points})")


def random_points(size_mm: tuple[float, float], count: int, seed: int) -> list[tuple[float, float]]:
    rng = np.random.default_rng(seed)
    half = np.array(size_mm) / 2
    return [tuple(p) for p in rng.uniform(-half, half, size=(count, 2)).tolist()]


def _axis(length_mm: float, count: int) -> list[float]:
    if count == 1:
        return [0.0]
    return [float(v) for v in np.linspace(-length_mm / 2, length_mm / 2, count)]
