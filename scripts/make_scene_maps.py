"""Write the measured-map CSVs of the scenes in config/scenes/maps/ (deterministic: rerun to check them).

    .venv/bin/python scripts/make_scene_maps.py

Each map is a grid of (x_mm, y_mm, stiffness_n_per_mm) samples over a 60 × 60 mm tissue, as a
dense palpation grid would measure it (dVRK-style phantoms are mapped on 1–2 mm grids), with a
relative measurement noise where a real map would have one:
- half-stiff.csv: a smooth stiff region covering about half the tissue, its edge a gentle curve
  with a ~6 mm wide rise, 2.5× the soft side, 2 % noise (a 1.5 mm grid);
- gradual-lump.csv: a lump whose stiffness rises gradually, like a Gaussian (sd 7 mm), 4.7× at
  its top: no sharp edge anywhere;
- elongated-lump.csv: an elongated lump, 12 × 5 mm semi-axes at 30°, 6.7× the tissue;
- narrow-lump.csv: a narrower one with a sharper edge, 10 × 4 mm at −50°, 4× the tissue (read along
  its axis it looks like a row of three circles);
- textured-half.csv: an 80 × 40 mm tissue whose left part is 2.5× stiffer, the region running past three
  of the tissue's edges, its boundary a slanted line with a ~8 mm wide rise, and 5 % texture (the
  tissue's own spot-to-spot variation, as a real phantom's map has it) on a 2 mm grid;
- textured-plain.csv: plain tissue, no lump, with 5 % texture on a 2 mm grid;
- touching-lumps.csv: touching-lumps' three lumps (5 mm, edges 2–4 mm apart, 6.7× the tissue, each with
  the power-law edge the simulator gives a lump 2 mm deep) as a 1 mm grid would measure them, 2 % noise.

    .venv/bin/python scripts/make_scene_maps.py --regions DIR

writes seven more maps with their scenes into DIR, none of them shipped: large smooth stiff regions unlike
half-stiff's (a quadrant, a straight diagonal half with a sharp rise, a band across the tissue, a broad
Gaussian rise, half-stiff on a coarse 3 mm grid with 4 % noise, two thirds of the tissue, two strips along
opposite edges), to try the learner on what it was not developed on (README, "Latest").
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent.parent / "config" / "scenes" / "maps"
TISSUE = 0.12


def grid(step_mm: float, half_mm=(30.0, 30.0)) -> np.ndarray:
    gx, gy = np.meshgrid(*(np.arange(-h, h + 1e-9, step_mm) for h in half_mm))
    return np.column_stack([gx.ravel(), gy.ravel()])


def half_stiff(xy: np.ndarray) -> np.ndarray:
    signed = xy[:, 0] + 0.3 * xy[:, 1] + 0.012 * xy[:, 1] ** 2 - 4.0  # > 0 on the stiff side
    return TISSUE * (1.0 + 1.5 / (1.0 + np.exp(-signed / 1.5)))


def gradual_lump(xy: np.ndarray) -> np.ndarray:
    r2 = (xy[:, 0] + 4.0) ** 2 + (xy[:, 1] - 6.0) ** 2
    return TISSUE + (0.56 - TISSUE) * np.exp(-r2 / (2.0 * 7.0**2))


def elongated_lump(xy: np.ndarray) -> np.ndarray:
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    ux, uy = xy[:, 0] - 3.0, xy[:, 1] + 2.0
    rho = np.hypot((c * ux + s * uy) / 12.0, (-s * ux + c * uy) / 5.0)
    return TISSUE + (0.8 - TISSUE) / (1.0 + rho**8)


def narrow_lump(xy: np.ndarray) -> np.ndarray:
    c, s = math.cos(math.radians(-50.0)), math.sin(math.radians(-50.0))
    ux, uy = xy[:, 0] - 8.0, xy[:, 1] + 10.0
    rho = np.hypot((c * ux + s * uy) / 10.0, (-s * ux + c * uy) / 4.0)
    return TISSUE + (0.48 - TISSUE) / (1.0 + np.exp((rho - 1.0) / 0.08))  # edge 0.3-0.8 mm wide


def textured_half(xy: np.ndarray) -> np.ndarray:
    signed = -xy[:, 0] - 5.0 + 0.2 * xy[:, 1]  # > 0 on the stiff side
    return TISSUE * (1.0 + 1.5 / (1.0 + np.exp(-signed / 2.0)))


def touching_lumps(xy: np.ndarray) -> np.ndarray:
    """The largest of three lumps' rises at each spot, with the simulator's own profile (drivers/sim/tissue.py)."""
    from drivers.sim.tissue import lump_profile, lump_sharpness

    rise = np.zeros(len(xy))
    for cx, cy in ((-8.0, 0.0), (4.0, 0.0), (-1.0, 13.5)):
        r_mm = np.hypot(xy[:, 0] - cx, xy[:, 1] - cy)
        rise = np.maximum(rise, (0.8 - TISSUE) * lump_profile(r_mm, 5.0, lump_sharpness(5.0, 2.0)))
    return TISSUE + rise


def _rise(signed: np.ndarray, width_mm: float) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-signed / width_mm))


# name: (grid step mm, relative noise, k(xy)); in this order (one noise stream runs through them)
REGIONS = {
    "quadrant": (1.5, 0.02, lambda p: TISSUE * (1 + 1.5 * _rise(p[:, 0] - 5, 1.5) * _rise(p[:, 1] - 5, 1.5))),
    "diagonal": (1.5, 0.02, lambda p: TISSUE * (1 + 2.0 * _rise((p[:, 0] + p[:, 1]) / math.sqrt(2) - 3, 0.8))),
    "stripe": (2.0, 0.02, lambda p: TISSUE * (1 + 1.5 * _rise(8 - np.abs(p[:, 1] - 2), 1.2))),
    "blob": (1.5, 0.02, lambda p: TISSUE * (1 + 2.0 * np.exp(-((p[:, 0] - 5) ** 2 + (p[:, 1] + 3) ** 2) / 288.0))),
    "coarse-half": (3.0, 0.04, lambda p: half_stiff(p)),
    "two-thirds": (1.5, 0.02, lambda p: TISSUE * (1 + 1.5 * _rise(p[:, 0] + 10 - 0.2 * p[:, 1], 1.5))),
    "two-strips": (1.5, 0.02, lambda p: TISSUE * (1 + 1.5 * _rise(np.abs(p[:, 0]) - 15, 1.5))),
}
REGION_SCENE = """name = "{name}"
seed = 4

[tissue]
size_mm = [60.0, 60.0]
stiffness_n_per_mm = 0.12
map = "{name}.csv"

[sensor]
noise_n = 0.01
tilt = true
"""


def write(name: str, xy: np.ndarray, k: np.ndarray, out: Path = OUT) -> None:
    rows = ["x_mm,y_mm,stiffness_n_per_mm"] + [f"{x:.2f},{y:.2f},{v:.5f}" for (x, y), v in zip(xy, k)]
    (out / name).write_text("\n".join(rows) + "\n")


def write_regions(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    for name, (step_mm, noise, k_at) in REGIONS.items():
        xy = grid(step_mm)
        write(f"{name}.csv", xy, k_at(xy) * (1.0 + noise * rng.standard_normal(len(xy))), out)
        (out / f"{name}.toml").write_text(REGION_SCENE.format(name=name))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--regions", type=Path, metavar="DIR", help="write the unshipped stiff-region maps here")
    args = parser.parse_args()
    if args.regions:
        write_regions(args.regions)
        return
    rng = np.random.default_rng(11)
    OUT.mkdir(parents=True, exist_ok=True)
    xy = grid(1.5)
    write("half-stiff.csv", xy, half_stiff(xy) * (1.0 + rng.normal(0.0, 0.02, len(xy))))
    xy = grid(1.0)
    write("gradual-lump.csv", xy, gradual_lump(xy))
    write("elongated-lump.csv", xy, elongated_lump(xy))
    write("narrow-lump.csv", xy, narrow_lump(xy))
    xy = grid(2.0, (40.0, 20.0))
    write("textured-half.csv", xy, textured_half(xy) * (1.0 + rng.normal(0.0, 0.05, len(xy))))
    xy = grid(2.0)
    write("textured-plain.csv", xy, TISSUE * (1.0 + rng.normal(0.0, 0.05, len(xy))))
    xy = grid(1.0)  # its own noise stream: added after the others, it leaves their noise as it was
    noise = np.random.default_rng(12).normal(0.0, 0.02, len(xy))
    write("touching-lumps.csv", xy, touching_lumps(xy) * (1.0 + noise))


if __name__ == "__main__":
    main()
