"""The dataset CSV: header `x_mm,y_mm,stiffness_n_per_mm[,tumor]` (DESIGN.md), written and read back.

Reading is kept apart from making datasets (dataset.py, which runs scans): the
learner reads a labelled training set and must not import what sits above it.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpd.errors import ConfigError, PalpdError

HEADER = ("x_mm", "y_mm", "stiffness_n_per_mm", "tumor")


@dataclass(frozen=True)
class Dataset:
    path: str
    xy_mm: np.ndarray  # (n, 2)
    stiffness_n_per_mm: np.ndarray
    tumor: np.ndarray | None  # 0/1 labels, None when the file has no tumor column


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


def read_training_set(path: str | Path) -> Dataset:
    """A dataset that can teach the supervised threshold (learner.training_set): labelled, both classes present;
    otherwise one ConfigError naming the file. Light enough for a command to check before it imports a scan."""
    data = read_dataset(path)
    if data.tumor is None:
        raise ConfigError(f"learner.training_set {path}: no tumor column, so nothing to learn a threshold from")
    if not data.tumor.any() or data.tumor.all():
        raise ConfigError(f"learner.training_set {path}: needs both tumor (1) and tissue (0) rows")
    return data


def _row(path: Path, line: int, row: dict, labelled: bool) -> tuple:
    try:
        x, y, k = (float(row[c]) for c in ("x_mm", "y_mm", "stiffness_n_per_mm"))
        tumor = int(row["tumor"]) if labelled else 0
    except (TypeError, ValueError):
        raise PalpdError(f"{path}:{line}: x_mm, y_mm, stiffness_n_per_mm must be numbers and tumor 0 or 1") from None
    if not all(map(math.isfinite, (x, y, k))) or k <= 0 or tumor not in (0, 1):
        raise PalpdError(f"{path}:{line}: values must be finite, the stiffness positive and tumor 0 or 1")
    return x, y, k, tumor
