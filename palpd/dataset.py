"""Making palpation datasets (x, y, stiffness[, tumor]) through the simulated robot; the file format is datafile.py.

A dataset is made exactly like a scan (same servo loop, palpation and
stiffness fit); only the points differ: a raster, uniform random points, or
`manual` coverage like the seed paper's hand-guided sets (§5.2), denser in a
few places the hand lingered and sparse elsewhere.
"""
from __future__ import annotations

import numpy as np

from palpd import strategies
from palpd.datafile import HEADER, Dataset, read_dataset, to_csv  # noqa: F401  (the format, re-exported)
from palpd.errors import UsageError

PATTERNS = ("raster", "random", "manual")


def manual_points(size_mm, count: int, seed: int) -> list[tuple[float, float]]:
    """Uneven, hand-like coverage: clusters where the hand lingered, a sparse sweep elsewhere, in visiting order."""
    rng = np.random.default_rng(seed)
    half = np.asarray(size_mm, dtype=float) / 2
    centres = rng.uniform(-0.7 * half, 0.7 * half, size=(rng.integers(3, 6), 2))
    weights = rng.dirichlet(np.ones(len(centres)))
    clustered = int(round(0.6 * count))
    which = rng.choice(len(centres), size=clustered, p=weights)
    points = centres[which] + rng.normal(0.0, 0.22 * half, size=(clustered, 2))
    points = np.vstack([points, rng.uniform(-half, half, size=(count - clustered, 2))])
    points = np.clip(points, -half, half)
    return [tuple(map(float, p)) for p in _visiting_order(points)]


def _visiting_order(points: np.ndarray) -> np.ndarray:
    """Nearest neighbour first, as a hand moves on to the next spot close by."""
    left, order = list(range(len(points))), [0]
    left.remove(0)
    while left:
        last = points[order[-1]]
        nearest = min(left, key=lambda i: float(np.sum((points[i] - last) ** 2)))
        order.append(nearest)
        left.remove(nearest)
    return points[order]


def pattern_points(pattern: str, size_mm, count: int, seed: int) -> list[tuple[float, float]]:
    if pattern == "raster":
        return strategies.raster_points(size_mm, count)
    if pattern == "random":
        return strategies.random_points(size_mm, count, seed)
    if pattern == "manual":
        return manual_points(size_mm, count, seed)
    raise UsageError(f"unknown pattern {pattern!r}; choose from {', '.join(PATTERNS)}")


def rotated(scene, rotation_deg: float):
    """The scene with its tissue turned by rotation_deg, as the paper's test sets were."""
    return scene.model_copy(update={"placement": scene.placement.model_copy(update={"rotation_deg": rotation_deg})})


def make_dataset(settings, scene, pattern: str, count: int, seed: int, progress=None) -> tuple[list[tuple], dict]:
    """Rows (x_mm, y_mm, stiffness_n_per_mm, tumor) of the fitted palpations, and the scan report.

    progress(done, total, probe) is called after each palpation."""
    from drivers.sim.scene import truth_lumps
    from palpd.bench import open_simulated_bench
    from palpd.scan import FixedPlan, run_scan

    points = pattern_points(pattern, scene.tissue.size_mm, count, seed)
    report = run_scan(open_simulated_bench(settings, scene, seed=seed), settings, FixedPlan(points), progress)
    fitted = [p for p in report["probes"] if p["stiffness_n_per_mm"] is not None]
    labels = label_tumor([p["xy_mm"] for p in fitted], truth_lumps(scene))
    return [(*p["xy_mm"], p["stiffness_n_per_mm"], t) for p, t in zip(fitted, labels)], report


def label_tumor(xy_mm, truth_lumps: list[dict]) -> list[int]:
    """1 where a point lies within a true lump (the paper's registered trace; its outline where it has one: a 3-D
    inclusion's footprint), else 0."""
    from palpd.metrics import inside_truth

    points = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    inside = np.zeros(len(points), dtype=bool)
    for lump in truth_lumps:
        inside |= inside_truth(points, lump)
    return inside.astype(int).tolist()
