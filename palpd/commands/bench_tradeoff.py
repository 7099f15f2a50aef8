"""palpd bench tradeoff: robot time against accuracy over scenes × seeds × settings, each scan run as a
user runs it (its own stop rule), as independent tasks on Dask (or a process pool), with the Pareto front."""
from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path


def add_parser(kinds):
    bench = kinds.add_parser("tradeoff", help="robot time against accuracy over scenes, seeds and settings; "
                                              "the Pareto front (Dask or a process pool)")
    bench.add_argument("--scenes", nargs="+", metavar="PATH|NAME",
                       help="scene files, shipped scene names or directories of *.toml scenes (default: every "
                            "shipped scene, `palpd scenes`)")
    bench.add_argument("--seeds", type=int, default=2, metavar="N", help="seeds 0..N-1 of every scene (default 2)")
    bench.add_argument("--grid", metavar="FILE.toml",
                       help="the settings to compare, as [[run]] tables (default: the built-in grid, see "
                            "docs/tradeoff.md)")
    bench.add_argument("--scheduler", default="local", metavar="local|tcp://HOST:PORT",
                       help="local: a Dask LocalCluster on this machine (a process pool without the cluster "
                            "extra); or the address of a running Dask scheduler")
    bench.add_argument("--workers", type=int, metavar="N", help="local workers (default: one per CPU)")
    bench.add_argument("--config", metavar="FILE", help="base settings (TOML) every run starts from")
    bench.add_argument("--out", default="out/tradeoff", metavar="DIR",
                       help="where tradeoff.csv, settings.csv, failures.csv and pareto.png go")
    bench.add_argument("--json", action="store_true", help="print the per-setting summary as JSON")
    return bench


def run(args) -> int:
    from palpd.config import load_settings
    from palpd.errors import UsageError
    from palpd.tradeoff import grid

    if args.seeds < 1 or (args.workers is not None and args.workers < 1):
        raise UsageError("--seeds and --workers must be at least 1")
    entries = grid.load_grid(args.grid) if args.grid else grid.DEFAULT_GRID
    runs = grid.runs(_scenes(args.scenes), args.seeds, entries, load_settings(args.config))
    rows, failures = _sweep(runs, args.scheduler, args.workers)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _report(rows, failures, out, args.json)
    return 1 if failures else 0


def _scenes(specs) -> list:
    from drivers.sim.scene import load_scene
    from palpd.errors import UsageError
    from palpd.shipped import resolve_scene, scene_names

    specs = specs or scene_names()
    paths = [q for p in map(Path, specs) for q in (sorted(p.glob("*.toml")) if p.is_dir() else [resolve_scene(p)])]
    if not paths:
        raise UsageError(f"--scenes {' '.join(specs)}: no *.toml scenes there")
    scenes = [load_scene(p) for p in paths]
    for scene in scenes:
        if scene.tissue.is_3d:  # built once here, not by every worker at once: a cold table takes minutes
            from drivers.sim.mechanics.table import cached_table

            cached_table(scene)
    return scenes


def _sweep(runs, scheduler: str, workers) -> tuple[list[dict], list[dict]]:
    """(rows, failures), in the order of the runs, with a progress bar; each failure is said as it happens."""
    from tqdm import tqdm

    from palpd.tradeoff.runs import run_one
    from palpd.tradeoff.schedulers import execute

    with tqdm(total=len(runs), desc="tradeoff", unit="scan", disable=None, file=sys.stderr) as bar:
        def done(index, _row, error):
            bar.update()
            if error:
                bar.write(f"palpd: run failed: {runs[index].name}: {error}", file=sys.stderr)

        results = execute(run_one, runs, scheduler, workers, done)
    rows = [row for row, _ in results if row is not None]
    failures = [{"run": runs[i].name, "error": error} for i, (_, error) in enumerate(results) if error]
    return rows, failures


def _report(rows: list[dict], failures: list[dict], out: Path, as_json: bool) -> None:
    from palpd.tradeoff.pareto import per_scene_lead, plot, settings_summary
    from palpd.tradeoff.runs import COLUMNS

    _write_csv(out / "tradeoff.csv", rows, COLUMNS)
    _write_csv(out / "failures.csv", failures, ["run", "error"]) if failures else (out / "failures.csv").unlink(
        missing_ok=True)
    summary = settings_summary(rows) if rows else []
    _write_csv(out / "settings.csv", summary, list(summary[0]) if summary else [])
    if rows:
        plot(rows, summary, out / "pareto.png")
    leads = per_scene_lead(rows)
    if as_json:
        print(json.dumps({"settings": summary, "scenes": leads, "failures": len(failures)}, default=str))
    else:
        print(_table(summary, leads, len(rows), len(failures)))
        print(f"written: {out}/tradeoff.csv, settings.csv, pareto.png" + (", failures.csv" if failures else ""))


def _table(summary: list[dict], leads: list[dict], runs: int, failed: int) -> str:
    lines = [f"{runs} scans ({failed} failed); medians per setting over scenes × seeds; * = on the Pareto front",
             "strategy  palpation  setting                 runs  palpations  robot s    IoU    centre mm"]
    for s in summary:
        lines.append(f"{s['strategy']:8s}  {s['palpation']:9s}  {s['setting']:22s}  {s['runs']:4d}  "
                     f"{s['palpations']:10.1f}  {s['robot_time_s']:7.1f}  {s['iou']:.3f}{'*' if s['front_iou'] else ' '}"
                     f"  {_mm(s['center_error_mm'])}{'*' if s['front_center'] else ''}")
    if leads:
        lines.append("per scene: best active IoU within the discrete raster's median robot time vs its median IoU")
        for lead in leads:
            best = "none that fast" if lead["best_active_iou"] is None else (
                f"{lead['best_active_iou']:.3f} ({lead['lead']:+.3f})")
            lines.append(f"  {lead['scene']:24s} raster {lead['raster_median_time_s']:6.1f} s, IoU "
                         f"{lead['raster_median_iou']:.3f}; active {best}")
    return "\n".join(lines)


def _mm(value: float) -> str:
    return "not found" if math.isinf(value) else ("n/a" if math.isnan(value) else f"{value:.3f}")


def _write_csv(path: Path, rows: list[dict], columns: list[str]) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
