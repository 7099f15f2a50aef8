"""palpd bench calibration: is the learner's stated error the error it makes? Over random scenes (none of them
shipped) or the shipped ones, the active scan at each tolerance × confidence, each scan run as a user runs it;
per setting, how often the count was right, how often a verdict claimed a wrong count, how often the true
boundary error was within the tolerance asked for, and what that cost in palpations: the reliability table."""
from __future__ import annotations

import json
import math
import statistics
import sys
from pathlib import Path


def add_parser(kinds):
    bench = kinds.add_parser("calibration", help="the stated boundary error and count against the truth, at each "
                                                 "tolerance and confidence: a reliability table")
    source = bench.add_mutually_exclusive_group()
    source.add_argument("--random", type=int, default=20, metavar="N",
                        help="N random scenes, none shipped (palpd.tradeoff.scenes; default 20)")
    source.add_argument("--scenes", nargs="+", metavar="PATH|NAME",
                        help="scene files or shipped scene names instead of random ones")
    bench.add_argument("--random-seed", type=int, default=0, metavar="S", help="which random scenes (default 0)")
    bench.add_argument("--tolerances", default="0.25,0.5,1,2", metavar="MM,...",
                       help="learner.tolerance_mm values (default 0.25,0.5,1,2)")
    bench.add_argument("--confidences", default="0.9", metavar="P,...", help="learner.confidence values (default 0.9, the default)")
    bench.add_argument("--scheduler", default="local", metavar="local|tcp://HOST:PORT",
                       help="local: a Dask LocalCluster (a process pool without the cluster extra), or a scheduler")
    bench.add_argument("--workers", type=int, metavar="N", help="local workers (default: one per CPU)")
    bench.add_argument("--config", metavar="FILE", help="base settings (TOML) every run starts from")
    bench.add_argument("--out", default="out/calibration", metavar="DIR", help="where calibration.csv goes")
    bench.add_argument("--json", action="store_true", help="print the per-setting table as JSON")
    return bench


def run(args) -> int:
    from palpd.commands.bench_tradeoff import _scenes, _sweep, _write_csv
    from palpd.config import load_settings
    from palpd.errors import UsageError
    from palpd.tradeoff import grid
    from palpd.tradeoff.runs import COLUMNS
    from palpd.tradeoff.scenes import random_scenes

    tolerances = _numbers(args.tolerances, "--tolerances")
    confidences = _numbers(args.confidences, "--confidences")
    if any(c <= 0.5 or c >= 1.0 for c in confidences):
        raise UsageError("--confidences: each must lie between 0.5 and 1")
    if args.random < 1 or (args.workers is not None and args.workers < 1):
        raise UsageError("--random and --workers must be at least 1")
    scenes = _scenes(args.scenes) if args.scenes else random_scenes(args.random, args.random_seed)
    entries = [grid.GridEntry(strategy="active", settings={"learner": {"tolerance_mm": t, "confidence": c}})
               for c in confidences for t in tolerances]
    rows, failures = _sweep(grid.runs(scenes, 1, entries, load_settings(args.config)), args.scheduler, args.workers)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _write_csv(out / "calibration.csv", rows, COLUMNS)
    table = reliability(rows)
    if args.json:
        print(json.dumps({"settings": table, "failures": len(failures)}))
    else:
        print(format_table(table, len(scenes), len(failures)))
        print(f"written: {out}/calibration.csv")
    return 1 if failures else 0


def reliability(rows: list[dict]) -> list[dict]:
    """One row per setting (in the order first run): runs; palpations (sum, median); the share whose count was
    right (every lump found, none false); verdicts that claimed a wrong count (`lumps` or `none`), and of those the
    ones wrong beyond what the verdict claims (a false lump, or a lump missed at least as large as the stated
    unfelt radius: metrics.wrong_beyond_claim); undetermined;
    of the runs with a lump to bound, the share whose true boundary error was within the tolerance asked for, and
    of those that claimed it (a verdict and a stated error within the tolerance), how many were; the median
    true and stated boundary errors."""
    table = []
    for setting in dict.fromkeys(r["setting"] for r in rows):
        runs = [r for r in rows if r["setting"] == setting]
        tolerance = float(_setting_value(setting, "tolerance_mm"))
        right = [r["lumps_found"] == r["lumps_true"] and r["false_lumps"] == 0 for r in runs]
        bounded = [r for r in runs if r["boundary_error_mm"] is not None]
        errors = [r["boundary_error_mm"] for r in bounded]
        stated = [r["expected_boundary_error_mm"] for r in runs if r["expected_boundary_error_mm"] is not None]
        # the runs that claimed the tolerance: a verdict, and a stated error within it (the rest ran out of budget)
        claimed = [r for r in bounded if r["verdict"] != "undetermined" and r["expected_boundary_error_mm"] is not None
                   and r["expected_boundary_error_mm"] <= tolerance]
        table.append({
            "setting": setting, "tolerance_mm": tolerance,
            "confidence": float(_setting_value(setting, "confidence")), "runs": len(runs),
            "palpations": sum(r["palpations"] for r in runs),
            "palpations_median": statistics.median(r["palpations"] for r in runs),
            "count_right": sum(right) / len(runs),
            "wrong_count_verdicts": sum(not ok and r["verdict"] != "undetermined" for ok, r in zip(right, runs)),
            "wrong_beyond_claim": sum(r["verdict"] != "undetermined" and int(r["wrong_beyond_claim"]) > 0 for r in runs),
            "undetermined": sum(r["verdict"] == "undetermined" for r in runs),
            "within_tolerance": (sum(e <= tolerance for e in errors) / len(errors)) if errors else math.nan,
            "claimed": len(claimed), "claimed_and_within": sum(r["boundary_error_mm"] <= tolerance for r in claimed),
            "boundary_error_mm": statistics.median(errors) if errors else math.nan,
            "stated_error_mm": statistics.median(stated) if stated else math.nan})
    return table


def format_table(table: list[dict], scenes: int, failed: int) -> str:
    lines = [f"{scenes} scenes × {len(table)} settings, the active scan ({failed} runs failed)",
             "| tolerance mm | confidence | palpations (sum) | median | count right | wrong-count verdicts "
             "| of them beyond the claim | undetermined | boundary error within tolerance | of the runs that claimed it "
             "| median true error mm | median stated error mm |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in table:
        lines.append(f"| {s['tolerance_mm']:g} | {s['confidence']:g} | {s['palpations']} | {s['palpations_median']:g} "
                     f"| {s['count_right']:.0%} | {s['wrong_count_verdicts']} | {s['wrong_beyond_claim']} "
                     f"| {s['undetermined']} "
                     f"| {_share(s['within_tolerance'])} | {s['claimed_and_within']}/{s['claimed']} "
                     f"| {_mm(s['boundary_error_mm'])} | {_mm(s['stated_error_mm'])} |")
    return "\n".join(lines)


def _setting_value(label: str, key: str) -> str:
    return dict(part.split("=", 1) for part in label.split(";"))[key]


def _numbers(text: str, option: str) -> list[float]:
    from palpd.errors import UsageError

    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"{option} {text}: a comma-separated list of numbers") from None
    if not values or any(not math.isfinite(v) or v <= 0 for v in values):
        raise UsageError(f"{option} {text}: each value must be a positive number")
    return values


def _share(value: float) -> str:
    return "–" if math.isnan(value) else f"{value:.0%}"


def _mm(value: float) -> str:
    return "–" if math.isnan(value) else f"{value:.2f}"
