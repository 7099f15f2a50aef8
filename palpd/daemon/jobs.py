"""Jobs the scan worker runs: a scan that journals and publishes each palpation, a single probe, a tare."""
from __future__ import annotations

from palpd.control.tasks import MoveTo
from palpd.scan import PARK_HEIGHT_MM, FixedPlan, palpate, plan


def region_plan(args, tissue_size_mm) -> FixedPlan:
    """The scan's points: the strategy over the requested region (default: the whole tissue)."""
    size = args["size_mm"] or tissue_size_mm
    cx, cy = args["center_mm"]
    base = plan(args["strategy"], size, args["max_palpations"], args["seed"])
    return FixedPlan([(x + cx, y + cy) for x, y in base.points])


def region_problem(args, tissue_size_mm) -> str | None:
    size = args["size_mm"] or tissue_size_mm
    for axis in range(2):
        if abs(args["center_mm"][axis]) + size[axis] / 2 > tissue_size_mm[axis] / 2 + 1e-9:
            return f"region {size[0]:g} x {size[1]:g} mm at {tuple(args['center_mm'])} leaves the tissue " \
                   f"({tissue_size_mm[0]:g} x {tissue_size_mm[1]:g} mm)"
    return None


def journal_entry(index: int, probe, t_s: float) -> dict:
    record = probe.record
    return {
        "index": index, "t": t_s, "target_xy_mm": list(record.target_xy_mm), "xy_mm": list(record.xy_mm),
        "depth_mm": record.depth_mm, "force_n": record.force_n, "stop_reason": record.stop_reason,
        "stiffness_n_per_mm": probe.stiffness_n_per_mm,
        "stiffness_sd_n_per_mm": probe.fit.stiffness_se_n_per_mm if probe.fit else None,
        "rejected": probe.rejected,
    }


def publish_entry(worker, entry: dict) -> None:
    """The palpation and (when the fit held) its stiffness on the bus."""
    worker.event("palpation", index=entry["index"], xy_mm=entry["xy_mm"], depth_mm=entry["depth_mm"],
                 force_n=entry["force_n"])
    if entry["stiffness_n_per_mm"] is not None:
        worker.event("stiffness", index=entry["index"], xy_mm=entry["xy_mm"],
                     stiffness_n_per_mm=entry["stiffness_n_per_mm"],
                     stiffness_sd_n_per_mm=entry["stiffness_sd_n_per_mm"])


class ScanJob:
    """Palpate the plan's remaining points; each palpation is journaled (fsync) before it is published."""

    def __init__(self, session, settings, planner, estimator) -> None:
        self.session, self.settings, self.planner, self.estimator = session, settings, planner, estimator
        self.finished = False

    def __call__(self, worker) -> None:
        report = worker.scan(self.settings, self.planner, lambda done, total, probe: self._on_probe(worker, probe))
        self.finished = not report["faults"] and not worker.stop_requested.is_set()
        worker.event("estimate", **self.estimator.estimate(), done=self.finished)

    def _on_probe(self, worker, probe) -> None:
        entry = journal_entry(len(self.session.entries), probe, worker.bench.clock.now())
        self.session.journal(entry)
        self.estimator.observe(entry["xy_mm"], entry["stiffness_n_per_mm"], entry["stiffness_sd_n_per_mm"] or 0.0)
        publish_entry(worker, entry)
        worker.event("estimate", **self.estimator.estimate())


class ProbeJob:
    """One palpation at a point, journaled (fsync) in the daemon's probes session before it is published."""

    def __init__(self, settings, xy_mm, session) -> None:
        self.settings, self.xy_mm, self.session = settings, xy_mm, session

    def __call__(self, worker) -> None:
        p, servo = self.settings.palpation, worker.bench.servo
        servo.start()
        try:
            probe = palpate(worker.bench, self.settings, self.xy_mm)
            tip = servo.last_tick.tip_mm
            servo.run(MoveTo((tip[0], tip[1], PARK_HEIGHT_MM), p.travel_speed_mm_s, p.accel_mm_s2))
        finally:
            servo.stop()
        entry = journal_entry(len(self.session.entries), probe, worker.bench.clock.now())
        self.session.journal(entry)
        publish_entry(worker, entry)


def reloaded_plan(session, tissue_size_mm) -> FixedPlan:
    """The session's plan without the points already journaled (plans are deterministic)."""
    planner = region_plan(session.meta["scan"], tissue_size_mm)
    done = len(session.entries)
    planner.points = planner.points[done:]
    return planner
