"""Sliding palpation in a scan: each planned path is one touch-down (a `palpation` of the scan), and every
modulation cycle along it one reading, reported and learned from like a discrete palpation's.

- raster: the rows of a serpentine raster, edge to edge (max_palpations is the number of rows);
- active: the learner's next probe, extended into a path across its current 50 % boundary
  (palpd.learner.paths); max_palpations counts paths, the learner's own stop rule ends the scan.
"""
from __future__ import annotations

import math

from palpd.control.palpation import PalpationRecord
from palpd.control.sliding import SlidingPalpation
from palpd.stiffness.sliding import stiffness_points

RASTER_ROWS_MIN = 2


def slide(bench, settings, path) -> list:
    """One sliding palpation through the servo loop: a Probe per stiffness point (none if it found no contact)."""
    from palpd.scan import Probe

    task = SlidingPalpation(path[0], path[1], settings.palpation)
    bench.servo.run(task, timeout_s=_timeout_s(path, settings.palpation))
    rec = task.record
    points = stiffness_points(rec, settings.palpation)
    if not points:
        record = PalpationRecord(tuple(path[0]), stop_reason=rec.stop_reason or "no_contact")
        return [Probe(record, None, "no contact found" if rec.contact_z_mm is None else "path too short to read")]
    return [Probe(PalpationRecord(point.xy_mm, point.xy_mm, rec.contact_z_mm, max_force_n=rec.max_force_n,
                                  stop_reason=rec.stop_reason), point) for point in points]


def _timeout_s(path, p) -> float:
    return 30.0 + math.dist(path[0], path[1]) / p.sliding_speed_mm_s


def raster_paths(size_mm, rows: int) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """Serpentine rows across the tissue, a row's width apart (the outer rows on the edges)."""
    from palpd.strategies import _axis

    half_x = size_mm[0] / 2.0
    ys = _axis(size_mm[1], max(RASTER_ROWS_MIN, rows))
    return [((-half_x, y), (half_x, y)) if i % 2 == 0 else ((half_x, y), (-half_x, y)) for i, y in enumerate(ys)]


class SlidingPlanner:
    """The learner's planner in sliding mode: next_probe() answers a path (start, end), or None to stop."""

    def __init__(self, size_mm, settings, max_paths: int, seed: int = 0) -> None:
        from palpd.learner.planner import ActivePlanner

        self.active = ActivePlanner(size_mm, settings, max_paths, seed)
        self.max_paths, self.expected_total, self.paths = max_paths, max_paths, 0
        p = settings.palpation
        self.length_mm = p.sliding_length_mm
        self.costs = (p.travel_speed_mm_s, p.sliding_speed_mm_s, p.sliding_speed_mm_s / p.modulation_hz)
        self.here = None

    def next_probe(self):
        from palpd.learner.paths import plan_path

        if self.paths >= self.max_paths:
            return None
        centre = self.active.learner.next_probe(math.inf)  # readings are many per path: paths are the budget
        if centre is None:
            return None
        self.paths += 1
        path = plan_path(self.active.learner, centre, self.length_mm, self.here, self.costs)
        self.here = path[1]
        return path

    def observe(self, probe) -> None:
        self.active.observe(probe)

    def lumps(self):
        return self.active.lumps()

    def verdict(self):
        return self.active.verdict()

    def model(self):
        return self.active.model()
