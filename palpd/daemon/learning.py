"""The daemon's estimator: the online learner (palpd.learner) over the scan's region, and its active planner.

One learner per session: every journaled palpation is observed once (live, on
recovery, in replay, always in journal order with the same numbers), so the
live, recovered and replayed estimates are the same. The learner's grid is
centred on its own origin; a scan's region may sit anywhere on the tissue, so
points go in and lumps and probes come out shifted by the region's centre.
"""
from __future__ import annotations

import math

from palpd.posterior import MAP_CELLS_PER_SIDE, posterior_grid

DEFAULT_MAX_PALPATIONS = 81  # raster and random, when scan.start does not say


def scan_settings(settings, scan: dict):
    """The settings a session's scan ran with (its strategy, budget, seed, depth and speed)."""
    return settings.updated(
        scan={"strategy": scan["strategy"], "max_palpations": scan["max_palpations"], "seed": scan["seed"]},
        palpation={"depth_mm": scan["depth_mm"], "speed_mm_s": scan["speed_mm_s"],
                   "mode": scan.get("palpation", "discrete")})


class LearnerEstimator:
    """The learner over a rectangle of the tissue (tissue-frame points in, tissue-frame answers out)."""

    def __init__(self, settings, center_mm, size_mm, max_palpations: int, seed: int = 0, plans: bool = True) -> None:
        self.cx, self.cy = float(center_mm[0]), float(center_mm[1])
        self.max_palpations = max_palpations
        self.plans = plans  # the learner chooses the probes (active); a raster's estimate names no next probe
        # Here, not at the top: the learner and its scipy take ~0.4 s to import, and a daemon that never
        # estimates (a probe, a bias, a status) should not pay it on every start.
        from palpd.learner.planner import make_learner

        self.learner = make_learner(settings, tuple(size_mm), seed)
        self.xy_mm: list[tuple[float, float]] = []  # the stiffness points, for estimate.get and plots
        self.k_n_per_mm: list[float] = []
        self._next = None  # (palpations seen, answer): next_probe is asked by the planner and the estimate

    def observe(self, xy_mm, stiffness_n_per_mm: float | None, sd_n_per_mm: float = 0.0,
                target_xy_mm=None, outcome: str | None = None, bound_n_per_mm: float | None = None) -> None:
        """A journaled palpation with its outcome (a censored one's bound is evidence too); one without a
        stiffness counts where it was aimed, so the learner never asks for that spot again."""
        if stiffness_n_per_mm is None and target_xy_mm is not None:
            xy_mm = target_xy_mm
        before = self.learner.obs.n
        self.learner.observe((xy_mm[0] - self.cx, xy_mm[1] - self.cy), stiffness_n_per_mm, sd_n_per_mm,
                             outcome=outcome, bound_n_per_mm=bound_n_per_mm)
        if self.learner.obs.n > before and stiffness_n_per_mm is not None:  # a stiffness point (not a bound)
            self.xy_mm.append((float(xy_mm[0]), float(xy_mm[1])))
            self.k_n_per_mm.append(float(stiffness_n_per_mm))

    def next_probe(self) -> tuple[float, float] | None:
        """Where the learner wants to palpate next (tissue frame), or None once sure enough or out of budget."""
        seen = self.learner.points
        if self._next is None or self._next[0] != seen:
            xy = self.learner.next_probe(self.max_palpations)
            self._next = (seen, None if xy is None else (float(xy[0]) + self.cx, float(xy[1]) + self.cy))
        return self._next[1]

    def estimate(self) -> dict:
        """Fields of the bus `estimate` event."""
        return {"points": len(self.k_n_per_mm), "lumps": [self._shifted(lump.as_dict()) for lump in self.learner.lumps()],
                "next_probe_mm": self.next_probe() if self.plans else None,
                "ambiguous_area_mm2": self.learner.ambiguous_area_mm2(), "model": self.learner.model()}

    def posterior_map(self, max_cells_per_side: int = MAP_CELLS_PER_SIDE) -> dict | None:
        """The learner's posterior on (at most) a max × max subgrid, tissue frame: reply.estimate.get's `map`,
        what the live view and `palpctl plot` draw. None before the first stiffness point."""
        grid = posterior_grid(self.learner, max_cells_per_side)
        if grid is None:
            return None
        grid["xs_mm"] = [round(x + self.cx, 3) for x in grid["xs_mm"]]
        grid["ys_mm"] = [round(y + self.cy, 3) for y in grid["ys_mm"]]
        return grid

    def _shifted(self, lump: dict) -> dict:
        x, y = lump["center_mm"]
        lump["center_mm"] = [round(x + self.cx, 3), round(y + self.cy, 3)]
        lump["boundary_mm"] = [[round(bx + self.cx, 3), round(by + self.cy, 3)] for bx, by in lump["boundary_mm"]]
        return lump


class LearnerPlan:
    """The active strategy: palpate where the session's learner says, until its stopping rule or the budget.

    It only asks: the scan job feeds the same learner each palpation once it is journaled.
    """

    def __init__(self, estimator: LearnerEstimator) -> None:
        self.estimator = estimator
        self.expected_total = estimator.max_palpations

    def next_probe(self):
        return self.estimator.next_probe()

    def observe(self, probe) -> None:
        """Nothing: the job observes the journaled entry into the estimator (one learner, fed once)."""


def make_estimator(settings, scan: dict | None, tissue_size_mm) -> LearnerEstimator:
    """The estimator of a session's scan (None: no scan yet, the whole tissue). `settings`: the scan's own."""
    scan = scan or {}
    size = scan.get("size_mm") or tissue_size_mm
    budget = scan.get("max_palpations") or settings.learner.max_palpations
    if scan.get("palpation") == "sliding":
        budget = math.inf  # the budget counts paths (palpd.slide.PathPlan); readings are many per path
    return LearnerEstimator(settings, scan.get("center_mm") or (0.0, 0.0), size, budget, scan.get("seed") or 0,
                            plans=scan.get("strategy", "active") == "active")
