"""The safety supervisor: every tick, before any command is written, decide whether to stop.

It also refuses, at start-up, a configuration that could not be made safe: a
force cap the sensor cannot measure, or a workspace the arm cannot reach.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from drivers.interfaces import (
    SAMPLE_INVALID, SAMPLE_SATURATED, SAMPLE_STALE, STATUS_AMPLIFIER_FAULT, STATUS_ESTOP,
    STATUS_OVER_TEMPERATURE, STATUS_WATCHDOG_TRIPPED,
)
from drivers.phantom import model
from palpd.errors import ConfigError

NANO17_FORCE_RANGE_N = (25.0, 25.0, 35.0)  # SI-25-0.25, when a sensor does not say its own
_STATUS_FAULTS = (
    (STATUS_ESTOP, "estop", "e-stop pressed"),
    (STATUS_AMPLIFIER_FAULT, "amplifier_fault", "amplifier fault reported by the robot"),
    (STATUS_WATCHDOG_TRIPPED, "watchdog", "robot watchdog tripped"),
    (STATUS_OVER_TEMPERATURE, "over_temperature", "motor over-temperature reported by the robot"),
)
# Faults after which the sensors, encoders and amplifiers can still be trusted to back the probe out.
RETRACTABLE = frozenset({"force_cap", "task_timeout"})


@dataclass(frozen=True, slots=True)
class Fault:
    code: str
    message: str
    t_s: float
    last_samples: tuple = field(default=(), compare=False)  # (t_s, tip_mm, force_tissue_n) before the fault

    def as_dict(self) -> dict:
        return {"code": self.code, "message": self.message, "t_s": round(self.t_s, 4),
                "last_samples": [{"t_s": round(t, 4), "tip_mm": [round(v, 3) for v in tip],
                                  "force_n": [round(v, 4) if math.isfinite(v) else None for v in force]}
                                 for t, tip, force in self.last_samples]}


class SafetySupervisor:
    def __init__(self, settings, tissue_size_mm: tuple[float, float], home_mm=(0.0, 0.0, 0.0),
                 period_s: float = 0.001) -> None:
        """The workspace box spans the tissue plus a margin, stretched to take in the arm's home."""
        self.force_cap_n = settings.force_cap_n
        self.max_speed = settings.max_tip_speed_mm_s
        self.max_sample_age_s = settings.max_sample_age_s
        self.max_tick_gap_s = settings.max_tick_gap_s
        self.max_joint_speed_rad_s = settings.max_joint_speed_rad_s
        self.period_s = period_s
        margin = settings.joint_limit_margin_rad
        self.joint_ranges = tuple((low + margin, high - margin) for low, high in model.JOINT_LIMITS_RAD)
        self.box_mm = workspace_box_mm(settings, tissue_size_mm, home_mm)
        self.monitors: list = []  # more checks with check(tick) and reset() (palpd.control.health.SensorHealth)
        self._previous_q = None

    def reset(self) -> None:
        self._previous_q = None
        for monitor in self.monitors:
            monitor.reset()

    def check(self, tick) -> Fault | None:
        """The first reason to stop at this tick, or None."""
        return (self._device(tick) or self._timing(tick) or self._sample(tick) or self._monitors(tick)
                or self._motion(tick))

    def _monitors(self, tick) -> Fault | None:
        for monitor in self.monitors:
            fault = monitor.check(tick)
            if fault is not None:
                return fault
        return None

    def check_device(self, tick) -> Fault | None:
        """Only the robot's own status bits: what still matters while the motors are off."""
        return self._device(tick)

    def _device(self, tick) -> Fault | None:
        for bit, code, message in _STATUS_FAULTS:
            if tick.status & bit:
                return Fault(code, message, tick.t_s)
        return None

    def _timing(self, tick) -> Fault | None:
        if tick.gap_s > self.max_tick_gap_s:
            return Fault("loop_stall", f"servo loop stalled for {1000 * tick.gap_s:.1f} ms", tick.t_s)
        previous, self._previous_q = self._previous_q, tick.q
        if previous is not None:
            allowed_rad = self.max_joint_speed_rad_s * self._elapsed_s(tick)
            for j in range(3):
                step = tick.q[j] - previous[j]
                if abs(step) > allowed_rad + model.RAD_PER_COUNT[j]:
                    return Fault("encoder_jump", f"joint {j + 1} encoder jumped {step:+.4f} rad in "
                                 f"{1000 * tick.sample_gap_s:.1f} ms", tick.t_s)
        return None

    def _elapsed_s(self, tick) -> float:
        """The time the joints had to move since the previous sample: a late tick allows more motion, but
        never less than one period (timestamps jitter) nor more than max_tick_gap_s (beyond that the host
        gap is a loop stall, and the device's clock is not trusted further)."""
        return min(max(tick.gap_s, tick.sample_gap_s, self.period_s), self.max_tick_gap_s)

    def _sample(self, tick) -> Fault | None:
        sample = tick.sample
        if sample.flags & SAMPLE_INVALID or not all(map(math.isfinite, tick.force_tissue_n)):
            return Fault("invalid_sample", "force sample invalid (NaN or flagged)", tick.t_s)
        if sample.flags & SAMPLE_STALE:
            return Fault("stale_sample", "force sensor gives no new readings (sensor frozen?)", tick.t_s)
        if tick.t_s - sample.t_s > self.max_sample_age_s:
            return Fault("stale_sample", f"force sample is {1000 * (tick.t_s - sample.t_s):.1f} ms old "
                         "(sensor frozen?)", tick.t_s)
        if sample.flags & SAMPLE_SATURATED:
            return Fault("saturated", "force sensor saturated", tick.t_s)
        return None

    def _motion(self, tick) -> Fault | None:
        fx, fy, fz = tick.force_tissue_n
        force = math.sqrt(fx * fx + fy * fy + fz * fz)
        if force > self.force_cap_n:
            return Fault("force_cap", f"contact force {force:.2f} N above the cap of {self.force_cap_n} N", tick.t_s)
        for j, (low, high) in enumerate(self.joint_ranges):
            if not low <= tick.q[j] <= high:
                return Fault("joint_limit", f"joint {j + 1} at {tick.q[j]:.3f} rad, near its hard stop", tick.t_s)
        if not all(low <= v <= high for v, (low, high) in zip(tick.tip_mm, self.box_mm)):
            x, y, z = tick.tip_mm
            return Fault("workspace", f"tip at ({x:.1f}, {y:.1f}, {z:.1f}) mm left the workspace box", tick.t_s)
        vx, vy, vz = tick.velocity_mm_s
        speed = math.sqrt(vx * vx + vy * vy + vz * vz)
        if speed > self.max_speed:
            return Fault("speed", f"tip speed {speed:.0f} mm/s above the limit of {self.max_speed} mm/s", tick.t_s)
        return None


def workspace_box_mm(settings, tissue_size_mm, home_mm) -> tuple[tuple[float, float], ...]:
    """(x, y, z) ranges in the tissue frame: the tissue plus a margin, the z band, and the arm's home."""
    margin = settings.workspace_margin_mm
    half_x, half_y = tissue_size_mm[0] / 2 + margin, tissue_size_mm[1] / 2 + margin
    z_low, z_high = settings.workspace_z_mm
    return ((min(-half_x, home_mm[0] - margin), max(half_x, home_mm[0] + margin)),
            (min(-half_y, home_mm[1] - margin), max(half_y, home_mm[1] + margin)),
            (z_low, max(z_high, home_mm[2] + margin)))


def refuse_unsafe_configuration(settings, frame, force_range_n=NANO17_FORCE_RANGE_N) -> None:
    """Raise ConfigError (one line) for a force cap the sensor cannot measure or a palpable area out of reach."""
    cap, weakest_axis_n = settings.safety.force_cap_n, min(force_range_n)
    if cap >= weakest_axis_n:
        raise ConfigError(f"safety.force_cap_n = {cap} N is not below the force sensor's range of "
                          f"{weakest_axis_n} N, so a harder push could not be measured")
    half_x, half_y = settings.tissue.size_mm[0] / 2, settings.tissue.size_mm[1] / 2
    z_low = max(settings.safety.workspace_z_mm[0], -settings.palpation.depth_mm)
    for x in (-half_x, half_x):
        for y in (-half_y, half_y):
            for z in (z_low, settings.palpation.clearance_mm):
                try:
                    model.inverse(frame.to_robot((x / 1000.0, y / 1000.0, z / 1000.0)))
                except model.UnreachableError as exc:
                    raise ConfigError(f"tissue.origin_mm {list(settings.tissue.origin_mm)} with size_mm "
                                      f"{list(settings.tissue.size_mm)}: corner ({x:g}, {y:g}, {z:g}) mm is "
                                      f"outside the arm's reach ({exc})") from None
