"""palpd bench extremes: what palpd measures at the extremes of sensor noise and tissue, one scan per scene.

For each scene (the shipped extremes by default) an active scan on the simulated bench, then one table row:
the scene's noise and stiffness, how many palpations gave a stiffness or a censored bound, their outcomes, the
share of straight-line models chosen, the median stiffness read away from any lump against the scene's tissue
(a line's slope: the tissue's own k when it is linear and undamped), and whether the lump was found (IoU).
`--out docs/extremes.md` writes the table with the command that produced it.
"""
from __future__ import annotations

import math
import sys
from collections import Counter

EXTREMES = ["paper", "noisy-sensor", "very-noisy-sensor", "soft-tissue", "stiff-tissue", "quiet-curved-damped"]
HEADER = ("| scene | noise N | tissue N/mm (3-D: kPa, thickness) | lump N/mm (kPa) | palpations | stiffness or bound | outcomes | linear models "
          "| background k N/mm (median) | verdict | lumps found | IoU |")
CLEAR_OF_LUMP_MM = 5.0  # a reading this far outside every lump's radius counts as background


def add_parser(kinds):
    bench = kinds.add_parser("extremes", help="scan scenes at the extremes of noise and stiffness; print a table")
    bench.add_argument("--scenes", nargs="+", default=EXTREMES, metavar="SCENE", help="files or shipped names")
    bench.add_argument("--max-palpations", type=int, default=40, metavar="N")
    bench.add_argument("--seed", type=int, default=0, metavar="N")
    bench.add_argument("--out", metavar="FILE.md", help="also write the table (markdown) with this command line")
    return bench


def run(args) -> int:
    from palpd.embedded import run_simulated_scan, scan_settings
    from palpd.shipped import load_scene_named

    scenes = [load_scene_named(name) for name in args.scenes]  # every scene checked before the first scan
    settings = scan_settings(None, "active", args.max_palpations, args.seed)
    rows = [HEADER, "|" + "---|" * (HEADER.count("|") - 1)]
    print(rows[0], flush=True)
    print(rows[1], flush=True)
    for scene in scenes:
        report, _ = run_simulated_scan(settings, scene, max_palpations=args.max_palpations)
        rows.append(table_row(scene, report))
        print(rows[-1], flush=True)
    if args.out:
        _write(args.out, rows)
        print(f"table written to {args.out}", file=sys.stderr)
    return 0


def table_row(scene, report: dict) -> str:
    probes = report["probes"]
    informative = sum(p["outcome"] == "fit" or p.get("stiffness_bound_n_per_mm") is not None for p in probes)
    outcomes = ", ".join(f"{name} {count}" for name, count in Counter(p["outcome"] for p in probes).most_common())
    fits = [p for p in probes if p["outcome"] == "fit"]
    linear = sum(p.get("stiffness_model") in ("linear", "linear-offset") for p in fits)
    background = sorted(p["stiffness_n_per_mm"] for p in fits if _clear_of_lumps(p["xy_mm"], scene))
    m = report["metrics"]
    lump_k = "/".join(_lump_stiffness(scene)) or "-"
    median = f"{background[len(background) // 2]:.4g}" if background else "-"
    iou = "-" if m["min_iou"] is None else f"{m['min_iou']:.2f}"
    return (f"| {scene.name} | {scene.sensor.noise_n:g} | {_tissue(scene)} | {lump_k} | {len(probes)} "
            f"| {_pct(informative, len(probes))} | {outcomes} | {_pct(linear, len(fits))} | {median} "
            f"| {report['verdict']} | {m['lumps_found']}/{m['lumps_true']} | {iou} |")


def _tissue(scene) -> str:
    t = scene.tissue
    if t.is_3d:  # a layer on its rigid base: its modulus and thickness, not a felt stiffness
        return f"{t.modulus_kpa:g} kPa, {t.thickness_mm:g} mm"
    extra = (f", n {t.exponent:g}" if t.exponent != 1.0 else "") + (f", b {t.damping_n_s_per_mm:g}" if t.damping_n_s_per_mm else "")
    return f"{t.stiffness_n_per_mm:g}{extra}"


def _lump_stiffness(scene) -> list[str]:
    if scene.tissue.is_3d:
        return [f"{body.modulus_kpa:g} kPa" for body in scene.inclusion]
    return [f"{lump.stiffness_n_per_mm:g}" for lump in scene.lump]


def _clear_of_lumps(xy, scene) -> bool:
    from drivers.sim.scene import truth_lumps  # as placed on the bench, in the tissue frame the readings are in

    return all(math.dist(xy, lump["center_mm"]) > lump["radius_mm"] + CLEAR_OF_LUMP_MM for lump in truth_lumps(scene))


def _pct(part: int, whole: int) -> str:
    return "-" if not whole else f"{100.0 * part / whole:.0f} %"


def _write(path: str, rows: list[str]) -> None:
    from pathlib import Path

    command = "palpd bench extremes " + " ".join(sys.argv[3:])
    text = ["# palpd at the extremes of noise and stiffness", "",
            f"Written by `{command.strip()}` (active scans on the simulated bench, simulated time).", "", *rows, ""]
    Path(path).write_text("\n".join(text))
