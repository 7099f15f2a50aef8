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


def probe_outcome(probe) -> str:
    """The palpation's outcome as the learner takes it (DESIGN.md `probes[].outcome`)."""
    outcome = getattr(probe, "outcome", None)
    if outcome:
        return outcome
    if probe.fit is not None:
        return "fit"
    return "no_contact" if getattr(probe.record, "stop_reason", "") == "no_contact" else "rejected"


def where(probe, outcome: str) -> tuple[float, float]:
    """Where a reading was taken: the contact point of a fit, else where the palpation was aimed
    (a failed palpation's record has no contact point: it reads (0, 0))."""
    if outcome == "fit" or getattr(probe.record, "target_xy_mm", None) is None:
        return tuple(probe.record.xy_mm)
    return tuple(probe.record.target_xy_mm)


class ActivePlanner:
    """Asks the learner where to go and tells it what each palpation found, where it was aimed."""

    def __init__(self, size_mm, settings, max_palpations: int, seed: int = 0) -> None:
        self.max_palpations = max_palpations
        self.expected_total = max_palpations
        self.learner = make_learner(settings, size_mm, seed)

    def next_probe(self) -> tuple[float, float] | None:
        return self.learner.next_probe(self.max_palpations)

    def observe(self, probe) -> None:
        fit, outcome = probe.fit, probe_outcome(probe)
        self.learner.observe(where(probe, outcome), None if fit is None else fit.stiffness_n_per_mm,
                             0.0 if fit is None else fit.stiffness_se_n_per_mm, outcome=outcome,
                             bound_n_per_mm=getattr(probe, "stiffness_bound_n_per_mm", None))

    def lumps(self) -> list:
        return self.learner.lumps()

    def verdict(self) -> str:
        return self.learner.verdict()

    def model(self) -> dict | None:
        return self.learner.model()
