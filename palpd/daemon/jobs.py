"""Jobs the scan worker runs: a scan that journals and publishes each palpation, a single probe, a tare."""
from __future__ import annotations

from palpd.control.safety import Fault
from palpd.control.tasks import MoveTo
from palpd.daemon.learning import DEFAULT_MAX_PALPATIONS, LearnerPlan
from palpd.errors import PalpdError, ScanFault
from palpd.files import is_storage_error
from palpd.scan import PARK_HEIGHT_MM, FixedPlan, palpate, plan
from palpd.stiffness import load_solvers


OLDER_SESSIONS = {"palpation": "discrete"}  # what a session written before a key existed meant


def resolved_scan(args: dict, tissue_size_mm, settings) -> dict:
    """scan.start's args with the defaults filled in, as the session keeps them (replay needs the region).
    The budget counts paths when sliding (a path gives a reading per modulation cycle)."""
    default_budget = settings.learner.max_palpations if args["strategy"] == "active" else DEFAULT_MAX_PALPATIONS
    return args | {"size_mm": list(args["size_mm"] or tissue_size_mm), "center_mm": list(args["center_mm"]),
                   "max_palpations": args["max_palpations"] or default_budget,
                   "palpation": args.get("palpation") or settings.palpation.mode}


def session_plan(scan: dict, estimator, entries: list[dict], settings):
    """The planner of a session's scan with `entries` journaled: the learner's, or the fixed plan's remaining
    points or paths (fixed plans are deterministic). settings: the scan's own (scan_settings)."""
    if scan["palpation"] == "sliding":
        return _sliding_session_plan(scan, estimator, paths_done(entries), settings)
    if scan["strategy"] == "active":
        return LearnerPlan(estimator)
    cx, cy = scan["center_mm"]
    base = plan(scan["strategy"], scan["size_mm"], scan["max_palpations"], scan["seed"])
    planner = FixedPlan([(x + cx, y + cy) for x, y in base.points])
    planner.points = planner.points[len(entries):]
    return planner


def paths_done(entries: list[dict]) -> int:
    """Paths a sliding scan has slid: a path's readings are journaled together, each with its path's index."""
    return len({entry["path"] for entry in entries if "path" in entry})


def _sliding_session_plan(scan: dict, estimator, done: int, settings):
    from palpd.slide import PathPlan, fixed_paths, shifted

    centre = tuple(scan["center_mm"])
    if scan["strategy"] == "active":
        return PathCount(LearnerPathPlan(PathPlan(estimator.learner, settings, scan["max_palpations"], centre, done)),
                         done)
    paths = fixed_paths(scan["strategy"], scan["size_mm"], scan["max_palpations"], scan["seed"],
                        settings.palpation.sliding_length_mm)
    planner = FixedPlan([shifted(path, centre) for path in paths])
    planner.points = planner.points[done:]
    return PathCount(planner, done)


class LearnerPathPlan:
    """Active sliding: the session's learner plans each path; the scan job feeds it what the path read."""

    def __init__(self, paths) -> None:
        self.paths = paths
        self.expected_total = paths.max_paths

    def next_probe(self):
        return self.paths.next_path()

    def observe(self, probe) -> None:
        """Nothing: the job observes the journaled entry into the estimator (one learner, fed once)."""


class PathCount:
    """A sliding plan that knows the index of the path under way (journaled with each of its readings)."""

    def __init__(self, inner, done: int) -> None:
        self.inner, self.current = inner, done - 1
        self.expected_total = inner.expected_total

    def next_probe(self):
        path = self.inner.next_probe()
        if path is not None:
            self.current += 1
        return path

    def observe(self, probe) -> None:
        self.inner.observe(probe)


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
        # the way out too: a damped model's fit uses it, and replay refits exactly what the scan fitted
        "unload_depth_mm": record.unload_depth_mm, "unload_force_n": record.unload_force_n,
        "t_first_tick_s": record.t_first_tick_s, "t_end_s": record.t_end_s,  # its raw samples, for replay
        "t_start_s": record.t_start_s, "t_armed_s": record.t_armed_s, "outcome": probe.outcome, "stop_reason_detail": probe.rejected,
        # how contact was judged (scaled to the measured noise) and aligned: replay cuts it again the same way
        "contact_on_n": record.contact_on_n, "contact_off_n": record.contact_off_n,
        "contact_filter_s": record.contact_filter_s, "force_lead_s": record.force_lead_s,
        "dropped_samples": record.dropped_samples, "stiffness_bound_n_per_mm": probe.stiffness_bound_n_per_mm,
        "presses": probe.presses,
    }


def publish_entry(worker, entry: dict) -> None:
    """The palpation and (when the fit held) its stiffness on the bus."""
    worker.event("palpation", index=entry["index"], xy_mm=entry["xy_mm"], depth_mm=entry["depth_mm"],
                 force_n=entry["force_n"], target_xy_mm=entry["target_xy_mm"], rejected=entry["rejected"],
                 outcome=entry["outcome"], stiffness_bound_n_per_mm=entry["stiffness_bound_n_per_mm"],
                 presses=entry.get("presses", 1))  # a journal older than the field: one press
    if entry["stiffness_n_per_mm"] is not None:
        worker.event("stiffness", index=entry["index"], xy_mm=entry["xy_mm"],
                     stiffness_n_per_mm=entry["stiffness_n_per_mm"],
                     stiffness_sd_n_per_mm=entry["stiffness_sd_n_per_mm"])


def journaled(worker, session, entry: dict) -> bool:
    """Journal the entry (fsync); on a storage error the scan stops (the supervisor makes it a `storage` fault
    once the arm is parked) and the palpation, not on the disk, is neither published nor learned from."""
    try:
        session.journal(entry)
    except OSError as exc:
        if not is_storage_error(exc):
            raise
        worker.request_stop()
        worker.send({"kind": "storage", "what": f"journaling palpation {entry['index']} of session {session.name}",
                     "error": exc})
        return False
    return True


class ScanJob:
    """Palpate the plan's remaining points; each palpation is journaled (fsync) before it is published."""

    def __init__(self, session, settings, planner, estimator) -> None:
        self.session, self.settings, self.planner, self.estimator = session, settings, planner, estimator
        self.finished = False
        self.recording = ""  # the MCAP file of this run, named by the supervisor

    def __call__(self, worker) -> None:
        report = worker.scan(self.settings, self.planner, lambda done, total, probe: self._on_probe(worker, probe))
        self.finished = not report["faults"] and not worker.stop_requested.is_set()
        worker.event("estimate", **self.estimator.estimate(), done=self.finished)
        worker.send({"kind": "map", "map": self.estimator.posterior_map()})

    def _on_probe(self, worker, probe) -> None:
        entry = journal_entry(len(self.session.entries), probe, worker.bench.clock.now())
        if isinstance(self.planner, PathCount):  # a sliding reading: its path, so a resumed scan goes on from there
            entry |= {"palpation": "sliding", "path": self.planner.current}
        entry["recording"] = self.recording  # whose raw samples hold it (each run's servo clock starts anew)
        if not journaled(worker, self.session, entry):
            return
        self.estimator.observe(entry["xy_mm"], entry["stiffness_n_per_mm"], entry["stiffness_sd_n_per_mm"] or 0.0,
                               entry.get("target_xy_mm"), entry.get("outcome"), entry.get("stiffness_bound_n_per_mm"))
        publish_entry(worker, entry)
        worker.event("estimate", **self.estimator.estimate())
        worker.send({"kind": "map", "map": self.estimator.posterior_map()})  # made here: the learner is ours


class ProbeJob:
    """One palpation at a point, journaled (fsync) in the daemon's probes session before it is published."""

    def __init__(self, settings, xy_mm, session) -> None:
        self.settings, self.xy_mm, self.session = settings, xy_mm, session
        self.recording = ""  # the MCAP file of this probe, named by the supervisor

    def __call__(self, worker) -> None:
        p, servo = self.settings.palpation, worker.bench.servo
        load_solvers()  # before the motors are on (see there)
        servo.start()
        try:
            probe = palpate(worker.bench, self.settings, self.xy_mm)
            tip = servo.last_tick.tip_mm
            servo.run(MoveTo((tip[0], tip[1], PARK_HEIGHT_MM), p.travel_speed_mm_s, p.accel_mm_s2))
        finally:
            servo.stop()
        entry = journal_entry(len(self.session.entries), probe, worker.bench.clock.now())
        entry["recording"] = self.recording  # whose raw samples hold it, as a scan's entries say
        if journaled(worker, self.session, entry):
            publish_entry(worker, entry)


class RestartServoJob:
    """After a servo_lost fault: a new servo process for the same bench; the worker drives it from then on."""

    def __init__(self, reopen_bench) -> None:
        self.reopen_bench, self.bench = reopen_bench, None

    def __call__(self, worker) -> None:
        lost = worker.bench
        try:
            bench = self.reopen_bench()
        except PalpdError as exc:  # still lost: the job ends with the old servo's servo_lost fault
            lost.servo.fault = Fault("servo_lost", f"restarting the servo process failed: {exc}", 0.0)
            raise ScanFault(str(exc)) from None
        lost.servo.close()  # its shared memory and pipe; the process is gone already
        worker.bench = self.bench = bench
        worker.home()  # the arm floats in the bridge's hold where the lost one left it: take it home
