"""Sliding palpation in a scan: each planned path is one touch-down (a `palpation` of the scan), and every
modulation cycle along it one reading, reported and learned from like a discrete palpation's.

- raster: the rows of a serpentine raster, edge to edge (max_palpations is the number of rows);
- random: max_palpations paths of sliding_length_mm, each through a uniform random point at a uniform random
  heading (kept inside the tissue), nearer end first;
- active: the learner's next probe, extended into a path across its current 50 % boundary
  (palpd.learner.paths); max_palpations counts paths, the learner's own stop rule ends the scan.

The daemon runs the same plans over a scan's region (palpd.daemon.jobs); there a path's readings are
journaled with the path's index, so a resumed scan knows how many paths are done.
"""
from __future__ import annotations

import math

from palpd.control.contact import contact_thresholds
from palpd.control.palpation import PalpationRecord
from palpd.control.sliding import SlidingPalpation
from palpd.stiffness.sliding import stiffness_points

RASTER_ROWS_MIN = 2
MIN_STEP_MM = 0.5  # pressed spots along a path, at least this far apart


def slide(bench, settings, path) -> list:
    """One sliding palpation through the servo loop: a Probe per stiffness point (none if it found no contact).

    Where the force limit lifts the path (or its press, before it could slide), the spot is too stiff to slide
    on at this depth: it is read as every pressed spot is, by a discrete palpation there (its force-limited
    curve, or a bound), and the path goes on a cycle's span further along, touching down again. Else a stiff
    lump is felt only at its edges, where the paths lift off, and a raster's rows end there."""
    from palpd.scan import Probe, palpate

    p = settings.palpation
    thresholds = contact_thresholds(p, getattr(bench.servo.forces, "noise", None), settings.servo.rate_hz)
    probes, start, end = [], tuple(path[0]), tuple(path[1])
    while True:
        task = SlidingPalpation(start, end, p, thresholds)
        bench.servo.run(task, timeout_s=_timeout_s((start, end), p))
        rec = task.record
        probes += [Probe(PalpationRecord(point.xy_mm, point.xy_mm, rec.contact_z_mm, max_force_n=rec.max_force_n,
                                         stop_reason=rec.stop_reason), point)
                   for point in stiffness_points(rec, p)]
        if rec.stop_reason != "force" or rec.contact_z_mm is None:
            break
        lifted_at = tuple(rec.xy_mm[-1][:2]) if rec.xy_mm else start
        probes.append(palpate(bench, settings, lifted_at))
        start = _onward(lifted_at, end, _step_mm(settings))
        if start is None:
            break
    if probes or rec.stop_reason == "stopped":
        return probes  # stopped before it read anything: not a failed palpation
    # a named outcome, like a discrete palpation's (the learner and the report need one)
    record = PalpationRecord(tuple(path[0]), stop_reason=rec.stop_reason or "no_contact")
    if rec.contact_z_mm is None:
        return [Probe(record, None, "no contact found", "no_contact")]
    return [Probe(record, None, f"path too short to read ({rec.stop_reason})", "rejected")]


def _step_mm(settings) -> float:
    """How far on a path touches down again past a pressed spot: a cycle's span (the spacing of its readings),
    but no closer than the learner presses spots apart (learner.min_spacing_mm), nor than MIN_STEP_MM: at a
    slow slide a cycle spans micrometres, and a path across a stiff lump would be pressed to no end."""
    p = settings.palpation
    return max(p.sliding_speed_mm_s / p.modulation_hz, settings.learner.min_spacing_mm, MIN_STEP_MM)


def _onward(xy, end, step_mm: float) -> tuple[float, float] | None:
    """step_mm further from xy towards end; None when end is no further than that."""
    left = math.dist(xy, end)
    if left <= step_mm:
        return None
    return tuple(a + (b - a) * step_mm / left for a, b in zip(xy, end))


def _timeout_s(path, p) -> float:
    return 30.0 + math.dist(path[0], path[1]) / p.sliding_speed_mm_s


Path = tuple[tuple[float, float], tuple[float, float]]


def raster_paths(size_mm, rows: int) -> list[Path]:
    """Serpentine rows across the tissue, a row's width apart (the outer rows on the edges)."""
    from palpd.strategies import _axis

    half_x = size_mm[0] / 2.0
    ys = _axis(size_mm[1], max(RASTER_ROWS_MIN, rows))
    return [((-half_x, y), (half_x, y)) if i % 2 == 0 else ((half_x, y), (-half_x, y)) for i, y in enumerate(ys)]


def random_paths(size_mm, count: int, seed: int, length_mm: float) -> list[Path]:
    """count paths through uniform random points at uniform random headings, each slid back inside the
    tissue (cut at its edges if longer), the end nearer the last path's end first."""
    import numpy as np

    from palpd.learner.paths import _clipped, _nearer_end_first
    from palpd.strategies import random_points

    headings = np.random.default_rng([seed, 1]).uniform(0.0, math.pi, count)  # its own stream: the
    paths, here = [], None                                                     # points are random_points'
    for centre, heading in zip(random_points(size_mm, count, seed), headings):
        path = _nearer_end_first(_clipped(centre, float(heading), length_mm, size_mm), here)
        paths.append(path)
        here = path[1]
    return paths


def fixed_paths(strategy: str, size_mm, count: int, seed: int, length_mm: float) -> list[Path]:
    """The paths of a fixed plan (raster rows or random paths), tissue frame, centred on the origin."""
    if strategy == "raster":
        return raster_paths(size_mm, count)
    return random_paths(size_mm, count, seed, length_mm)


def shifted(path: Path, offset) -> Path:
    return tuple((x + offset[0], y + offset[1]) for x, y in path)  # type: ignore[return-value]


class PathPlan:
    """The learner's next probe extended into a path (learner frame in, `offset` added on the way out).
    At most max_paths paths; the learner's own stop rule (readings are many per path: not its budget)
    ends it sooner. `paths` may start above 0 (a resumed scan)."""

    def __init__(self, learner, settings, max_paths: int, offset=(0.0, 0.0), paths_done: int = 0) -> None:
        p = settings.palpation
        self.learner, self.max_paths, self.offset, self.paths = learner, max_paths, offset, paths_done
        self.length_mm = p.sliding_length_mm
        self.costs = (p.travel_speed_mm_s, p.sliding_speed_mm_s, p.sliding_speed_mm_s / p.modulation_hz)
        self.here = None

    def next_path(self) -> Path | None:
        from palpd.learner.paths import plan_path

        if self.paths >= self.max_paths:
            return None
        centre = self.learner.next_probe(math.inf)
        if centre is None:
            return None
        self.paths += 1
        path = plan_path(self.learner, centre, self.length_mm, self.here, self.costs)
        self.here = path[1]
        return shifted(path, self.offset)


class SlidingPlanner:
    """The learner's planner in sliding mode: next_probe() answers a path (start, end), or None to stop."""

    def __init__(self, size_mm, settings, max_paths: int, seed: int = 0) -> None:
        from palpd.learner.planner import ActivePlanner

        self.active = ActivePlanner(size_mm, settings, max_paths, seed)
        self.paths = PathPlan(self.active.learner, settings, max_paths)
        self.expected_total = max_paths

    def next_probe(self):
        return self.paths.next_path()

    def observe(self, probe) -> None:
        self.active.observe(probe)

    def lumps(self):
        return self.active.lumps()

    def verdict(self):
        return self.active.verdict()

    def model(self):
        return self.active.model()
