"""The safety supervisor: every tick, before any command is written, decide whether to stop, and how.

Checks run in order and the first fault wins; each is a method taking the tick
and returning a Fault or None, listed in `checks` (a new check is one more
method and one more entry). Every limit is in seconds or in physical units,
never in ticks, so the same settings hold at any rate and on a late host.

Each fault code has its stop category (IEC 60204-1), `stop_category(code)`:
category 0 (cut the current now) only where the amplifiers, the encoders or the
e-stop demand it; every other fault is a category-1 stop, which the servo loop
carries out (retract along the tissue normal, hold, park, power off).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from drivers.interfaces import (
    SAMPLE_INVALID, SAMPLE_SATURATED, SAMPLE_STALE, STATUS_AMPLIFIER_FAULT, STATUS_ESTOP,
    STATUS_OVER_TEMPERATURE, STATUS_WATCHDOG_TRIPPED,
)
from drivers.phantom import model
from palpd.control.limits import workspace_box_mm

_STATUS_FAULTS = (
    (STATUS_ESTOP, "estop", "e-stop pressed"),
    (STATUS_AMPLIFIER_FAULT, "amplifier_fault", "amplifier fault reported by the robot"),
    (STATUS_WATCHDOG_TRIPPED, "watchdog", "robot watchdog tripped"),
    (STATUS_OVER_TEMPERATURE, "over_temperature", "motor over-temperature reported by the robot"),
)
_FAULT_BITS = sum(bit for bit, _, _ in _STATUS_FAULTS)
# Faults after which the arm cannot be moved safely: the current goes at once (stop category 0). A robot
# link that stopped answering leaves nothing to command; the bridge's watchdog holds and then cuts.
CATEGORY_0 = frozenset({"estop", "amplifier_fault", "watchdog", "over_temperature", "encoder_jump", "robot_link"})
RIGID_FORCE_FRACTION = 0.9  # measured force at least this share of the cap...
RIGID_STILL_MM = 0.25  # ...with the tip within this of where it was, for rigid_window_s: pushing on something rigid
LATE_MEMORY_S = 1.0  # lateness is remembered over about this long (an exponential window)
WIDEN_MM, WIDEN_RAD = 5.0, 0.05  # slack around a pose accepted as inside the limits (recovering from it)


def stop_category(code: str) -> int:
    """0: cut the current at once; 1: retract, hold, park at the rest pose, then power off."""
    return 0 if code in CATEGORY_0 else 1


@dataclass(frozen=True, slots=True)
class Fault:
    code: str
    message: str
    t_s: float
    last_samples: tuple = field(default=(), compare=False)  # (t_s, tip_mm, force_tissue_n) before the fault
    stop: str = field(default="", compare=False)  # how the stop it caused ended

    @property
    def category(self) -> int:
        return stop_category(self.code)

    def as_dict(self) -> dict:
        return {"code": self.code, "message": self.message, "t_s": round(self.t_s, 4), "stop_category": self.category,
                "stop": self.stop,
                "last_samples": [{"t_s": round(t, 4), "tip_mm": [round(v, 3) for v in tip],
                                  "force_n": [round(v, 4) if math.isfinite(v) else None for v in force]}
                                 for t, tip, force in self.last_samples]}


class SafetySupervisor:
    def __init__(self, settings, tissue_size_mm: tuple[float, float], home_mm=(0.0, 0.0, 0.0),
                 period_s: float = 0.001) -> None:
        """settings: palpd.config.SafetySettings; the workspace box spans the tissue and the arm's home."""
        self.s = settings
        self.period_s = period_s
        margin = settings.joint_limit_margin_rad
        self.joint_ranges = tuple((low + margin, high - margin) for low, high in model.JOINT_LIMITS_RAD)
        self.box_mm = workspace_box_mm(settings, tissue_size_mm, home_mm)
        # The category-0 checks first; the encoder check also keeps the previous pose, so it must see every tick.
        self.checks = [self._device, self._encoders, self._stall, self._sample, self._force, self._lateral, self._rigid,
                       self._limits, self._speed, self._tracking]
        self.category_0_checks = [self._device, self._encoders]
        self._limits_now = (self.joint_ranges, self.box_mm)
        self.monitors: list = []  # more checks with check(tick) and reset() (palpd.control.health.SensorHealth)
        self.reset()

    def reset(self) -> None:
        """Forget the past: after a pause, a reset, or a move by hand while the motors were off."""
        self._previous_q = None
        self._late_s = 0.0
        self._rigid_since: float | None = None
        self._rigid_at = (0.0, 0.0, 0.0)
        self._astray_since: float | None = None
        self._recovering(False)
        for monitor in self.monitors:
            monitor.reset()

    def add_monitor(self, monitor) -> None:
        """One more category-1 check, after the sample checks (a monitor judges readings already found sound)."""
        self.monitors.append(monitor)
        self.checks.insert(self.checks.index(self._sample) + 1, monitor.check)
        monitor.reset()

    def check(self, tick) -> Fault | None:
        """The first reason to stop at this tick, or None."""
        for check in self.checks:
            fault = check(tick)
            if fault is not None:
                return fault
        return None

    def check_category_0(self, tick) -> Fault | None:
        """Only what demands the current off now: what still matters during a stop or with the motors off."""
        return self._device(tick) or self._encoders(tick)

    def check_device(self, tick) -> Fault | None:
        return self._device(tick)

    def narrow(self) -> None:
        """Back to the configured limits after widen_to()."""
        self._recovering(False)

    def _recovering(self, on: bool) -> None:
        """Monitors that judge a palpation (the sensor against the motors, the depth below the surface) stand
        aside while the arm is recovered from wherever a fault left it: it may lie in the tissue, pushed off it."""
        if not on:
            self._limits_now = (self.joint_ranges, self.box_mm)
        for monitor in self.monitors:
            monitor.recovering = on

    def guided_by_hand(self, on: bool) -> None:
        """Monitors that judge a palpation stand aside while a person moves the arm (a manual session): the
        motors push nothing there, and the hand, not the tissue, sets the force and the depth."""
        for monitor in self.monitors:
            monitor.hand_guided = on

    def widen_to(self, tick) -> None:
        """Accept the pose the arm is in now as inside the limits (recovering it from wherever it came to
        rest after a fault); reset() narrows them again."""
        (joints, box) = self._limits_now
        joints = tuple((min(lo, q - WIDEN_RAD), max(hi, q + WIDEN_RAD)) for (lo, hi), q in zip(joints, tick.q))
        box = tuple((min(lo, v - WIDEN_MM), max(hi, v + WIDEN_MM)) for (lo, hi), v in zip(box, tick.tip_mm))
        self._recovering(True)
        self._limits_now = (joints, box)

    # -- the checks, in order -------------------------------------------------------------------------
    def _device(self, tick) -> Fault | None:
        status = tick.status
        if status & _FAULT_BITS:
            for bit, code, message in _STATUS_FAULTS:
                if status & bit:
                    return Fault(code, message, tick.t_s)
        return None

    def _stall(self, tick) -> Fault | None:
        """One gap beyond max_tick_gap_s, or too many missed deadlines within about a second (jitter within
        a period is not lost time, so it never adds up to a stall)."""
        gap = tick.gap_s
        if gap > self.s.max_tick_gap_s:
            return Fault("loop_stall", f"servo loop stalled for {1000 * gap:.1f} ms "
                         f"(limit {1000 * self.s.max_tick_gap_s:.0f} ms)", tick.t_s)
        if tick.lost_s == 0.0 and self._late_s == 0.0:
            return None
        self._late_s = self._late_s * math.exp(-max(gap, self.period_s) / LATE_MEMORY_S) + tick.lost_s
        if self._late_s < 1e-6:
            self._late_s = 0.0
        if self._late_s > self.s.late_budget_s:
            return Fault("loop_stall", f"servo loop missed {1000 * self._late_s:.0f} ms of deadlines within about "
                         f"{LATE_MEMORY_S:.0f} s (budget {1000 * self.s.late_budget_s:.0f} ms)", tick.t_s)
        return None

    def _encoders(self, tick) -> Fault | None:
        q = tick.q
        previous, self._previous_q = self._previous_q, q
        if previous is None:
            return None
        allowed_rad = self.s.max_joint_speed_rad_s * self._elapsed_s(tick)
        c0, c1, c2 = model.RAD_PER_COUNT
        if abs(q[0] - previous[0]) <= allowed_rad + c0 and abs(q[1] - previous[1]) <= allowed_rad + c1 \
                and abs(q[2] - previous[2]) <= allowed_rad + c2:
            return None
        j = max(range(3), key=lambda i: abs(q[i] - previous[i]) - model.RAD_PER_COUNT[i])
        return Fault("encoder_jump", f"joint {j + 1} encoder jumped {q[j] - previous[j]:+.4f} rad in "
                     f"{1000 * tick.sample_gap_s:.1f} ms", tick.t_s)

    def _elapsed_s(self, tick) -> float:
        """The time the joints had to move since the previous sample: a late tick allows more motion, but
        never less than one period (timestamps jitter) nor more than max_tick_gap_s (beyond that the host
        gap is a loop stall, and the device's clock is not trusted further)."""
        return min(max(tick.gap_s, tick.sample_gap_s, self.period_s), self.s.max_tick_gap_s)

    def _sample(self, tick) -> Fault | None:
        sample = tick.sample
        flags = sample.flags
        fx, fy, fz = tick.force_tissue_n
        if flags & SAMPLE_INVALID or not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fz)):
            return Fault("invalid_sample", "force sample invalid (NaN or flagged)", tick.t_s)
        if flags & SAMPLE_STALE:
            return Fault("stale_sample", "force sensor gives no new readings (sensor frozen?)", tick.t_s)
        if tick.t_s - sample.t_s > self.s.max_sample_age_s:
            return Fault("stale_sample", f"force sample is {1000 * (tick.t_s - sample.t_s):.1f} ms old "
                         "(sensor frozen?)", tick.t_s)
        if flags & SAMPLE_SATURATED:
            return Fault("saturated", "force sensor saturated", tick.t_s)
        return None

    def _force(self, tick) -> Fault | None:
        force = _norm(tick.force_tissue_n)
        if force > self.s.force_cap_n:
            return Fault("force_cap", f"contact force {force:.2f} N above the cap of {self.s.force_cap_n} N", tick.t_s)
        return None

    def _lateral(self, tick) -> Fault | None:
        """Drag on a sliding probe (or a press that skids): the tissue is being sheared, stop before it tears."""
        fx, fy, _ = tick.force_tissue_n
        lateral = math.hypot(fx, fy)
        if lateral > self.s.max_lateral_force_n:
            return Fault("lateral_force", f"lateral force {lateral:.2f} N above the limit of "
                                          f"{self.s.max_lateral_force_n} N", tick.t_s)
        return None

    def _rigid(self, tick) -> Fault | None:
        """The controller at its cap, the sensor confirming it and the tip not moving over the whole window
        (by displacement, which the encoder's counts do not make flicker as a velocity would): something rigid."""
        cap = self.s.force_cap_n
        pressed = tick.commanded_n >= cap * 0.999 and _norm(tick.force_tissue_n) >= RIGID_FORCE_FRACTION * cap
        if not pressed:
            self._rigid_since = None
            return None
        if self._rigid_since is None or math.dist(tick.tip_mm, self._rigid_at) > RIGID_STILL_MM:
            self._rigid_since, self._rigid_at = tick.t_s, tick.tip_mm
        if tick.t_s - self._rigid_since >= self.s.rigid_window_s:
            return Fault("rigid_contact", f"pushing against something rigid: {_norm(tick.force_tissue_n):.2f} N "
                         f"measured at the {cap} N cap with the tip still for "
                         f"{1000 * (tick.t_s - self._rigid_since):.0f} ms", tick.t_s)
        return None

    def _limits(self, tick) -> Fault | None:
        (j0, j1, j2), (bx, by, bz) = self._limits_now
        q, (x, y, z) = tick.q, tick.tip_mm
        if not (j0[0] <= q[0] <= j0[1] and j1[0] <= q[1] <= j1[1] and j2[0] <= q[2] <= j2[1]):
            j = next(i for i, (low, high) in enumerate((j0, j1, j2)) if not low <= q[i] <= high)
            return Fault("joint_limit", f"joint {j + 1} at {q[j]:.3f} rad, near its hard stop", tick.t_s)
        if not (bx[0] <= x <= bx[1] and by[0] <= y <= by[1] and bz[0] <= z <= bz[1]):
            return Fault("workspace", f"tip at ({x:.1f}, {y:.1f}, {z:.1f}) mm left the workspace box", tick.t_s)
        return None

    def _speed(self, tick) -> Fault | None:
        speed = _norm(tick.velocity_mm_s)
        if speed > self.s.max_tip_speed_mm_s:
            return Fault("speed", f"tip speed {speed:.0f} mm/s above the limit of {self.s.max_tip_speed_mm_s} mm/s",
                         tick.t_s)
        return None

    def _tracking(self, tick) -> Fault | None:
        """The tip far from where the controller has been sending it, for longer than a transient."""
        setpoint = tick.setpoint_mm
        if setpoint is None or math.dist(setpoint, tick.tip_mm) <= self.s.max_tracking_error_mm:
            self._astray_since = None
            return None
        if self._astray_since is None:
            self._astray_since = tick.t_s
        if tick.t_s - self._astray_since >= self.s.tracking_window_s:
            return Fault("tracking_error", f"the tip is {math.dist(setpoint, tick.tip_mm):.1f} mm from its setpoint "
                         f"after {1000 * (tick.t_s - self._astray_since):.0f} ms: the controller cannot follow",
                         tick.t_s)
        return None


def _norm(v) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
