"""Scans from a script, without a daemon: the embedded simulated bench (servo loop in its own process,
simulated time), the same code `palpd scan` runs.

    import palpd
    report = palpd.simulate_scan("paper", strategy="active")
    print(report["lumps"])
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable


def scan_settings(config=None, strategy=None, max_palpations=None, seed=None, depth_mm=None, speed_mm_s=None,
                  confidence=None, train=None, tolerance_mm=None, palpation=None, coverage_mm=None):
    """Validated settings of one scan (defaults, then the config file, PALPD_ variables, then these)."""
    from palpd.config import load_settings
    from palpd.errors import UsageError

    if max_palpations is not None and max_palpations < 1:
        raise UsageError("max_palpations must be at least 1")
    if train is not None and strategy != "active":
        raise UsageError("--train teaches the active strategy's threshold; use it with --strategy active")
    return load_settings(config).updated(
        scan={"strategy": strategy, "max_palpations": max_palpations, "seed": seed},
        palpation={"depth_mm": depth_mm, "speed_mm_s": speed_mm_s, "mode": palpation},
        learner={"confidence": confidence, "tolerance_mm": tolerance_mm, "training_set": train,
                 "coverage_mm": coverage_mm},
    )


def run_simulated_scan(settings, scene, progress: Callable | None = None, realtime: bool = False,
                       max_palpations: int | None = None, on_start: Callable | None = None,
                       in_process: bool = False):
    """One scan of a scene on the simulated bench: (report with truth and metrics, planner).

    The active budget defaults to learner.max_palpations (it stops on its own well before a raster's).
    in_process: the servo loop in this process (virtual time only), for callers that may not start
    processes of their own (a Dask worker is a daemon process) and need no real-time isolation.
    """
    from palpd import metrics
    from palpd.scan import plan, run_scan

    s = settings.scan
    budget = max_palpations or (settings.learner.max_palpations if s.strategy == "active" else s.max_palpations)
    bench, close = _open_bench(settings, scene, s.seed, realtime, in_process)  # refuses a tissue out of reach first
    try:
        planner = plan(s.strategy, scene.tissue.size_mm, budget, s.seed, settings)
        if on_start is not None:
            on_start(planner)
        report = {"scene": scene.name, **run_scan(bench, settings, planner, progress)}
    finally:
        close()
    truth = metrics.scene_truth(scene, settings.scan.min_contrast)
    report["truth"] = {"lumps": truth, **report.get("truth", {})}  # with the world\'s true peak force, if known
    report["metrics"] = metrics.compare(truth, report["lumps"], scene.tissue.size_mm)
    return report, planner


def _open_bench(settings, scene, seed: int, realtime: bool, in_process: bool):
    """(bench, close): one servo process per scan, or the servo loop in this process."""
    if in_process:
        from palpd.bench import open_simulated_bench

        return open_simulated_bench(settings, scene, seed=seed), lambda: None
    from palpd.control.remote import open_servo_bench

    bench = open_servo_bench(settings, scene, seed=seed, realtime=realtime)
    return bench, bench.servo.close


def simulate_scan(scene: str | Path = "paper", strategy: str = "active", *, max_palpations: int | None = None,
                  seed: int | None = None, confidence: float | None = None, depth_mm: float | None = None,
                  speed_mm_s: float | None = None, config: str | Path | None = None,
                  progress: Callable | None = None) -> dict:
    """A whole simulated scan of a scene (a file or a shipped name, `palpd scenes`); returns the scan report
    (DESIGN.md's "Scan report JSON": lumps, probes, faults, truth, metrics ...).

    progress(done, total, probe) is called after each palpation.
    """
    from palpd.shipped import load_scene_named

    settings = scan_settings(config, strategy, max_palpations, seed, depth_mm, speed_mm_s, confidence)
    report, _ = run_simulated_scan(settings, load_scene_named(scene), progress, max_palpations=max_palpations)
    return report
