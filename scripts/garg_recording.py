"""Turn a recording of the public repository of Garg et al. (CASE 2016, `yjen/palpation_strategy`) into a scene.

    .venv/bin/python scripts/garg_recording.py RECORDING.p OUT_DIR [--baseline B]

The repository keeps its recordings as Python 2 pickles in two layouts, both read here:
- a list of [reading, 4 x 4 pose in m] (`scripts/experiments/exp*.p`, sliding rasters; the point-probe grids of
  `scripts/saved_palpation_data/point_probe_*.p`): the probe's raw value at the pose's position;
- a dict with `data`, rows of [x m, y m, reading] (`scripts/saved_palpation_data/dense_grid_*.p`).

Writes OUT_DIR/NAME.csv (`x_mm,y_mm,z_mm,reading`, the points in a frame centred on them with x along their long
side, as the shipped garg-phantom's readings are) and OUT_DIR/NAME.toml, a scene that reads them itself
(`tissue.map_baseline`, docs/how-to/scenes.md), its tissue the points' extent. The probe's value at no force is
not in the data: the baseline is a stated assumption, 700 under the 1st percentile of the readings (rounded down
to 100) unless given, as for the shipped map; readings at or under it (a press that never touched) are left out
and counted. A pickle can run code as it loads: convert only files from a source you trust.
"""
from __future__ import annotations

import argparse
import math
import pickle
import sys
import warnings
from pathlib import Path

import numpy as np

BASELINE_MARGIN = 700.0  # the shipped map's: its baseline 8000 lies ~700 under its softest reading


def read_recording(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(xy mm (n × 2), z mm (n), readings (n)) in the robot's frame."""
    with path.open("rb") as handle:
        try:
            with warnings.catch_warnings():  # numpy's note that matrices are not recommended: the file's, not ours
                warnings.simplefilter("ignore", PendingDeprecationWarning)
                data = pickle.load(handle, encoding="latin1")  # Python 2 pickles (numpy matrices among them)
        except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, IndexError, TypeError) as exc:
            raise ValueError(f"{path}: not a recording's pickle ({exc})") from None
    if isinstance(data, dict) and "data" in data:
        rows = np.asarray(data["data"], dtype=float)
        return rows[:, :2] * 1000.0, np.zeros(len(rows)), rows[:, 2]
    if isinstance(data, list) and data and len(data[0]) == 2:
        readings = np.array([float(reading) for reading, _ in data])
        positions = np.array([np.asarray(pose, dtype=float)[:3, 3] for _, pose in data]) * 1000.0
        return positions[:, :2], positions[:, 2], readings
    raise ValueError(f"{path}: neither a list of [reading, pose] nor a dict with 'data' rows")


def tissue_frame(xy: np.ndarray) -> np.ndarray:
    """The points centred on their extent, x along their long side (their principal axis)."""
    centred = xy - xy.mean(axis=0)
    _, axes = np.linalg.eigh(np.cov(centred.T))
    turned = centred @ axes[:, ::-1]
    return turned - (turned.max(axis=0) + turned.min(axis=0)) / 2.0


def default_baseline(readings: np.ndarray) -> float:
    return math.floor((float(np.percentile(readings, 1)) - BASELINE_MARGIN) / 100.0) * 100.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--baseline", type=float, default=None)
    args = parser.parse_args(argv)
    try:
        xy, z, readings = read_recording(args.recording)
    except (OSError, ValueError) as exc:
        print(f"garg_recording: {exc}", file=sys.stderr)
        return 1
    baseline = default_baseline(readings) if args.baseline is None else args.baseline
    touched = readings > baseline
    frame = tissue_frame(xy[touched])
    name = args.recording.stem
    args.out.mkdir(parents=True, exist_ok=True)
    with (args.out / f"{name}.csv").open("w") as out:
        out.write("x_mm,y_mm,z_mm,reading\n")
        for (x, y), height, reading in zip(frame, z[touched] - z[touched].mean(), readings[touched]):
            out.write(f"{x:.3f},{y:.3f},{height:.3f},{reading:.2f}\n")
    size = np.ceil(np.ptp(frame, axis=0) * 10.0) / 10.0
    (args.out / f"{name}.toml").write_text(
        f'# {args.recording.name} of yjen/palpation_strategy (scripts/garg_recording.py)\nname = "{name}"\nseed = 0\n\n'
        f'[tissue]\nsize_mm = [{size[0]}, {size[1]}]\nstiffness_n_per_mm = 0.12\nmap = "{name}.csv"\n'
        f"map_baseline = {baseline:g}\n\n[sensor]\nnoise_n = 0.01\ntilt = true\n")
    left_out = int(np.count_nonzero(~touched))
    print(f"{args.out / name}.toml: {touched.sum()} readings over {size[0]} x {size[1]} mm, baseline {baseline:g}"
          + (f" ({left_out} at or under it left out: presses that never touched)" if left_out else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
