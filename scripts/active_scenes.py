"""Active scans with default settings on every scene in config/scenes/ (or the ones named), as a table.

    .venv/bin/python scripts/active_scenes.py [--seed N | --seeds 0,1,2] [--raster-too] [SCENE | FILE.toml ...]
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
import sys
from pathlib import Path

from palpd.threads import pin_blas_to_one_thread

pin_blas_to_one_thread()

from drivers.sim.scene import Scene, SceneError, load_scene  # noqa: E402
from palpd import metrics  # noqa: E402
from palpd.bench import open_simulated_bench  # noqa: E402
from palpd.config import Settings, load_settings  # noqa: E402
from palpd.errors import ConfigError  # noqa: E402
from palpd.scan import plan, run_scan  # noqa: E402
from palpd.tradeoff.scenes import random_scenes, soft_scenes, varied_scenes  # noqa: E402,F401  (tests use them here)

HEADER = ("| scene | palpations | robot time | verdict | model (weight) | found | false | centre error | radius error "
          "| IoU | depth error |\n|---|---|---|---|---|---|---|---|---|---|---|")
SUMMARY_HEADER = ("\n| scene | count right | wrong beyond the verdict's claim | palpations (median) | (most) "
                  "| undetermined | worst centre error (mm) | worst radius error (mm) | worst IoU |"
                  "\n|---|---|---|---|---|---|---|---|---|")
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
    # depth: a 3-D scene's inclusions only, with the worst error in the lump's own sds
    sds = [p["depth_error_sd"] for p in m["per_lump"] if p.get("depth_error_sd") is not None]
    depth = mm(m.get("max_depth_error_mm")) + (f" ({max(sds):.1f} sd)" if sds else "")
    return (f"| {name} | {report['palpations']} | {report['robot_time_s']:.1f} s | {report['verdict']} | {chosen} | "
            f"{m['lumps_found']}/{m['lumps_true']} | {m['false_lumps']} | {mm(m['max_center_error_mm'])} | "
            f"{mm(m['max_radius_error_mm'])} | {iou} | {depth} |")


def summary(name: str, runs: list[tuple[dict, dict]]) -> str:
    """One row over seeds: count right, the verdicts wrong beyond their claim (metrics.wrong_beyond_claim: a false
    lump, or one missed at least as large as the stated unfelt radius), palpations (median, most), worst centre
    and radius error, worst IoU."""
    right = sum(m["lumps_found"] == m["lumps_true"] and m["false_lumps"] == 0 for _, m in runs)
    beyond = sum(r["verdict"] != "undetermined" and metrics.wrong_beyond_claim(m, (r["model"] or {}).get("unfelt_radius_mm")) > 0
                 for r, m in runs)
    palpations = sorted(r["palpations"] for r, _ in runs)
    undetermined = sum(r["verdict"] == "undetermined" for r, _ in runs)
    def worst(key, pick=max):
        values = [m[key] for _, m in runs if m[key] is not None]
        return "–" if not values else f"{pick(values):.2f}"
    return (f"| {name} | {right}/{len(runs)} | {beyond} | {palpations[len(palpations) // 2]} | {palpations[-1]} | {undetermined} | "
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
        path = scene_path(name)
        name, scene = path.stem, load_scene(path)
        report, m = scan(scene, "active", BASE[0].learner.max_palpations, args.seed)
        print(row(name, report, m), flush=True)
        if args.raster_too:
            raster, rm = scan(scene, "raster", report["palpations"], args.seed)
            print(row(f"{name} (raster, same count)", raster, rm), flush=True)
    return 0


def scene_path(name: str) -> Path:
    """A scene file, or a shipped scene's name."""
    return Path(name) if name.endswith(".toml") else SCENES / f"{name}.toml"


def sweep(names: list[str], seeds: list[int]) -> int:
    print(HEADER)
    rows = []
    for name in names:
        path = scene_path(name)
        name, scene = path.stem, load_scene(path)
        runs = [scan(scene, "active", BASE[0].learner.max_palpations, seed) for seed in seeds]
        for seed, (report, m) in zip(seeds, runs):
            print(row(f"{name} (seed {seed})", report, m), flush=True)
        rows.append(summary(name, runs))
    print(SUMMARY_HEADER)
    print("\n".join(rows))
    return 0


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
    try:
        sys.exit(main())
    except SceneError as exc:  # a scene named that does not load: one line, as `palpd scan` says it
        sys.exit(f"active_scenes.py: {exc}")
