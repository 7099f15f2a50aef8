"""What one palpation found: a stiffness, a bound, or a named reason why not, always where it was aimed.

`judge` turns a finished palpation record into a Probe. A palpation that reached the force limit before
it gave a stiffness, or with one too uncertain to say more than the bound (BOUND_OVER_FIT_REL_SD), is
`too_stiff`, a censored reading: the stiffness is at least the force reached over the deepest indentation (plus
two encoder steps, so the bound never overstates it); one that pressed to full
depth with no force rising out of the noise is `too_soft`: at most that force (plus three noise sds) over
that depth, or, when the threshold never fired all the way down yet the trace shows a rise too faint to fit,
at most the threshold over the depth reached below the nominal surface. Neither is missing data: the learner takes them as bounds.
"""
from __future__ import annotations

from dataclasses import dataclass

from palpd.control.palpation import MIN_SLOPE_DEPTH_MM, PalpationRecord
from palpd.stiffness import FitRejected, StiffnessResult
from palpd.stiffness.palpation import fit_palpation

DEPTH_RESOLUTION_MM = 0.05  # two encoder steps at the tip (~23 µm each)
# A press the force limit stopped short of the reference depth gives its stiffness there only by extrapolating its
# fit; beyond this relative sd the fit says less than the bound the press gives for sure (force over depth), and
# the bound is the reading. The learner gives a bound a log sd of 0.25 where it weighs it as a value
# (learner.model.CENSORED_SD), a fit its relative sd: past this they trade places. Kept as fits, a 50 N/mm lump
# in 0.12 N/mm tissue read 91.8 ± 201 and 72.9 ± 202 N/mm, readings as likely under plain tissue, and the scan
# said "no lump" at weight 1.000; a 15 N/mm one in 5 N/mm tissue, 16.2 ± 11.7 and 15.3 ± 9.1, the same.
BOUND_OVER_FIT_REL_SD = 0.25
NO_FIT = ("too_few_samples", "no_range", "no_rise", "constant_force", "not_converged")


@dataclass
class Probe:
    """One palpation, where it was aimed, with its outcome (DESIGN.md `probes[].outcome`): `fit`, `no_contact`,
    `too_stiff` (k ≥ stiffness_bound_n_per_mm: the force limit came first), `too_soft` (k ≤ the bound: the
    press stayed within the force resolution) or `rejected` (the reason in `rejected`)."""

    record: PalpationRecord
    fit: StiffnessResult | None
    rejected: str | None = None
    outcome: str = "fit"
    stiffness_bound_n_per_mm: float | None = None
    presses: int = 1  # 2 when a too_stiff press was repeated gently (palpation.too_stiff = "repalpate")

    @property
    def stiffness_n_per_mm(self) -> float | None:
        return self.fit.stiffness_n_per_mm if self.fit else None

    def as_dict(self) -> dict:
        rec = self.record
        out = {"target_xy_mm": _mm(rec.target_xy_mm), "xy_mm": _mm(rec.xy_mm), "outcome": self.outcome,
               "stiffness_n_per_mm": None if self.fit is None else round(self.fit.stiffness_n_per_mm, 5),
               "max_force_n": round(rec.max_force_n, 4), "stop_reason": rec.stop_reason,
               "contact_threshold_n": round(rec.contact_on_n, 4), "dropped_samples": rec.dropped_samples,
               "presses": self.presses}
        if rec.contact:
            out["contact_xy_mm"] = _mm(rec.xy_mm)
        if self.fit is not None:
            out["stiffness_se_n_per_mm"] = round(self.fit.stiffness_se_n_per_mm, 6)
            out["stiffness_model"] = self.fit.model
            out["samples"] = self.fit.samples  # a StiffnessResult or a sliding point
        if self.stiffness_bound_n_per_mm is not None:
            out["stiffness_bound_n_per_mm"] = round(self.stiffness_bound_n_per_mm, 5)
        if self.rejected is not None:
            out["rejected"] = self.rejected
        return out


def _mm(xy) -> list[float]:
    return [round(float(v), 3) for v in xy]


def judge(record: PalpationRecord, settings) -> Probe:
    """settings: palpd.config.Settings. The fit, or the outcome that says why there is none."""
    if not record.contact:
        return Probe(record, None, "no contact found within the approach", "no_contact")
    if record.stop_reason == "no_contact" and record.onset_spread_mm > max(record.depth_mm, default=0.0):
        # No threshold fired and the rise found in the approach could begin anywhere over more than the depth
        # pressed after it: its slope is the noise's (0.005 N/mm tissue under 0.24 N of noise read 0.095 ±
        # 0.030 from the last 1.8 mm of a 15 mm approach, the onset as plausible anywhere over 5 mm).
        return _too_soft_in_approach(record, f"a rise too faint to place: its onset as likely anywhere over "
                                             f"{record.onset_spread_mm:.1f} mm")
    if record.rebounded:  # its trace is impacts, not a press: no slope in it (palpd.control.palpation)
        return _too_stiff(record, f"the tip bounced off it at {record.max_force_n:.1f} N, "
                                  f"{max(record.depth_mm, default=0.0):.3f} mm in")
    try:
        varying = settings.palpation.speed_profile == "varying"
        fit = fit_palpation(record, settings.stiffness, settings.servo.rate_hz, varying)
    except FitRejected as exc:
        return _unfitted(record, exc)
    deepest_mm = max(record.depth_mm, default=0.0)
    if record.stop_reason == "force" and deepest_mm < MIN_SLOPE_DEPTH_MM:
        return _too_stiff(record, f"force limit {deepest_mm:.3f} mm in, under the {MIN_SLOPE_DEPTH_MM} mm a slope needs")
    if record.stop_reason == "force" and fit.stiffness_se_n_per_mm > BOUND_OVER_FIT_REL_SD * fit.stiffness_n_per_mm:
        return _too_stiff(record, f"force limit {deepest_mm:.3f} mm in: its fit, {fit.stiffness_n_per_mm:.3g} ± "
                                  f"{fit.stiffness_se_n_per_mm:.2g} N/mm, says less than the bound")
    return Probe(record, fit)


def _too_stiff(record: PalpationRecord, why: str) -> Probe:
    bound = record.max_force_n / (max(record.depth_mm, default=0.0) + DEPTH_RESOLUTION_MM)
    return Probe(record, None, f"force limit before a stiffness ({why})", "too_stiff", bound)


def _too_soft_in_approach(record: PalpationRecord, why: str) -> Probe:
    """The threshold never fired all the way down: at most the threshold over the depth reached below the
    nominal surface."""
    bound = record.contact_on_n / max(-record.lowest_z_mm, DEPTH_RESOLUTION_MM)
    return Probe(record, None, f"no force reached the contact threshold down to the margin ({why})", "too_soft", bound)


def _unfitted(record: PalpationRecord, exc: FitRejected) -> Probe:
    deepest_mm = max(record.depth_mm, default=0.0)
    if record.stop_reason == "no_contact":  # the threshold never fired all the way down, and no rise fits
        return _too_soft_in_approach(record, str(exc))
    if exc.reason in NO_FIT and record.stop_reason == "force":
        return _too_stiff(record, str(exc))
    if exc.reason in ("no_rise", "constant_force") and record.stop_reason in ("depth", "floor") and deepest_mm > 0:
        resolution_n = 3.0 * (record.noise_sd_n or 0.0)
        bound = (max(record.max_force_n, 0.0) + resolution_n) / deepest_mm
        return Probe(record, None, f"no force above the noise at full depth ({exc})", "too_soft", bound)
    return Probe(record, None, str(exc), "rejected")
