"""palpd bench tradeoff: palpations and robot time to reach the accuracy targets, active vs raster vs random,
and the speed-for-accuracy curve of the active scan (confidence, indentation speed, depth)."""
from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

TARGET = {"center_mm": 1.0, "radius_mm": 1.0, "iou": 0.9}
BUDGET = 81
RASTER_SIDES = (5, 7, 9)  # each size is a whole scan of its own: every side would cost 271 palpations per run
CURVE = {"confidence": [0.7, 0.9, 0.99], "speed_mm_s": [5.0, 20.0, 40.0], "depth_mm": [2.0, 4.0, 6.0]}


def add_parser(kinds):
    bench = kinds.add_parser("tradeoff", help="active vs raster vs random to the accuracy targets; speed-for-accuracy curve")
    bench.add_argument("--scenes", nargs="+", metavar="PATH|NAME",
                       help="scene files, shipped scene names or directories of *.toml scenes (default: every "
                            "shipped scene, `palpd scenes`)")
    bench.add_argument("--seeds", type=int, default=3, metavar="N")
    bench.add_argument("--curve-scene", default="paper", metavar="NAME",
                       help="scene (by name) of the speed-for-accuracy curve, seed 0; 'none' to skip it")
    bench.add_argument("--out", default="out/tradeoff", metavar="DIR", help="where the CSVs and the plot go")
    bench.add_argument("--json", action="store_true")
    return bench


def run(args) -> int:
    from drivers.sim.scene import load_scene
    from palpd.errors import UsageError
    from palpd.shipped import resolve_scene, scene_names

    specs = args.scenes or scene_names()
    paths = [q for p in map(Path, specs) for q in (sorted(p.glob("*.toml")) if p.is_dir() else [resolve_scene(p)])]
    if not paths or args.seeds < 1:
        raise UsageError(f"--scenes {' '.join(specs)}: no *.toml scenes there (or --seeds below 1)")
    scenes = [load_scene(p) for p in paths]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = _races(scenes, args.seeds)
    curve = [row for scene in scenes if scene.lump and scene.name == args.curve_scene for row in _curve(scene, 0)]
    _write_csv(out / "tradeoff.csv", rows)
    _write_csv(out / "curve.csv", curve)
    _plot_curve(curve, out / "curve.png")
    summary = _summary(rows)
    print(json.dumps(summary) if args.json else _table(summary) + f"\nwritten: {out}/tradeoff.csv, curve.csv, curve.png")
    return 0


def _races(scenes, seeds: int) -> list[dict]:
    """Every strategy on every scene and seed, with a progress bar (a full run takes minutes)."""
    from tqdm import tqdm

    from palpd.commands._tradeoff_runs import first_on_target_active, first_on_target_random, first_on_target_raster

    runs = [(scene, seed, run) for scene in scenes for seed in range(seeds)
            for run in (first_on_target_active, first_on_target_raster, first_on_target_random)]
    rows = []
    with tqdm(runs, desc="tradeoff", unit="scan", disable=None) as bar:
        for scene, seed, run in bar:
            rows.append(run(scene, seed))
            bar.write(f"{scene.name} seed {seed} {rows[-1]['strategy']}: palpations to target "
                      f"{rows[-1]['palpations']}, robot time {rows[-1]['robot_time_s']} s", file=sys.stderr)
    return rows


def _curve(scene, seed: int) -> list[dict]:
    from palpd.commands._tradeoff_runs import active_scan

    rows = []
    for knob, values in CURVE.items():
        for value in values:
            rows.append({"scene": scene.name, "seed": seed, "knob": knob, "value": value,
                         **active_scan(scene, seed, {knob: value})})
    return rows


def _summary(rows: list[dict]) -> dict:
    out = {}
    for strategy in ("active", "raster", "random"):
        mine = [r for r in rows if r["strategy"] == strategy and r["lumps_true"] > 0]
        hit = [r for r in mine if r["palpations"] is not None]
        out[strategy] = {
            "runs": len(mine), "reached": len(hit),
            "palpations_mean": round(sum(r["palpations"] for r in hit) / len(hit), 1) if hit else None,
            "robot_time_s_mean": round(sum(r["robot_time_s"] for r in hit) / len(hit), 1) if hit else None,
            "false_lumps_no_lump_scenes": sum(r["false_lumps"] for r in rows
                                              if r["strategy"] == strategy and r["lumps_true"] == 0),
        }
    return out


def _table(summary: dict) -> str:
    lines = [f"to centre <= {TARGET['center_mm']} mm, radius <= {TARGET['radius_mm']} mm, IoU >= {TARGET['iou']} "
             f"(budget {BUDGET}):", "strategy  reached  palpations  robot time  false lumps (no-lump scenes)"]
    for name, s in summary.items():
        lines.append(f"{name:8s}  {s['reached']}/{s['runs']:<5d}  {s['palpations_mean']!s:>10}  "
                     f"{s['robot_time_s_mean']!s:>8} s  {s['false_lumps_no_lump_scenes']}")
    return "\n".join(lines)


def _write_csv(path: Path, rows: list[dict]) -> None:
    if not rows:
        return
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def _plot_curve(rows: list[dict], path: Path) -> None:
    if not rows:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    for knob, marker in zip(CURVE, "osD"):
        mine = [r for r in rows if r["knob"] == knob and r["max_center_error_mm"] is not None]
        ax.scatter([r["robot_time_s"] for r in mine], [r["max_center_error_mm"] + r["max_radius_error_mm"] for r in mine],
                   marker=marker, label=knob)
    ax.set_xlabel("robot time (s)")
    ax.set_ylabel("centre + radius error (mm)")
    ax.set_title("active scan: speed for accuracy")
    ax.legend()
    fig.savefig(path, dpi=100)
    plt.close(fig)
