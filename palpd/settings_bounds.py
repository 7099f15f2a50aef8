"""Sane limits of every safety and timing setting, each with the reason a user reads when refused.

The pydantic models in palpd.config say what type a setting has; this table says how far it may go and why,
so `safety.max_tick_gap_s = 1000` is refused with "at most 0.1 s; a longer gap is no longer servo control"
instead of being accepted (or refused without a reason). A new limit is one row. The table is checked on the
raw values before the models validate them, so its reason wins over a model's bare "less than or equal".
Rules between settings (an inverted workspace, a window shorter than a period) follow in CONSISTENCY.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Bound:
    high: float
    unit: str
    why: str
    low: float = 0.0  # exclusive: every bounded setting is a positive duration, speed, force or distance
    low_inclusive: bool = False

    def problem(self, value: float) -> str | None:
        if not math.isfinite(value):
            return "must be a finite number"
        if value > self.high:
            return f"at most {self.high:g} {self.unit}; {self.why}"
        if value < self.low or (value == self.low and not self.low_inclusive):
            return f"must be {'at least' if self.low_inclusive else 'above'} {self.low:g} {self.unit}"
        return None


TIMEOUT_REASON = "a device silent for longer is unplugged or hung, and the loop must say so"
BOUNDS: dict[str, Bound] = {
    "robot.current_limit_a": Bound(5.5, "A", "the Maxon RE25's stall current"),
    "robot.hold_after_s": Bound(0.05, "s", "the bridge keeps the last current until then, and an arm driven that "
                                           "long without its host is a runaway", low=0.0005, low_inclusive=True),
    "robot.hold_ramp_s": Bound(0.1, "s", "the currents must reach the gravity hold while the arm is still where "
                                         "its host left it", low=0.0005, low_inclusive=True),
    "robot.watchdog_s": Bound(60.0, "s", "an arm floating in the gravity hold longer than that without its host "
                                         "is left unattended", low=0.002, low_inclusive=True),
    "robot.timeout_s": Bound(0.1, "s", "the servo loop waits this long for each reply, and a longer wait is a "
                                       "loop stall (safety.max_tick_gap_s is at most 0.1 s)"),
    "sensor.timeout_s": Bound(1.0, "s", TIMEOUT_REASON),
    "sensor.stale_after_s": Bound(0.1, "s", "an older force reading no longer describes the contact"),
    "servo.rate_hz": Bound(4000.0, "Hz", "the bridge exchanges at most one frame every 250 us", low=100.0,
                           low_inclusive=True),
    "palpation.speed_mm_s": Bound(100.0, "mm/s", "a faster indentation is an impact, not a palpation"),
    "palpation.approach_speed_mm_s": Bound(100.0, "mm/s", "the probe must be able to stop at first contact"),
    "palpation.travel_speed_mm_s": Bound(300.0, "mm/s", "travel stays well below safety.max_tip_speed_mm_s's bound"),
    "palpation.hold_s": Bound(60.0, "s", "a longer hold is a creep test, not a palpation", low_inclusive=True),
    "palpation.sliding_speed_mm_s": Bound(50.0, "mm/s", "a faster slide drags and shears the tissue"),
    "palpation.modulation_hz": Bound(20.0, "Hz", "the servo must trace each cycle with enough samples to fit it"),
    "palpation.contact_filter_s": Bound(0.1, "s", "a slower filter finds contact millimetres late at the approach speed",
                                        low_inclusive=True),
    "safety.force_cap_n": Bound(8.5, "N", "the Phantom Premium 1.5A's peak tip force: a higher cap never trips"),
    "safety.max_lateral_force_n": Bound(8.5, "N", "the Phantom Premium 1.5A's peak tip force: a higher limit "
                                                  "never trips"),
    "safety.workspace_margin_mm": Bound(50.0, "mm", "the box guards the tissue, not the whole reach of the arm",
                                        low_inclusive=True),
    "safety.max_tip_speed_mm_s": Bound(1000.0, "mm/s", "over twice the fastest move palpd commands: a higher "
                                                       "limit lets a runaway arm go unnoticed"),
    "safety.joint_limit_margin_rad": Bound(0.5, "rad", "a wider margin leaves little of the joint's range",
                                           low_inclusive=True),
    "safety.max_joint_speed_rad_s": Bound(50.0, "rad/s", "an encoder step faster than that is a glitch, whatever "
                                                         "the arm does"),
    "safety.max_sample_age_s": Bound(0.05, "s", "an older force reading no longer describes the contact (the "
                                                "probe moves 0.5 mm in 50 ms at 10 mm/s)"),
    "safety.max_tick_gap_s": Bound(0.1, "s", "a longer gap is no longer servo control"),
    "safety.late_budget_s": Bound(1.0, "s", "more lateness than that within a second is no longer servo control"),
    "safety.rigid_window_s": Bound(1.0, "s", "pressing at the cap on something rigid for longer hurts what is pressed"),
    "safety.max_tracking_error_mm": Bound(30.0, "mm", "a tip further than that from where it is sent is not under "
                                                      "control (the tissue is 40 mm across)"),
    "safety.tracking_window_s": Bound(1.0, "s", "an arm that cannot follow for longer is not under control"),
    "safety.retract_speed_mm_s": Bound(200.0, "mm/s", "a controlled stop backs out gently"),
    "safety.retract_timeout_s": Bound(5.0, "s", "a stop that takes longer is no controlled stop"),
    "safety.frozen_window_s": Bound(0.02, "s", "the force cap is blind while the sensor is frozen"),
    "safety.drift_window_s": Bound(0.5, "s", "older readings describe an older zero"),
    "safety.drift_retare_n": Bound(0.5, "N", "a zero further off than that is no drift to correct quietly"),
    "safety.drift_fault_n": Bound(2.0, "N", "a zero that moved more between two palpations is a broken sensor"),
    "safety.force_mismatch_n": Bound(2.0, "N", "a sensor further off than that from the motors' push lets the tissue "
                                               "take the cap unseen"),
    "safety.force_mismatch_window_s": Bound(0.1, "s", "a drift of 20 N/s is 2 N off in that time"),
    "safety.indentation_margin_mm": Bound(3.0, "mm", "deeper than that beyond the palpation depth is no longer "
                                                     "the press that was asked for"),
    "daemon.stop_timeout_s": Bound(15.0, "s", "systemd kills palpd after TimeoutStopSec (20 s in palpd.service), "
                                              "mid-palpation"),
    "daemon.status_interval_s": Bound(1.0, "s", "a subscriber joining at any time must have the status within "
                                                "a second", low=0.05, low_inclusive=True),
}


def bound_problem(data: dict) -> tuple[str, str] | None:
    """(dotted key, problem) for the first raw value outside its bound; values that are not numbers are left
    to the models (they say what type is expected)."""
    for dotted, bound in BOUNDS.items():
        section, key = dotted.split(".")
        value = data.get(section, {}).get(key) if isinstance(data.get(section), dict) else None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            problem = bound.problem(float(value))
            if problem:
                return dotted, f"{dotted} = {value}: {problem}"
    return None


def _workspace_z(s) -> str | None:
    low, high = s.safety.workspace_z_mm
    if low >= high:
        return f"safety.workspace_z_mm {list(s.safety.workspace_z_mm)} is inverted: [below, above] the surface"
    if low > -s.palpation.depth_mm:
        return (f"safety.workspace_z_mm starts at {low:g} mm, above the palpation depth "
                f"(palpation.depth_mm = {s.palpation.depth_mm:g}): every palpation would leave the workspace")
    if high < s.palpation.clearance_mm:
        return (f"safety.workspace_z_mm ends at {high:g} mm, below palpation.clearance_mm "
                f"({s.palpation.clearance_mm:g} mm): the probe could not travel between palpations")
    return None


def _speeds(s) -> str | None:
    limit = s.safety.max_tip_speed_mm_s
    for name in ("palpation.speed_mm_s", "palpation.approach_speed_mm_s", "palpation.travel_speed_mm_s",
                 "palpation.sliding_speed_mm_s", "safety.retract_speed_mm_s"):
        section, key = name.split(".")
        speed = getattr(getattr(s, section), key)
        if speed >= limit:
            return (f"{name} = {speed:g} is not below safety.max_tip_speed_mm_s ({limit:g} mm/s): every such move "
                    "would stop the robot")
    return None


def _velocity_filter(s) -> str | None:
    if s.control.velocity_filter_hz >= s.servo.rate_hz / 2:
        return (f"control.velocity_filter_hz = {s.control.velocity_filter_hz:g} must be below half of "
                f"servo.rate_hz ({s.servo.rate_hz:g} Hz): a filter above the Nyquist rate filters nothing")
    return None


def _sensor_health(s) -> str | None:
    safety, period_s = s.safety, 1.0 / s.servo.rate_hz
    if safety.frozen_window_s < 2 * period_s:
        return (f"safety.frozen_window_s = {safety.frozen_window_s:g} s is shorter than two servo periods "
                f"(servo.rate_hz = {s.servo.rate_hz:g}): a reading repeats once whenever a tick comes early")
    if safety.drift_retare_n >= safety.drift_fault_n:
        return (f"safety.drift_retare_n ({safety.drift_retare_n:g} N) must be below safety.drift_fault_n "
                f"({safety.drift_fault_n:g} N): re-tare small drift, fault on large")
    if safety.drift_retare_n >= s.palpation.contact_on_n:
        return (f"safety.drift_retare_n ({safety.drift_retare_n:g} N) must be below palpation.contact_on_n "
                f"({s.palpation.contact_on_n:g} N): a drift left uncorrected would read as contact")
    return None


def _sample_age(s) -> str | None:
    if s.safety.max_sample_age_s < 1.0 / s.servo.rate_hz:
        return (f"safety.max_sample_age_s = {s.safety.max_sample_age_s:g} s is shorter than one servo period "
                f"(servo.rate_hz = {s.servo.rate_hz:g}): every sample would be stale")
    return None


# (the setting the rule is about, the rule): the problem names every setting involved.
CONSISTENCY = (("safety.workspace_z_mm", _workspace_z), ("safety.max_tip_speed_mm_s", _speeds),
               ("control.velocity_filter_hz", _velocity_filter),
               ("safety.max_sample_age_s", _sample_age), ("safety.drift_retare_n", _sensor_health))


def consistency_problem(settings) -> tuple[str, str] | None:
    """(dotted key, one line naming the fields) for the first rule between settings that does not hold."""
    for dotted, rule in CONSISTENCY:
        problem = rule(settings)
        if problem:
            return dotted, problem
    return None
