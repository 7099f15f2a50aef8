"""ActivePlanner: the learner behind the scan's planner protocol (next_probe / observe / expected_total)."""
from __future__ import annotations

from palpd.learner.model import Learner

TRAVEL_OVERHEAD_S = 0.25  # settling and the tare-free transitions around each palpation


def palpation_time_s(palpation) -> float:
    """Rough robot time of one palpation, so travel can be weighed in palpations."""
    approach = 2.0 * palpation.clearance_mm / palpation.approach_speed_mm_s
    indent = 2.0 * palpation.depth_mm / palpation.speed_mm_s
    return approach + indent + palpation.hold_s + TRAVEL_OVERHEAD_S


class ActivePlanner:
    """Asks the learner where to go and tells it what each palpation found."""

    def __init__(self, size_mm, settings, max_palpations: int, seed: int = 0) -> None:
        p = settings.palpation
        self.max_palpations = max_palpations
        self.expected_total = max_palpations
        self.learner = Learner(size_mm, settings.learner, settings.scan.min_contrast, seed,
                               travel_mm_per_palpation=p.travel_speed_mm_s * palpation_time_s(p))

    def next_probe(self) -> tuple[float, float] | None:
        return self.learner.next_probe(self.max_palpations)

    def observe(self, probe) -> None:
        fit = probe.fit
        self.learner.observe(probe.record.xy_mm, None if fit is None else fit.stiffness_n_per_mm,
                             0.0 if fit is None else fit.stiffness_se_n_per_mm)

    def lumps(self) -> list:
        return self.learner.lumps()
