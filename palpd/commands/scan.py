"""palpd scan: a whole simulated scan, with progress, report and map."""
from __future__ import annotations

import sys

from palpd.errors import EXIT_FAILURE, EXIT_UNDETERMINED


def add_parser(subparsers):
    scan = subparsers.add_parser("scan", help="palpate a scene end to end and estimate its lumps")
    scan.add_argument("--scene", required=True, metavar="FILE|NAME",
                      help="scene file (TOML) or the name of a shipped scene (`palpd scenes`)")
    scan.add_argument("--strategy", choices=["active", "raster", "random"],
                      help="where to palpate: active (default) asks the online learner where it is least sure; "
                           "raster, a square grid; random, uniform points")
    scan.add_argument("--palpation", choices=["discrete", "sliding"],
                      help="press point by point, or slide along paths in contact (default discrete)")
    scan.add_argument("--max-palpations", type=int, metavar="N", help="budget (sliding: of paths)")
    scan.add_argument("--confidence", type=float, metavar="P",
                      help="stop once the count of lumps has this posterior mass, over 0.5 and under 1 "
                           "(active; default 0.9): lower stops sooner")
    scan.add_argument("--tolerance-mm", type=float, metavar="T",
                      help="...and the boundary's expected error is at most T mm: the expected misread area over "
                           "the boundary's length (active; default 0.5): looser stops sooner")
    scan.add_argument("--coverage-mm", type=float, metavar="MM",
                      help="...and no spot is farther than MM from a reading (active; default 18): a lump felt over "
                           "less than that could lie unfelt between the readings. Lower finds more small lumps "
                           "and costs palpations (docs/explanation/scanning.md)")
    scan.add_argument("--seed", type=int, metavar="N")
    scan.add_argument("--train", metavar="FILE.csv",
                      help="labelled dataset (tumor column): learn the lump threshold from it (active strategy)")
    scan.add_argument("--depth-mm", type=float, metavar="D", help="indentation depth")
    scan.add_argument("--speed-mm-s", type=float, metavar="V", help="indentation speed")
    scan.add_argument("--report", metavar="FILE.json")
    scan.add_argument("--plot", metavar="FILE.png")
    scan.add_argument("--realtime", action="store_true", help="run on the wall clock instead of simulated time")
    scan.add_argument("--config", metavar="FILE", help="settings (TOML); default: built-in, as config/palpd.toml")
    scan.add_argument("--quiet", action="store_true", help="no progress lines")
    return scan


def run(args) -> int:
    from palpd.embedded import run_simulated_scan, scan_settings
    from palpd.shipped import load_scene_named

    settings = scan_settings(args.config, args.strategy, args.max_palpations, args.seed, args.depth_mm,
                             args.speed_mm_s, args.confidence, args.train, args.tolerance_mm,
                             args.palpation, args.coverage_mm)
    scene = load_scene_named(args.scene)
    if settings.learner.training_set:
        from palpd.datafile import read_training_set

        read_training_set(settings.learner.training_set)  # a file that cannot teach fails before the scan stack loads
    # Heavy imports (scipy.stats, scikit-learn, matplotlib) only once arguments, config and scene are known good.
    from palpd.files import check_writable, write_json

    check_writable(args.report, args.plot)  # before the scan: its result must not be lost to a typo in a path
    _note_raster(settings, args.max_palpations)

    def started(planner) -> None:
        p = settings.palpation
        how = (f"depth {p.depth_mm} mm at {p.speed_mm_s} mm/s" if p.mode == "discrete" else
               f"sliding paths at {p.sliding_speed_mm_s} mm/s, {p.sliding_depth_mm} ± {p.modulation_mm} mm deep")
        _say(args, f"scan of scene {scene.name!r}: {settings.scan.strategy}, up to {planner.expected_total} "
                   f"{'palpations' if p.mode == 'discrete' else 'paths'}, {how}")

    printer = _progress_printer(args, settings.palpation.mode == "sliding")
    report, planner = run_simulated_scan(settings, scene, printer, args.realtime, args.max_palpations, started)
    _say(args, _summary(report), always=True)
    doubt = (report.get("model") or {}).get("boundary_doubt")
    if report["verdict"] == "lumps" and doubt and report.get("strategy") == "active":
        # the count is decided, the boundary not to what was asked: only the budget ends an active scan so
        _say(args, f"boundary: not known to the tolerance: {doubt} (the budget was spent first: raise "
                   f"--max-palpations, or loosen --tolerance-mm)", always=True)
    if args.report:
        write_json(args.report, report)
        _say(args, f"report written to {args.report}")
    if args.plot:
        from palpd.plot import plot_scan, posterior_of

        plot_scan(report, scene.tissue.size_mm, args.plot, posterior_of(planner, report, settings, scene.tissue.size_mm))
        _say(args, f"map written to {args.plot}")
    if report.get("paths_lifted_at_force_limit"):
        print(f"palpd: note: {report['paths_lifted_at_force_limit']} sliding path(s) met the force limit "
              f"({settings.palpation.max_force_n:g} N): each spot too stiff to slide on was pressed instead (a "
              f"discrete palpation) and the path touched down again past it, which costs robot time; a shallower "
              f"palpation.sliding_depth_mm slides across such spots", file=sys.stderr)
    if report["faults"]:
        fault = report["faults"][0]
        print(f"palpd: scan stopped by a safety fault ({fault['code']}): {fault['message']}", file=sys.stderr)
        return EXIT_FAILURE
    if report.get("undetermined_reason"):
        print(f"palpd: undetermined: {report['undetermined_reason']}", file=sys.stderr)
        return EXIT_UNDETERMINED
    if report["verdict"] == "undetermined":
        model = report.get("model") or {}
        why = f": {model['undecided']}" if model.get("undecided") else ""
        # a lower confidence decides only a choice short of it, not one that misses its readings
        advice = "--max-palpations or lower --confidence" if model.get("weight", 0.0) < settings.learner.confidence \
            else "--max-palpations"
        print(f"palpd: undetermined: {report['palpations']} palpations did not decide whether and which lumps "
              f"there are{why} (raise {advice})", file=sys.stderr)
        return EXIT_UNDETERMINED
    return 0


def _note_raster(settings, budget: int | None) -> None:
    """A budget a square grid cannot use whole is said, even with --quiet: 3 palpating one spot surprises."""
    if settings.scan.strategy == "raster" and settings.palpation.mode == "discrete":
        from palpd.strategies import raster_note  # here: building the parser must not import numpy

        note = raster_note(budget or settings.scan.max_palpations)
        if note:
            print(f"palpd: {note}", file=sys.stderr, flush=True)


def _progress_printer(args, sliding: bool = False):
    def show(done: int, total: int, probe) -> None:
        x, y = probe.record.xy_mm
        k = f"{probe.outcome}: {probe.rejected}" if probe.fit is None else f"k = {probe.stiffness_n_per_mm:.3f} N/mm"
        if probe.stiffness_bound_n_per_mm is not None:
            k += f" (k {'≥' if probe.outcome == 'too_stiff' else '≤'} {probe.stiffness_bound_n_per_mm:.3g} N/mm)"
        if sliding and probe.record.contact:  # a discrete palpation within a path: a spot too stiff to slide on
            k += "  (pressed: too stiff to slide on)"
        _say(args, f"[{done:3d}/{total}] ({x:6.1f}, {y:6.1f}) mm  {k}")

    return show


def _summary(report: dict) -> str:
    lines = [f"{report['palpations']} palpations in {report['robot_time_s']:.1f} s robot time "
             f"({report['wall_time_s']:.1f} s wall), max force {report['max_contact_force_n']:.2f} N"]
    lines.append(_verdict_line(report))
    for i, lump in enumerate(report["lumps"], 1):
        lines.append(f"lump {i}: {_lump_line(lump)}")
    m = report["metrics"]
    if m["lumps_true"] or m["false_lumps"]:
        lines.append(f"vs truth: {m['lumps_found']}/{m['lumps_true']} found, {m['false_lumps']} false, "
                     f"centre error {_mm(m['max_center_error_mm'])}, radius error {_mm(m['max_radius_error_mm'])}"
                     + (f", depth error {_mm(m['max_depth_error_mm'])}" if "max_depth_error_mm" in m else ""))
    return "\n".join(lines)


def _verdict_line(report: dict) -> str:
    model = report.get("model")
    drawn = (model or {}).get("drawn_by")
    chosen = "" if not model else (f" (model {model['chosen']}, weight {model['weight']:.3f}"
                                   + (f", runner-up {model['runner_up']}" if model["runner_up"] else "")
                                   + (f"; lumps drawn by {drawn}, which foresees the readings better"
                                      if drawn and drawn != model["chosen"] else "") + ")")
    text = {"none": "no lump", "lumps": f"{len(report['lumps'])} lump(s)",
            "undetermined": "undetermined"}[report["verdict"]]
    for soft in (model or {}).get("soft_regions") or []:  # no lump, but the map the user will look at has it
        (x, y), r = soft["center_mm"], soft["radius_mm"]
        text += f" (tissue {soft['softer']:g}x softer around ({x:.1f}, {y:.1f}), radius {r:.1f} mm)"
    unfelt = report.get("unfelt_radius_mm", (model or {}).get("unfelt_radius_mm"))  # a fixed plan's is exact
    unfelt = None if report["verdict"] == "undetermined" else unfelt
    reach = "" if unfelt is None else f"; a lump under {unfelt:.1f} mm in radius could lie unfelt between the readings"
    if reach and report.get("strategy") == "active":  # the user's side of that trade, where the user meets it
        # the tolerance bounds a drawn boundary, with the area lumps could hide beside it (stop rule (b)); with
        # no lump drawn there is no boundary to bound, and only the coverage reads closer: an 80 mm tissue's
        # `none` took 18 palpations at 0.25, 0.5 and 2 mm alike (14.1 mm unfelt), 28 at --coverage-mm 11
        knobs = "--coverage-mm" if report["verdict"] == "none" else "--tolerance-mm or --coverage-mm"
        reach += f" (a tighter {knobs} reads closer)"
    return f"verdict: {text}{chosen}{reach}"


def _lump_line(lump: dict) -> str:
    (x, y), r = lump["center_mm"], lump["radius_mm"]
    text = f"centre ({x:.2f}, {y:.2f}) ± {lump['center_sd_mm']:.2f} mm, radius {r:.2f} ± {lump['radius_sd_mm']:.2f} mm"
    if lump.get("cut_by_edge"):  # centre and radius of its part on the tissue; its axes are the whole shape's
        text += f" (its part on the tissue, whose edge cuts it: boundary ± {lump['boundary_sd_mm']:.2f} mm)"
    if "axes_mm" in lump:
        (a, b), (sa, sb) = lump["axes_mm"], lump["axes_sd_mm"]
        whole = "whole shape's axes" if lump.get("cut_by_edge") else "axes"
        text += f", {whole} {a:.2f} ± {sa:.2f} / {b:.2f} ± {sb:.2f} mm at {lump['angle_deg']:.1f}°"
    if "edge_mm" in lump:
        text += f", edge {lump['edge_mm']:.2f} mm"
    if "depth_mm" in lump:
        text += f", top {lump['depth_mm']:.1f} ± {lump['depth_sd_mm']:.1f} mm deep"
    return text


def _mm(value) -> str:
    return "n/a" if value is None else f"{value:.2f} mm"


def _say(args, text: str, always: bool = False) -> None:
    if always or not args.quiet:
        print(text, file=sys.stderr if not always else sys.stdout, flush=True)
