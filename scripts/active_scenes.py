"""Active scans with default settings on every scene in config/scenes/ (or the ones named), as a table.

    .venv/bin/python scripts/active_scenes.py [--seed N | --seeds 0,1,2] [--raster-too] [SCENE ...]
    .venv/bin/python scripts/active_scenes.py --random N [--random-seed S] [--raster-too]
    .venv/bin/python scripts/active_scenes.py --varied N [--random-seed S] [--raster-too]
    .venv/bin/python scripts/active_scenes.py --soft N [--random-seed S] [--raster-too]
    add --config FILE (TOML) to any of them for other settings, e.g. [learner] coverage_mm = 11


Each row is `palpd scan --scene SCENE --strategy active` with default settings (simulated time, the
real control and fit code, in this process): palpations, robot time, the verdict and the model the
evidence chose (with its weight), and the errors against the scene's truth. With --raster-too, a raster
scan of the same number of palpations is scored beside it (its readings weighed by the learner, as every
fixed plan's are). With --seeds, every scene once per seed (the scan's and the simulator's), then one
summary row per scene: how often the count was right (every lump found, none false), palpations (median and most), the worst errors and IoU.
With --random, N scenes none of which ships, drawn from --random-seed (tissue size and stiffness, one to
three lumps that do not touch, of any radius, depth and contrast in the ranges below, any sensor noise):
the same table and one summary row, so that what the learner decides is tried beyond the scenes it was
developed on. --varied N draws from a wider range still (varied_scenes: tissues not square, hardening,
damped, with friction, turned on the bench, lumps partly past the tissue's edge, some scenes with none).
--soft N draws scenes with a soft inclusion (soft_scenes: a cyst, no lump) and none to two lumps beside it.
"""
from __future__ import annotations

import argparse
import math
import random
import sys
from pathlib import Path

from palpd.threads import pin_blas_to_one_thread

pin_blas_to_one_thread()

from drivers.sim.scene import Scene, load_scene  # noqa: E402
from palpd import metrics  # noqa: E402
from palpd.bench import open_simulated_bench  # noqa: E402
from palpd.config import Settings, load_settings  # noqa: E402
from palpd.errors import ConfigError  # noqa: E402
from palpd.scan import plan, run_scan  # noqa: E402

HEADER = ("| scene | palpations | robot time | verdict | model (weight) | found | false | centre error | radius error "
          "| IoU |\n|---|---|---|---|---|---|---|---|---|---|")
SUMMARY_HEADER = ("\n| scene | count right | palpations (median) | (most) | undetermined | worst centre error (mm) "
                  "| worst radius error (mm) | worst IoU |\n|---|---|---|---|---|---|---|---|")
SCENES = Path(__file__).resolve().parent.parent / "config" / "scenes"
BASE = [Settings()]  # the settings every scan starts from (--config replaces them)


def scan(scene, strategy: str, budget: int, seed: int) -> tuple[dict, dict]:
    settings = BASE[0].updated(scan={"strategy": strategy, "seed": seed})
    planner = plan(strategy, scene.tissue.size_mm, budget, seed, settings)
    report = run_scan(open_simulated_bench(settings, scene, seed=seed), settings, planner)
    truth = metrics.scene_truth(scene, settings.scan.min_contrast)
    return report, metrics.compare(truth, report["lumps"], scene.tissue.size_mm)


def row(name: str, report: dict, m: dict) -> str:
    model = report["model"]
    chosen = f"{model['chosen']} ({model['weight']:.3f})" if model else "–"
    def mm(v):
        return "–" if v is None else f"{v:.2f} mm"
    iou = "–" if m["min_iou"] is None else f"{m['min_iou']:.3f}"
    return (f"| {name} | {report['palpations']} | {report['robot_time_s']:.1f} s | {report['verdict']} | {chosen} | "
            f"{m['lumps_found']}/{m['lumps_true']} | {m['false_lumps']} | {mm(m['max_center_error_mm'])} | "
            f"{mm(m['max_radius_error_mm'])} | {iou} |")


def summary(name: str, runs: list[tuple[dict, dict]]) -> str:
    """One row over seeds: count right, palpations (median, most), worst centre and radius error, worst IoU."""
    right = sum(m["lumps_found"] == m["lumps_true"] and m["false_lumps"] == 0 for _, m in runs)
    palpations = sorted(r["palpations"] for r, _ in runs)
    undetermined = sum(r["verdict"] == "undetermined" for r, _ in runs)
    def worst(key, pick=max):
        values = [m[key] for _, m in runs if m[key] is not None]
        return "–" if not values else f"{pick(values):.2f}"
    return (f"| {name} | {right}/{len(runs)} | {palpations[len(palpations) // 2]} | {palpations[-1]} | {undetermined} | "
            f"{worst('max_center_error_mm')} | {worst('max_radius_error_mm')} | {worst('min_iou', min)} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seeds", default=None, help="comma-separated seeds: every scene once per seed, and a summary")
    parser.add_argument("--raster-too", action="store_true")
    parser.add_argument("--random", type=int, default=0, metavar="N", help="N random scenes instead of the shipped ones")
    parser.add_argument("--varied", type=int, default=0, metavar="N",
                        help="N random scenes of the wider range (varied_scenes) instead of the shipped ones")
    parser.add_argument("--soft", type=int, default=0, metavar="N",
                        help="N random scenes with a soft inclusion (soft_scenes) instead of the shipped ones")
    parser.add_argument("--random-seed", type=int, default=0)
    parser.add_argument("--config", default=None, metavar="FILE", help="settings (TOML) instead of the defaults")
    args = parser.parse_args()
    if args.config:
        try:
            BASE[0] = load_settings(args.config)
        except ConfigError as exc:
            print(f"active_scenes: {exc}", file=sys.stderr)
            return 2
    if args.random:
        return tried_beyond(random_scenes(args.random, args.random_seed), args.raster_too)
    if args.varied:
        return tried_beyond(varied_scenes(args.varied, args.random_seed), args.raster_too)
    if args.soft:
        return tried_beyond(soft_scenes(args.soft, args.random_seed), args.raster_too)
    names = args.scenes or sorted(p.stem for p in SCENES.glob("*.toml"))
    if args.seeds:
        return sweep(names, [int(s) for s in args.seeds.split(",")])
    print(HEADER)
    for name in names:
        scene = load_scene(SCENES / f"{name}.toml")
        report, m = scan(scene, "active", BASE[0].learner.max_palpations, args.seed)
        print(row(name, report, m), flush=True)
        if args.raster_too:
            raster, rm = scan(scene, "raster", report["palpations"], args.seed)
            print(row(f"{name} (raster, same count)", raster, rm), flush=True)
    return 0


def sweep(names: list[str], seeds: list[int]) -> int:
    print(HEADER)
    rows = []
    for name in names:
        scene = load_scene(SCENES / f"{name}.toml")
        runs = [scan(scene, "active", BASE[0].learner.max_palpations, seed) for seed in seeds]
        for seed, (report, m) in zip(seeds, runs):
            print(row(f"{name} (seed {seed})", report, m), flush=True)
        rows.append(summary(name, runs))
    print(SUMMARY_HEADER)
    print("\n".join(rows))
    return 0


def random_scenes(count: int, seed: int) -> list[Scene]:
    """Scenes drawn at random: tissue 50-80 mm across and 0.05-0.4 N/mm; one to three lumps 3-12 mm in
    radius, 1-8 mm deep, 2.5-8 times as stiff, wholly on the tissue and at least 6 mm apart edge to edge
    (touching lumps are a shipped scene of their own); sensor noise 0.005-0.06 N."""
    rng = random.Random(seed)
    scenes = []
    for i in range(count):
        size = rng.choice([50.0, 60.0, 80.0])
        tissue_k = math.exp(rng.uniform(math.log(0.05), math.log(0.4)))
        lumps: list[dict] = []
        for _ in range(rng.choices([1, 2, 3], [0.5, 0.3, 0.2])[0]):
            _add_lump(rng, size, tissue_k, lumps)
        scenes.append(_square_scene(rng, f"random-{seed}-{i}", seed * 1000 + i, size, tissue_k, lumps))
    return scenes


def _square_scene(rng: random.Random, name: str, seed: int, size: float, tissue_k: float, lumps: list[dict]) -> Scene:
    """A square tissue of `size` with the lumps, its sensor noise drawn from 0.005-0.06 N."""
    return Scene(name=name, seed=seed, tissue={"size_mm": [size, size], "stiffness_n_per_mm": tissue_k}, lump=lumps,
                 sensor={"noise_n": rng.choice([0.005, 0.01, 0.03, 0.06]), "tilt": True})


def _add_lump(rng: random.Random, size: float, tissue_k: float, lumps: list[dict]) -> None:
    """One lump 3-12 mm in radius, 1-8 mm deep, 2.5-8 times as stiff, wholly on a square tissue of `size` and
    at least 6 mm from the others edge to edge (up to 100 draws; none if no draw fits)."""
    for _attempt in range(100):
        radius = rng.uniform(3.0, 12.0)
        centre = [rng.uniform(-size / 2 + radius, size / 2 - radius) for _ in range(2)]
        if all(math.dist(centre, other["center_mm"]) > radius + other["radius_mm"] + 6.0 for other in lumps):
            lumps.append({"center_mm": centre, "radius_mm": radius, "depth_mm": rng.uniform(1.0, 8.0),
                          "stiffness_n_per_mm": tissue_k * rng.uniform(2.5, 8.0)})
            return


def varied_scenes(count: int, seed: int) -> list[Scene]:
    """Scenes drawn at random from a wider range than random_scenes: tissue 40-80 mm on each side (not only
    square), hardening (exponent 1-2), sometimes damped or with sliding friction, turned on the bench by up
    to 30°; none to three lumps 2-12 mm in radius, 0-8 mm deep, 2.5-10 times as stiff, whose centre may lie
    up to 0.7 of their radius from the tissue's edge (part of the lump past it); sensor noise 0.001-0.06 N."""
    rng = random.Random(seed + 5000)
    scenes = []
    for i in range(count):
        width, height = rng.choice([40.0, 50.0, 60.0, 80.0]), rng.choice([40.0, 50.0, 60.0, 80.0])
        tissue_k = math.exp(rng.uniform(math.log(0.05), math.log(0.4)))
        lumps: list[dict] = []
        for _ in range(rng.choices([0, 1, 2, 3], [0.15, 0.45, 0.25, 0.15])[0]):
            for _attempt in range(100):
                radius = rng.uniform(2.0, 12.0)
                centre = [rng.uniform(-width / 2 + radius * 0.3, width / 2 - radius * 0.3),
                          rng.uniform(-height / 2 + radius * 0.3, height / 2 - radius * 0.3)]
                if all(math.dist(centre, other["center_mm"]) > radius + other["radius_mm"] + 6.0 for other in lumps):
                    lumps.append({"center_mm": centre, "radius_mm": radius, "depth_mm": rng.uniform(0.0, 8.0),
                                  "stiffness_n_per_mm": tissue_k * rng.uniform(2.5, 10.0)})
                    break
        tissue = {"size_mm": [width, height], "stiffness_n_per_mm": tissue_k,
                  "exponent": rng.choice([1.0, 1.0, 1.5, 2.0]), "damping_n_s_per_mm": rng.choice([0.0, 0.0, 0.01]),
                  "friction": rng.choice([0.0, 0.0, 0.3])}
        scenes.append(Scene(name=f"varied-{seed}-{i}", seed=seed * 1000 + i, tissue=tissue, lump=lumps,
                            placement={"rotation_deg": rng.choice([0.0, 0.0, 15.0, 30.0])},
                            sensor={"noise_n": rng.choice([0.001, 0.005, 0.01, 0.03, 0.06]), "tilt": True}))
    return scenes


def soft_scenes(count: int, seed: int) -> list[Scene]:
    """Scenes with one soft inclusion (a cyst, a pocket of fat: no lump to find, metrics.scene_truth): tissue
    50-80 mm across and 0.05-0.4 N/mm, the inclusion 5-15 mm in radius, 0-3 mm deep, 1.5-5 times softer and
    wholly on the tissue; none to two lumps beside it as random_scenes draws them, at least 6 mm from it and
    from each other edge to edge; sensor noise 0.005-0.06 N."""
    rng = random.Random(seed + 9000)
    scenes = []
    for i in range(count):
        size = rng.choice([50.0, 60.0, 80.0])
        tissue_k = math.exp(rng.uniform(math.log(0.05), math.log(0.4)))
        radius = rng.uniform(5.0, 15.0)
        soft = {"center_mm": [rng.uniform(-size / 2 + radius, size / 2 - radius) for _ in range(2)],
                "radius_mm": radius, "depth_mm": rng.uniform(0.0, 3.0), "stiffness_n_per_mm": tissue_k / rng.uniform(1.5, 5.0)}
        lumps: list[dict] = [soft]
        for _ in range(rng.choices([0, 1, 2], [0.4, 0.4, 0.2])[0]):
            _add_lump(rng, size, tissue_k, lumps)
        scenes.append(_square_scene(rng, f"soft-{seed}-{i}", seed * 1000 + i, size, tissue_k, lumps))
    return scenes


def tried_beyond(scenes: list[Scene], raster_too: bool) -> int:
    print(HEADER)
    runs = []
    for scene in scenes:
        k = scene.tissue.stiffness_n_per_mm
        lumps = ", ".join(f"r {lump.radius_mm:.1f} mm {lump.depth_mm:.1f} deep ×{lump.stiffness_n_per_mm / k:.1f}"
                          for lump in scene.lump)
        width, height = scene.tissue.size_mm
        size = f"{width:.0f} mm" if width == height else f"{width:.0f} × {height:.0f} mm"
        extras = "".join(text for text, shown in (
            (f", exponent {scene.tissue.exponent:g}", scene.tissue.exponent != 1.0),
            (f", damping {scene.tissue.damping_n_s_per_mm:g}", scene.tissue.damping_n_s_per_mm > 0.0),
            (f", friction {scene.tissue.friction:g}", scene.tissue.friction > 0.0),
            (f", turned {scene.placement.rotation_deg:g}°", scene.placement.rotation_deg != 0.0)) if shown)
        name = f"{scene.name}: {size}, {k:.2f} N/mm{extras}, noise {scene.sensor.noise_n} N; {lumps or 'no lump'}"
        runs.append(scan(scene, "active", BASE[0].learner.max_palpations, 0))
        print(row(name, *runs[-1]), flush=True)
        if raster_too:
            raster, rm = scan(scene, "raster", runs[-1][0]["palpations"], 0)
            print(row(f"{scene.name} (raster, same count)", raster, rm), flush=True)
    print(SUMMARY_HEADER)
    print(summary(f"{len(scenes)} random", runs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
