"""Turn real point-palpation readings into a measured-map scene (config/scenes/maps/garg-phantom.csv).

    .venv/bin/python scripts/make_real_map.py READINGS.csv [--baseline 8000] [--out maps/garg-phantom.csv]

READINGS.csv has the columns x_mm, y_mm, reading (others ignored): each a probe's raw value at one point of a
grid pressed to the same depth below the registered surface, as Garg et al. (CASE 2016) recorded a silicone
phantom with a dVRK arm (760 readings, a 40 x 20 grid over about 58 x 20 mm).

How a reading becomes stiffness (drivers/sim/scene.py, stiffness_from_readings; a scene can read such a CSV
itself, given tissue.map_baseline): pressed to one depth, the force is the stiffness times that depth, and the
probe's raw value is the force plus the sensor's offset (its value at no force). So the felt stiffness is
proportional to (reading - baseline); it is scaled so that the median reading reads as 0.12 N/mm, the shipped
scenes' tissue. The offset is not in the data: the baseline is a stated assumption (8000, some 700 units under
the softest reading); the stiff region found (its half-height area) is the same for baselines 7000-8500.
Each reading is kept as it is, point-to-point scatter and the gradient from the tilted surface included: the
simulator interpolates through every sample (Clough-Tocher), it does not smooth them away.
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from drivers.sim.scene import stiffness_from_readings  # noqa: E402

TISSUE_N_PER_MM = 0.12
OUT = ROOT / "config" / "scenes" / "maps" / "garg-phantom.csv"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("readings", type=Path)
    parser.add_argument("--baseline", type=float, default=8000.0)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    with args.readings.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    xy = np.array([(float(r["x_mm"]), float(r["y_mm"])) for r in rows])
    try:
        k = np.array(stiffness_from_readings([float(r["reading"]) for r in rows], args.baseline, TISSUE_N_PER_MM))
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    with args.out.open("w") as out:
        out.write("x_mm,y_mm,stiffness_n_per_mm\n")
        for (x, y), value in zip(xy, k):
            out.write(f"{x:.3f},{y:.3f},{value:.5f}\n")
    print(f"{args.out}: {len(k)} samples, {k.min():.4f}-{k.max():.4f} N/mm")


if __name__ == "__main__":
    main()
