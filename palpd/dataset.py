"""Palpation datasets: CSV files of (x, y, stiffness[, tumor]) made through the simulated robot, and read back.

A dataset is made exactly like a scan (same servo loop, palpation and
stiffness fit); only the points differ: a raster, uniform random points, or
`manual` coverage like the seed paper's hand-guided sets (§5.2), denser in a
few places the hand lingered and sparse elsewhere.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpd import strategies
from palpd.errors import PalpdError, UsageError

PATTERNS = ("raster", "random", "manual")
HEADER = ("x_mm", "y_mm", "stiffness_n_per_mm", "tumor")


@dataclass(frozen=True)
class Dataset:
    path: str
    xy_mm: np.ndarray  # (n, 2)
    stiffness_n_per_mm: np.ndarray
    tumor: np.ndarray | None  # 0/1 labels, None when the file has no tumor column


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
    """1 where a point lies within a true lump's radius (the paper's registered trace), else 0."""
    return [int(any(math.dist(xy, lump["center_mm"]) <= lump["radius_mm"] for lump in truth_lumps)) for xy in xy_mm]


def to_csv(rows) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(HEADER)
    for x, y, k, tumor in rows:
        writer.writerow([f"{x:.3f}", f"{y:.3f}", f"{k:.6f}", tumor])
    return out.getvalue()


def read_dataset(path: str | Path) -> Dataset:
    """Rows with a finite position and a positive stiffness; a bad file is one clear PalpdError."""
    path = Path(path)
    try:
        with path.open(newline="") as handle:
            reader = csv.DictReader(handle)
            columns = set(reader.fieldnames or [])
            missing = {"x_mm", "y_mm", "stiffness_n_per_mm"} - columns
            if missing:
                raise PalpdError(f"{path}: missing column(s) {', '.join(sorted(missing))}")
            rows = [_row(path, number + 2, row, "tumor" in columns) for number, row in enumerate(reader)]
    except OSError as exc:
        raise PalpdError(f"{path}: cannot read dataset: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise PalpdError(f"{path}: not a text CSV file") from None
    values = np.array([r[:3] for r in rows], dtype=float).reshape(-1, 3)
    tumor = np.array([r[3] for r in rows], dtype=int) if "tumor" in columns else None
    return Dataset(str(path), values[:, :2], values[:, 2], tumor)


def _row(path: Path, line: int, row: dict, labelled: bool) -> tuple:
    try:
        x, y, k = (float(row[c]) for c in ("x_mm", "y_mm", "stiffness_n_per_mm"))
        tumor = int(row["tumor"]) if labelled else 0
    except (TypeError, ValueError):
        raise PalpdError(f"{path}:{line}: x_mm, y_mm, stiffness_n_per_mm must be numbers and tumor 0 or 1") from None
    if not all(map(math.isfinite, (x, y, k))) or k <= 0 or tumor not in (0, 1):
        raise PalpdError(f"{path}:{line}: values must be finite, the stiffness positive and tumor 0 or 1")
    return x, y, k, tumor
