"""A whole autonomous scan: tare, palpate each planned point, fit, estimate, report."""
from __future__ import annotations

import time
from collections import Counter
from functools import partial
from typing import Callable

from palpd import strategies
from palpd.bench import Bench
from palpd.config import RATE_MODELS
from palpd.control.contact import contact_thresholds, tare_summary
from palpd.control.palpation import Palpation, PalpationRecord
from palpd.probe import MIN_SLOPE_DEPTH_MM, Probe, judge
from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.errors import ScanFault, UsageError
from palpd.estimate import estimate_lumps, unfelt_radius_mm
from palpd.stiffness import load_solvers

# A press stopped by the force limit whose stiffness is less certain than this (relative sd) is repeated gently
# (palpation.too_stiff = "repalpate"): a 30 N/mm lump in 5 N/mm tissue read 25.1 ± 6.9, then 30.2 ± 4.3
# (scripts/stiff_spots.py).
REPALPATE_REL_SE = 0.1
PARK_HEIGHT_MM = 20.0  # a single probe (probe.at) backs out this high before the servo parks the arm


class FixedPlan:
    """A planner whose points are all decided before the first palpation (raster, random).

    Planners answer next_probe() with a point or None when the scan should stop,
    and learn from observe(probe); an adaptive planner (the learner) does the same.
    A fixed plan's readings are weighed by the learner all the same (`estimator`): the points do not
    change with what is found, but what is reported is what the evidence decides, as in an active
    scan, so that no strategy reports a lump the readings do not support.
    """

    def __init__(self, points: list[tuple[float, float]], size_mm=None, make_estimator=None) -> None:
        self.points = list(points)
        self.size_mm = size_mm  # the tissue the points cover (what a "no lump" from them claims)
        self.expected_total = len(self.points)
        self._make_estimator = make_estimator  # makes the estimator at the first reading (a learner costs ~0.3 s to build)
        self.estimator = None
        self._next = 0

    def next_probe(self) -> tuple[float, float] | None:
        if self._next >= len(self.points):
            return None
        self._next += 1
        return self.points[self._next - 1]

    def observe(self, probe: "Probe") -> None:
        """The points do not change with what is found; the estimator learns from it."""
        if self.estimator is None and self._make_estimator is not None:
            self.estimator = self._make_estimator()
        if self.estimator is not None:
            self.estimator.observe(probe)


def plan(strategy: str, size_mm, max_palpations: int, seed: int, settings=None):
    """The planner for a strategy; `active` is the online learner (settings: palpd.config.Settings).
    With palpation.mode = "sliding" the plan is of paths (palpd.slide)."""
    if settings is not None and settings.palpation.mode == "sliding":
        return _sliding_plan(strategy, size_mm, max_palpations, seed, settings)
    if strategy == "raster":
        return FixedPlan(strategies.raster_points(size_mm, max_palpations), size_mm, partial(_learner_planner, size_mm, settings, seed))
    if strategy == "random":
        points = strategies.random_points(size_mm, max_palpations, seed)
        return FixedPlan(points, size_mm, partial(_learner_planner, size_mm, settings, seed))
    if strategy == "active":
        return _learner_planner(size_mm, settings, seed, max_palpations)
    raise UsageError(f"unknown strategy {strategy!r}; choose from {', '.join(strategies.STRATEGIES)}")


def _learner_planner(size_mm, settings, seed: int, max_palpations: int = 0):
    """The learner: the active strategy's planner, and the estimator of a fixed plan's readings."""
    from palpd.config import Settings
    from palpd.learner import ActivePlanner

    return ActivePlanner(size_mm, settings or Settings(), max_palpations, seed)


def _sliding_plan(strategy: str, size_mm, max_palpations: int, seed: int, settings):
    from palpd import slide

    if strategy in ("raster", "random"):
        paths = slide.fixed_paths(strategy, size_mm, max_palpations, seed, settings.palpation.sliding_length_mm)
        return FixedPlan(paths, size_mm, partial(_learner_planner, size_mm, settings, seed))
    if strategy == "active":
        return slide.SlidingPlanner(size_mm, settings, max_palpations, seed)
    raise UsageError(f"unknown strategy {strategy!r}; choose from {', '.join(strategies.STRATEGIES)}")


def palpations(bench: Bench, settings, planned) -> list[Probe]:
    """What one planned palpation reads: a point pressed once, or a path slid along (a reading per cycle).
    A pressed point returns while the servo may still be lifting out of it: the caller calls servo.settle()
    once it has used the reading (palpate's `lifting`)."""
    if settings.palpation.mode == "sliding":
        from palpd.slide import slide

        return slide(bench, settings, planned)
    return [palpate(bench, settings, planned, lifting=True)]


def palpate(bench: Bench, settings, xy_mm, lifting: bool = False) -> Probe:
    """One palpation through the servo loop (contact thresholds scaled to the noise the last tare measured),
    then its contact point found from the whole trace and its stiffness fit, or a named outcome. A press
    that met the force limit early is repeated gently when palpation.too_stiff says so. `lifting`: return
    with the servo still lifting out of the press (servo.begin); the caller calls servo.settle() before it
    reads the servo's state, and that raises a fault of the lift."""
    p = settings.palpation
    probe = _press(bench, settings, p, xy_mm)
    if p.too_stiff != "repalpate" or not _stopped_early(probe):
        if not lifting:
            bench.servo.settle()
        return probe
    again = _press(bench, settings, p.model_copy(update={"speed_mm_s": p.speed_mm_s * p.gentle_speed_factor}), xy_mm)
    # the gentle press's fit over the first's (less of the controller's lag in it); a fit over a bound; and of
    # two lower bounds on one spot, the higher (both hold)
    kept = again if again.fit is not None or probe.fit is None else probe
    if kept.outcome == "too_stiff" and probe.outcome == "too_stiff":
        kept.stiffness_bound_n_per_mm = max(kept.stiffness_bound_n_per_mm, probe.stiffness_bound_n_per_mm)
    kept.presses = 2
    if not lifting:
        bench.servo.settle()
    return kept


def _stopped_early(probe: Probe) -> bool:
    """The force limit came before a reading to REPALPATE_REL_SE: a fit over few samples, or a bound for want
    of samples. Not a press the limit stopped within MIN_SLOPE_DEPTH_MM, nor one that bounced off: a gentler one
    stops as shallow (the depth is the force over k, whatever the speed), and bounces too (palpd.control.palpation)."""
    rec = probe.record
    if rec.stop_reason != "force" or rec.rebounded or max(rec.depth_mm, default=0.0) < MIN_SLOPE_DEPTH_MM:
        return False
    return probe.outcome == "too_stiff" or (
        probe.fit is not None and probe.fit.stiffness_se_n_per_mm > REPALPATE_REL_SE * probe.fit.stiffness_n_per_mm)


def _press(bench: Bench, settings, palpation_settings, xy_mm) -> Probe:
    thresholds = contact_thresholds(palpation_settings, getattr(bench.servo.forces, "noise", None),
                                    settings.servo.rate_hz)
    palpation = Palpation(xy_mm, palpation_settings, thresholds)
    bench.servo.begin(palpation)  # back once the record is final: the fit runs beside the lift (settle)
    return judge(palpation.finish(refit_onset=settings.stiffness.model not in RATE_MODELS), settings)


def _settled(servo) -> ScanFault | None:
    """servo.settle(): the fault that stopped the task begun last after it settled, returned, not raised."""
    try:
        servo.settle()
    except ScanFault as exc:
        return exc
    return None


def _estimate(planner, probes: list[Probe], settings) -> tuple[list, str, dict | None]:
    """(lumps, verdict, model): what the learner decides from the readings, whether it chose the points
    (active) or weighed a fixed plan's; without one the §3.4 estimate, whose verdict is `lumps` or
    `none`, with no model choice behind it."""
    planner = getattr(planner, "estimator", None) or planner
    if hasattr(planner, "lumps"):
        return planner.lumps(), planner.verdict(), planner.model()
    good = [pr for pr in probes if pr.fit is not None]
    lumps = estimate_lumps([pr.record.xy_mm for pr in good], [pr.stiffness_n_per_mm for pr in good],
                           settings.scan.min_contrast) if good else []
    return lumps, ("lumps" if lumps else "none") if good else "undetermined", None


HINTS = {"no_contact": "check the tissue placement (tissue.origin_mm) and the force sensor",
         "rejected": "check the sensor noise and the palpation depth and speed",
         "too_soft": "press deeper (palpation.depth_mm) or check the force sensor",
         "too_stiff": "lower the indentation speed or raise palpation.max_force_n"}
WHAT = {"no_contact": "found no contact", "rejected": "gave no usable fit", "too_soft": "felt no force above the noise",
        "too_stiff": "hit the force limit at once"}


def failure_reason(probes: list) -> str | None:
    """A sentence when fewer than half the palpations gave a stiffness or a bound, naming the commonest failure."""
    informative = sum(pr.fit is not None or pr.stiffness_bound_n_per_mm is not None for pr in probes)
    if not probes or informative * 2 >= len(probes):
        return None
    failed = Counter(pr.outcome for pr in probes if pr.fit is None)
    outcome, count = failed.most_common(1)[0]
    return f"{count} of {len(probes)} palpations {WHAT[outcome]}: {HINTS[outcome]}"


def _cut_short(faults: list[dict]) -> str | None:
    """A sentence when a safety fault ended the scan: it palpated only part of what it planned to."""
    return f"a safety fault ({faults[0]['code']}) stopped the scan before it was done" if faults else None


def run_scan(bench: Bench, settings, planner, progress: Callable[[int, int, Probe], None] | None = None) -> dict:
    """Palpate where the planner says until it says stop; returns the report body (without truth).

    A fault ends the scan early and is recorded in the report.
    """
    p = settings.palpation
    servo = bench.servo
    wall_start, robot_start = time.monotonic(), bench.clock.now()
    probes: list[Probe] = []
    faults = []
    tared = None
    lifted = 0  # sliding paths the force limit lifted off somewhere (the spot pressed instead: palpd.slide)
    load_solvers()  # before the motors are on (see there)
    try:
        servo.start()  # homes the arm first, supervised: after a category-0 stop it may lie anywhere
        xy = planner.next_probe()
        start = (0.0, 0.0) if xy is None else (xy[0] if p.mode == "sliding" else xy)
        first = (start[0], start[1], p.clearance_mm)
        servo.run(MoveTo(first, p.travel_speed_mm_s, p.accel_mm_s2))
        tare = HoldAndCollect(p.tare_samples, where=first)
        servo.run(tare)
        servo.forces.tare(tare.samples)
        tared = tare_summary(servo.forces, p, settings.servo.rate_hz)
        while xy is not None:
            read = palpations(bench, settings, xy)
            lifted += p.mode == "sliding" and any(pr.record.stop_reason == "force" for pr in read)
            for probe in read:
                probes.append(probe)
                planner.observe(probe)
                # The servo may still be lifting out of the press (palpate's `lifting`): its end before the
                # progress (the daemon journals the record, the lift's end included) and the next motion. A
                # fault there ends the scan as ever; the reading, complete before it, stands (the learner has it).
                lift_fault = _settled(servo)
                if progress:
                    progress(len(probes), max(planner.expected_total, len(probes)), probe)
                if lift_fault is not None:
                    raise lift_fault
            xy = planner.next_probe()
        servo.stop()  # parks at the rest pose, then the amplifiers go off
        if servo.fault is not None:  # latched between tasks (the servo process's idle hold): the motors were off
            raise ScanFault(servo.fault.message)
    except ScanFault:
        faults.append(servo.fault.as_dict())
    finally:
        servo.stop()
    lumps, verdict, model = _estimate(planner, probes, settings)
    failing = failure_reason(probes) or _cut_short(faults)
    if failing:
        # palpations that keep failing decide nothing, least of all "no lump"; nor does a plan a fault cut short:
        # a sliding raster of a noisy sensor stopped at its 26th reading by an indentation fault had said "none"
        verdict = "undetermined"
    body = {
        "strategy": settings.scan.strategy,
        "palpation": p.mode,
        "seed": settings.scan.seed,
        "palpations": len(probes),
        "robot_time_s": round(bench.clock.now() - robot_start, 3),
        "wall_time_s": round(time.monotonic() - wall_start, 3),
        "max_contact_force_n": round(servo.max_contact_force_n, 4),
        # re-tares at approaches and the largest drift found (control.health); what the scan's tare measured
        "sensor": {**servo.health.summary(), "tare": tared},
        "faults": faults,
        "outcomes": dict(Counter(pr.outcome for pr in probes)),
        "verdict": verdict,
        "model": model,
        "lumps": [lump.as_dict() for lump in lumps],
        "probes": [pr.as_dict() for pr in probes],
    }
    if failing:
        body["undetermined_reason"] = failing
    if isinstance(planner, FixedPlan) and planner.size_mm is not None and verdict != "undetermined":
        # a fixed plan's claim, exactly (the learner's model states its own on its coverage cells, 2 mm apart):
        # how large a lump could lie unread
        good = [pr.record.xy_mm for pr in probes if pr.fit is not None]
        body["unfelt_radius_mm"] = round(unfelt_radius_mm(good, planner.size_mm), 1)
    if p.mode == "sliding":
        body["paths_lifted_at_force_limit"] = lifted
    true_peak_n = servo.true_max_contact_force_n
    if true_peak_n is not None:  # in simulation: what the tissue really took, at every physics step
        body["truth"] = {"max_contact_force_n": round(true_peak_n, 4),
                         "max_indentation_mm": round(servo.true_max_indentation_mm, 3)}
    return body
