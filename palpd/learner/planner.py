"""ActivePlanner: the learner behind the scan's planner protocol (next_probe / observe / expected_total)."""
from __future__ import annotations

from palpd.learner.model import Learner
from palpd.learner.training import supervised_tau

TRAVEL_OVERHEAD_S = 0.25  # settling and the tare-free transitions around each palpation


def make_learner(settings, size_mm, seed: int) -> Learner:
    """The learner for these settings: travel weighed in palpations, τ supervised when a training set is given."""
    p = settings.palpation
    training_set = settings.learner.training_set
    tau = supervised_tau(training_set) if training_set else None
    return Learner(size_mm, settings.learner, settings.scan.min_contrast, seed,
                   p.travel_speed_mm_s * palpation_time_s(p), tau)


def palpation_time_s(palpation) -> float:
    """Rough robot time of one palpation, so travel can be weighed in palpations."""
    approach = 2.0 * palpation.clearance_mm / palpation.approach_speed_mm_s
    indent = 2.0 * palpation.depth_mm / palpation.speed_mm_s
    return approach + indent + palpation.hold_s + TRAVEL_OVERHEAD_S


class ActivePlanner:
    """Asks the learner where to go and tells it what each palpation found."""

    def __init__(self, size_mm, settings, max_palpations: int, seed: int = 0) -> None:
        self.max_palpations = max_palpations
        self.expected_total = max_palpations
        self.learner = make_learner(settings, size_mm, seed)

    def next_probe(self) -> tuple[float, float] | None:
        return self.learner.next_probe(self.max_palpations)

    def observe(self, probe) -> None:
        fit = probe.fit
        self.learner.observe(probe.record.xy_mm, None if fit is None else fit.stiffness_n_per_mm,
                             0.0 if fit is None else fit.stiffness_se_n_per_mm)

    def lumps(self) -> list:
        return self.learner.lumps()
