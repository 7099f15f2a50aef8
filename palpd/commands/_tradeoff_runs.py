"""Scans for the tradeoff benchmark: the first palpation at which each strategy meets the targets."""
from __future__ import annotations

from palpd import metrics
from palpd.bench import open_simulated_bench
from palpd.commands.bench_tradeoff import BUDGET, RASTER_SIDES, TARGET
from palpd.config import Settings
from palpd.estimate import estimate_lumps
from palpd.scan import plan, run_scan


def on_target(m: dict) -> bool:
    return (m["lumps_found"] == m["lumps_true"] and m["false_lumps"] == 0
            and (m["lumps_true"] == 0 or (m["max_center_error_mm"] <= TARGET["center_mm"]
                                          and m["max_radius_error_mm"] <= TARGET["radius_mm"]
                                          and m["min_iou"] >= TARGET["iou"])))


class _UntilOnTarget:
    """A planner that stops as soon as a check says the targets are met (lump scenes only: on a
    no-lump scene the run goes on to its end, to count the false lumps it grows)."""

    def __init__(self, planner, stop) -> None:
        self.planner, self.stop = planner, stop
        self.expected_total = planner.expected_total

    def next_probe(self):
        return None if self.stop() else self.planner.next_probe()

    def observe(self, probe) -> None:
        self.planner.observe(probe)


def _scan_until(scene, seed: int, settings, planner, lumps_now) -> dict:
    """Scan until the estimate meets the targets (or the plan ends); lumps_now(probes) is the estimate so far."""
    bench = open_simulated_bench(settings, scene, seed=seed)
    truth, t0, first, probes = metrics.scene_truth(scene), bench.clock.now(), {}, []

    def progress(done, _total, probe):
        probes.append(probe)
        if not first and on_target(metrics.compare(truth, [l.as_dict() for l in lumps_now(probes)])):
            first.update(palpations=done, robot_time_s=round(bench.clock.now() - t0, 2))

    report = run_scan(bench, settings, _UntilOnTarget(planner, lambda: bool(first) and bool(truth)), progress)
    if hasattr(planner, "lumps"):
        report["lumps"] = [l.as_dict() for l in planner.lumps()]
    final = metrics.compare(truth, report["lumps"])
    return {"scene": scene.name, "seed": seed, "lumps_true": len(truth), "palpations": first.get("palpations"),
            "robot_time_s": first.get("robot_time_s"), "false_lumps": final["false_lumps"],
            "final_palpations": report["palpations"]}


def first_on_target_active(scene, seed: int) -> dict:
    settings = Settings().updated(scan={"strategy": "active"}, learner={"confidence": 0.99})
    planner = plan("active", scene.tissue.size_mm, BUDGET, seed, settings)
    return {"strategy": "active", **_scan_until(scene, seed, settings, planner, lambda _probes: planner.lumps())}


def first_on_target_random(scene, seed: int) -> dict:
    settings = Settings()
    planner = plan("random", scene.tissue.size_mm, BUDGET, seed)

    def lumps_now(probes):
        """The §3.4-style estimate a scan report gives, from the fitted probes so far."""
        good = [p for p in probes if p.fit is not None]
        return estimate_lumps([p.record.xy_mm for p in good], [p.stiffness_n_per_mm for p in good],
                              settings.scan.min_contrast) if good else []

    return {"strategy": "random", **_scan_until(scene, seed, settings, planner, lumps_now)}


def first_on_target_raster(scene, seed: int) -> dict:
    """A raster is planned for its size, so each size is its own scan; the first size on target counts."""
    settings = Settings()
    result = None
    for side in RASTER_SIDES:
        bench = open_simulated_bench(settings, scene, seed=seed)
        report = run_scan(bench, settings, plan("raster", scene.tissue.size_mm, side * side, seed))
        m = metrics.compare(metrics.scene_truth(scene), report["lumps"])
        result = {"scene": scene.name, "seed": seed, "lumps_true": len(scene.lump),
                  "palpations": report["palpations"] if on_target(m) else None,
                  "robot_time_s": report["robot_time_s"] if on_target(m) else None,
                  "false_lumps": m["false_lumps"], "final_palpations": report["palpations"]}
        if on_target(m):
            break
    return {"strategy": "raster", **result}


def active_scan(scene, seed: int, change: dict) -> dict:
    """One default active scan with one knob changed: its robot time and errors."""
    learner = {k: v for k, v in change.items() if k == "confidence"}
    palpation = {k: v for k, v in change.items() if k != "confidence"}
    settings = Settings().updated(scan={"strategy": "active"}, learner=learner, palpation=palpation)
    planner = plan("active", scene.tissue.size_mm, settings.learner.max_palpations, seed, settings)
    report = run_scan(open_simulated_bench(settings, scene, seed=seed), settings, planner)
    m = metrics.compare(metrics.scene_truth(scene), report["lumps"])
    return {"palpations": report["palpations"], "robot_time_s": report["robot_time_s"],
            "max_center_error_mm": m["max_center_error_mm"], "max_radius_error_mm": m["max_radius_error_mm"],
            "min_iou": m["min_iou"], "false_lumps": m["false_lumps"], "lumps_missed": m["lumps_missed"]}
