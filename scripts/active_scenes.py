"""Active scans with default settings on every scene in config/scenes/ (or the ones named), as a table.

    .venv/bin/python scripts/active_scenes.py [--seed N | --seeds 0,1,2] [--raster-too] [SCENE ...]

Each row is `palpd scan --scene SCENE --strategy active` with default settings (simulated time, the
real control and fit code, in this process): palpations, robot time, the verdict and the model the
evidence chose (with its weight), and the errors against the scene's truth. With --raster-too, a raster
scan of the same number of palpations is scored beside it (its §3.4 estimate). With --seeds, every
scene once per seed (the scan's and the simulator's), then one summary row per scene: how often the
count was right (every lump found, none false), palpations (median and most), the worst errors and IoU.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from palpd.threads import pin_blas_to_one_thread

pin_blas_to_one_thread()

from drivers.sim.scene import load_scene  # noqa: E402
from palpd import metrics  # noqa: E402
from palpd.bench import open_simulated_bench  # noqa: E402
from palpd.config import Settings  # noqa: E402
from palpd.scan import plan, run_scan  # noqa: E402

HEADER = ("| scene | palpations | robot time | verdict | model (weight) | found | false | centre error | radius error "
          "| IoU |\n|---|---|---|---|---|---|---|---|---|---|")
SCENES = Path(__file__).resolve().parent.parent / "config" / "scenes"


def scan(scene, strategy: str, budget: int, seed: int) -> tuple[dict, dict]:
    settings = Settings().updated(scan={"strategy": strategy, "seed": seed})
    planner = plan(strategy, scene.tissue.size_mm, budget, seed, settings)
    report = run_scan(open_simulated_bench(settings, scene, seed=seed), settings, planner)
    return report, metrics.compare(metrics.scene_truth(scene, settings.scan.min_contrast), report["lumps"])


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
    args = parser.parse_args()
    names = args.scenes or sorted(p.stem for p in SCENES.glob("*.toml"))
    if args.seeds:
        return sweep(names, [int(s) for s in args.seeds.split(",")])
    print(HEADER)
    for name in names:
        scene = load_scene(SCENES / f"{name}.toml")
        report, m = scan(scene, "active", Settings().learner.max_palpations, args.seed)
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
        runs = [scan(scene, "active", Settings().learner.max_palpations, seed) for seed in seeds]
        for seed, (report, m) in zip(seeds, runs):
            print(row(f"{name} (seed {seed})", report, m), flush=True)
        rows.append(summary(name, runs))
    print("\n| scene | count right | palpations (median) | (most) | undetermined | worst centre error (mm) | "
          "worst radius error (mm) | worst IoU |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
