"""One tradeoff run: a scan exactly as `palpd scan` runs it (the planner's own stop rule, never the truth),
then scored against the scene's truth."""
from __future__ import annotations

from palpd.errors import ScanFault
from palpd.tradeoff.grid import Run

COLUMNS = ["scene", "seed", "strategy", "palpation", "setting", "palpations", "robot_time_s",
           "center_error_mm", "radius_error_mm", "iou", "lumps_found", "lumps_true", "false_lumps", "verdict",
           "boundary_error_mm", "expected_boundary_error_mm", "unfelt_radius_mm", "wrong_beyond_claim"]


def run_one(run: Run) -> dict:
    """The tradeoff row of one run (a task: it may run in another process or on another machine).

    A scan stopped by a safety fault raises ScanFault: its accuracy would mean nothing.
    """
    from palpd.embedded import run_simulated_scan
    from palpd.threads import pin_blas_to_one_thread

    pin_blas_to_one_thread()  # a worker started by hand did not come through palpd's entry point
    report, _ = run_simulated_scan(run.settings, run.scene, max_palpations=run.entry.palpations, in_process=True)
    if report["faults"]:
        fault = report["faults"][0]
        raise ScanFault(f"safety fault {fault['code']}: {fault['message']}")
    return row(run, report)


def row(run: Run, report: dict) -> dict:
    from palpd.metrics import boundary_error_mm, region_iou, wrong_beyond_claim

    m, size = report["metrics"], run.scene.tissue.size_mm
    iou = region_iou(report["truth"]["lumps"], report["lumps"], size)
    error = boundary_error_mm(report["truth"]["lumps"], report["lumps"], size)
    unfelt = (report.get("model") or {}).get("unfelt_radius_mm")
    return {"scene": run.scene.name, "seed": run.seed, "strategy": run.entry.strategy,
            "palpation": run.entry.palpation, "setting": run.entry.label, "palpations": report["palpations"],
            "robot_time_s": report["robot_time_s"], "center_error_mm": m["max_center_error_mm"],
            "radius_error_mm": m["max_radius_error_mm"], "iou": round(iou, 4),
            "lumps_found": m["lumps_found"], "lumps_true": m["lumps_true"], "false_lumps": m["false_lumps"],
            "verdict": report["verdict"], "boundary_error_mm": None if error is None else round(error, 4),
            "expected_boundary_error_mm": (report.get("model") or {}).get("expected_boundary_error_mm"),
            "unfelt_radius_mm": unfelt, "wrong_beyond_claim": wrong_beyond_claim(m, unfelt)}
