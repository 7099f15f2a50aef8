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
  the power-law edge the simulator gives a lump 2 mm deep) as a 1 mm grid would measure them, 2 % noise;
- cone-lump.csv: a lump whose stiffness rises linearly to a point, 4.5× the tissue at its top, 16 mm
  from its top to where it meets the tissue (its half-height 8 mm out): tails that end, a top with no
  plateau, 2 % noise on a 1.5 mm grid.

    .venv/bin/python scripts/make_scene_maps.py --regions DIR

writes seven more maps with their scenes into DIR, none of them shipped: large smooth stiff regions unlike
half-stiff's (a quadrant, a straight diagonal half with a sharp rise, a band across the tissue, a broad
Gaussian rise, half-stiff on a coarse 3 mm grid with 4 % noise, two thirds of the tissue, two strips along
opposite edges), to try the learner on what it was not developed on (README, "Latest").

    .venv/bin/python scripts/make_scene_maps.py --profiles DIR

writes eleven more, lumps whose profiles the simulator does not make (a cone, two Gaussian bumps, a flat
top with a linear ramp, an ellipse ending near the tissue's edge, a stiff region around a corner of an
80 × 60 mm tissue, a lump on a background that stiffens across the tissue, plain tissue with 2 % noise;
then four lumps whose rise ends: a low cone, a large cone, a paraboloid's cap, a flat top with a wide
ramp): the same kind of try (README, "Tried beyond" and "Latest").

    .venv/bin/python scripts/make_scene_maps.py --steps DIR

writes eight stiff inclusions drawn by hand as steps (0.5 N/mm in 0.12, nothing between) on 0.5-2 mm grids,
none of them shipped (README, "Scenes": what the learner does with a staircase edge).

    .venv/bin/python scripts/make_scene_maps.py --shapes DIR

writes two regions no parametric family draws (issue 48), none shipped: a C and a rounded rectangle.
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


def cone_lump(xy: np.ndarray) -> np.ndarray:
    return TISSUE + (0.54 - TISSUE) * np.clip(1.0 - _distance(xy, -7.0, 5.0) / 16.0, 0.0, 1.0)


def c_shape(xy: np.ndarray) -> np.ndarray:
    """A ring 8-16 mm from (-1.5, 0) with its right quarter open (a C), 5× the tissue, its edge ~0.5 mm wide:
    no disc, ellipse or few of them draws it."""
    r = _distance(xy, -1.5, 0.0)
    angle = np.degrees(np.abs(np.arctan2(xy[:, 1], xy[:, 0] + 1.5)))  # 0 along +x
    inside = np.minimum(np.minimum(r - 8.0, 16.0 - r), (angle - 45.0) * np.radians(1.0) * r)  # > 0 in the C
    return TISSUE + (0.62 - TISSUE) * _rise(inside, 0.25)


def rounded_rectangle(xy: np.ndarray) -> np.ndarray:
    """A 24 × 12 mm rectangle centred at (3, -2), corners rounded to 2 mm, 5× the tissue, its edge ~0.5 mm wide:
    straight sides an ellipse only approximates."""
    half = np.array([12.0, 6.0]) - 2.0
    q = np.abs(xy - np.array([3.0, -2.0])) - half
    outside = np.hypot(*np.maximum(q, 0.0).T) + np.minimum(np.max(q, axis=1), 0.0) - 2.0  # signed distance
    return TISSUE + (0.62 - TISSUE) * _rise(-outside, 0.25)


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
def _distance(p: np.ndarray, cx: float, cy: float) -> np.ndarray:
    return np.hypot(p[:, 0] - cx, p[:, 1] - cy)


def _ellipse_at_edge(p: np.ndarray) -> np.ndarray:
    """15 x 6 mm semi-axes at 70 degrees, its end 5 mm from the tissue's edge, 5.8x the tissue."""
    c, s = math.cos(math.radians(70.0)), math.sin(math.radians(70.0))
    ux, uy = p[:, 0] - 20.0, p[:, 1] - 2.0
    rho = np.hypot((c * ux + s * uy) / 15.0, (-s * ux + c * uy) / 6.0)
    return TISSUE + 0.58 / (1.0 + rho**6)


# Lumps of profiles the simulator does not make (its lumps are Hill profiles, drivers/sim/tissue.py): name:
# (tissue size mm, grid step mm, relative noise, k(xy)), in this order (one noise stream runs through them)
PROFILES = {
    # a cone: the stiffness rises linearly to a point at the centre; half height 7 mm out
    "cone": ((60, 60), 1.5, 0.02, lambda p: TISSUE + 0.48 * np.clip(1 - _distance(p, 6, -4) / 14, 0, 1)),
    # two Gaussian bumps, sd 4 and 6 mm, 5.8x and 3.8x the tissue
    "two-bumps": ((60, 60), 1.5, 0.02, lambda p: TISSUE + np.maximum(0.58 * np.exp(-_distance(p, -14, 10) ** 2 / 32),
                                                                     0.33 * np.exp(-_distance(p, 12, -12) ** 2 / 72))),
    # a flat top and a linear ramp 3 mm wide, half height 9.5 mm out
    "plateau": ((60, 60), 1.5, 0.02, lambda p: TISSUE + 0.38 * np.clip((11 - _distance(p, -5, -3)) / 3, 0, 1)),
    "ellipse-at-edge": ((60, 60), 1.5, 0.02, _ellipse_at_edge),
    # a stiff region around one corner of an 80 x 60 mm tissue, on a 2 mm grid with 3 % noise
    "corner": ((80, 60), 2.0, 0.03, lambda p: TISSUE * (1 + 1.8 * _rise(35 - _distance(p, 40, 30), 2.0))),
    # a lump 5x stiffer than a background that itself stiffens 1.3x across the tissue
    "sloped-lump": ((60, 60), 1.5, 0.02, lambda p: TISSUE * np.exp(0.125 * p[:, 0] / 30) * (
        1 + 4 / (1 + (_distance(p, 8, 9) / 6) ** 8))),
    # no lump: plain tissue with 2 % noise on a 1.5 mm grid
    "plain": ((60, 60), 1.5, 0.02, lambda p: np.full(len(p), TISSUE)),
    # lumps whose rise ends (after the seven above, whose noise it leaves as it was): a low cone (2x, meeting
    # the tissue 12 mm out, half height 6 mm out), a large one (10x, 20 mm, 10 mm), a paraboloid's cap (4x,
    # 12 mm, 8.49 mm) and a flat top of 4 mm with a 10 mm linear ramp (4.3x, half height 9 mm out)
    "low-cone": ((60, 60), 1.5, 0.02, lambda p: TISSUE + 0.12 * np.clip(1 - _distance(p, -4, 2) / 12, 0, 1)),
    "big-cone": ((60, 60), 1.5, 0.02, lambda p: TISSUE + 1.08 * np.clip(1 - _distance(p, 3, 3) / 20, 0, 1)),
    "cap": ((60, 60), 1.5, 0.02, lambda p: TISSUE + 0.36 * np.clip(1 - (_distance(p, 2, -6) / 12) ** 2, 0, 1)),
    "ramp": ((60, 60), 1.5, 0.02, lambda p: TISSUE + 0.40 * np.clip((14 - _distance(p, -3, 5)) / 10, 0, 1)),
}
def _disc(cx: float, cy: float, r: float):
    return lambda p: _distance(p, cx, cy) <= r


def _inside_ellipse(cx: float, cy: float, a: float, b: float, degrees: float):
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    def inside(p: np.ndarray) -> np.ndarray:
        u, v = (p[:, 0] - cx) * c + (p[:, 1] - cy) * s, -(p[:, 0] - cx) * s + (p[:, 1] - cy) * c
        return (u / a) ** 2 + (v / b) ** 2 <= 1.0
    return inside


def _step(inside):
    """A stiff inclusion drawn by hand: 0.5 N/mm inside, the tissue's 0.12 outside, nothing between."""
    return lambda p: np.where(inside(p), 0.5, TISSUE)


# Stiff inclusions drawn as steps (README, "Scenes" and "Still open"): discs of 4, 6, 10 (2 mm grid), 8 (0.5 mm)
# and 7 mm (2 mm, no noise), a 6 x 2.5 mm ellipse at 30°, a 16 mm square, two 6 mm discs.
# Regions no parametric family draws (issue 48): a C (a ring 8-16 mm out, a quarter of it open) and a 24 x 12 mm
# rectangle with 2 mm corners, each 5x the tissue with a ~0.5 mm edge, 2 % noise on a 1 mm grid.
SHAPES = {"c-shape": ((60, 60), 1.0, 0.02, c_shape), "rounded-rectangle": ((60, 60), 1.0, 0.02, rounded_rectangle)}
STEPS = {
    "d4": ((60, 60), 1.0, 0.02, _step(_disc(5, -3, 4))),
    "d6": ((60, 60), 1.0, 0.02, _step(_disc(-8, 6, 6))),
    "d10g2": ((60, 60), 2.0, 0.02, _step(_disc(3, 2, 10))),
    "ell": ((60, 60), 1.0, 0.02, _step(_inside_ellipse(2, -4, 6, 2.5, 30))),
    "square": ((60, 60), 1.0, 0.02, _step(lambda p: np.maximum(np.abs(p[:, 0] - 4), np.abs(p[:, 1] + 3)) <= 8)),
    "two": ((60, 60), 1.0, 0.02, _step(lambda p: _disc(-12, -8, 6)(p) | _disc(12, 10, 6)(p))),
    "d8g05": ((60, 60), 0.5, 0.02, _step(_disc(-4, 3, 8))),
    "d7g2q": ((60, 60), 2.0, 0.0, _step(_disc(6, 5, 7))),
}
REGION_SCENE = """name = "{name}"
seed = 4

[tissue]
size_mm = [{width:.1f}, {height:.1f}]
stiffness_n_per_mm = 0.12
map = "{name}.csv"

[sensor]
noise_n = 0.01
tilt = true
"""
# the step maps' scenes take the bench's default seed (as `palpd scan --scene FILE` does), which is how they were
# first measured
STEP_SCENE = REGION_SCENE.replace("seed = 4\n", "")


def write(name: str, xy: np.ndarray, k: np.ndarray, out: Path = OUT) -> None:
    rows = ["x_mm,y_mm,stiffness_n_per_mm"] + [f"{x:.2f},{y:.2f},{v:.5f}" for (x, y), v in zip(xy, k)]
    (out / name).write_text("\n".join(rows) + "\n")


def write_regions(out: Path) -> None:
    write_maps(out, {name: ((60, 60), *rest) for name, rest in REGIONS.items()})


def write_maps(out: Path, maps: dict, scene: str | None = None) -> None:
    """Each map's CSV and a scene that palpates it (REGION_SCENE unless given), into `out`."""
    scene = REGION_SCENE if scene is None else scene
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    for name, ((width, height), step_mm, noise, k_at) in maps.items():
        xy = grid(step_mm, (width / 2.0, height / 2.0))
        write(f"{name}.csv", xy, k_at(xy) * (1.0 + noise * rng.standard_normal(len(xy))), out)
        (out / f"{name}.toml").write_text(scene.format(name=name, width=width, height=height))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--regions", type=Path, metavar="DIR", help="write the unshipped stiff-region maps here")
    parser.add_argument("--profiles", type=Path, metavar="DIR", help="write the unshipped lump-profile maps here")
    parser.add_argument("--steps", type=Path, metavar="DIR", help="write the unshipped maps drawn as steps here")
    parser.add_argument("--shapes", type=Path, metavar="DIR", help="write the unshipped C and rectangle maps here")
    args = parser.parse_args()
    if args.regions or args.profiles or args.steps or args.shapes:
        if args.regions:
            write_regions(args.regions)
        if args.profiles:
            write_maps(args.profiles, PROFILES)
        if args.steps:
            write_maps(args.steps, STEPS, STEP_SCENE)
        if args.shapes:
            write_maps(args.shapes, SHAPES)
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
    xy = grid(1.5)
    noise = np.random.default_rng(13).normal(0.0, 0.02, len(xy))
    write("cone-lump.csv", xy, cone_lump(xy) * (1.0 + noise))


if __name__ == "__main__":
    main()
