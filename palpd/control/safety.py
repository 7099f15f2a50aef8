"""The safety supervisor: every tick, before any command is written, decide whether to stop."""
from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.interfaces import (
    SAMPLE_INVALID, SAMPLE_SATURATED, SAMPLE_STALE, STATUS_AMPLIFIER_FAULT, STATUS_ESTOP,
    STATUS_OVER_TEMPERATURE, STATUS_WATCHDOG_TRIPPED,
)

_STATUS_FAULTS = (
    (STATUS_ESTOP, "estop", "e-stop pressed"),
    (STATUS_AMPLIFIER_FAULT, "amplifier_fault", "amplifier fault reported by the robot"),
    (STATUS_WATCHDOG_TRIPPED, "watchdog", "robot watchdog tripped"),
    (STATUS_OVER_TEMPERATURE, "over_temperature", "motor over-temperature reported by the robot"),
)


@dataclass(frozen=True, slots=True)
class Fault:
    code: str
    message: str
    t_s: float

    def as_dict(self) -> dict:
        return {"code": self.code, "message": self.message, "t_s": round(self.t_s, 4)}


class SafetySupervisor:
    def __init__(self, settings, tissue_size_mm: tuple[float, float], home_mm=(0.0, 0.0, 0.0)) -> None:
        """The workspace box spans the tissue plus a margin, stretched to take in the arm's home."""
        self.force_cap_n = settings.force_cap_n
        self.max_speed = settings.max_tip_speed_mm_s
        margin = settings.workspace_margin_mm
        half_x, half_y = tissue_size_mm[0] / 2 + margin, tissue_size_mm[1] / 2 + margin
        self.x_range = (min(-half_x, home_mm[0] - margin), max(half_x, home_mm[0] + margin))
        self.y_range = (min(-half_y, home_mm[1] - margin), max(half_y, home_mm[1] + margin))
        z_low, z_high = settings.workspace_z_mm
        self.z_range = (z_low, max(z_high, home_mm[2] + margin))

    def check(self, tick) -> Fault | None:
        """The first reason to stop at this tick, or None."""
        for bit, code, message in _STATUS_FAULTS:
            if tick.status & bit:
                return Fault(code, message, tick.t_s)
        flags = tick.sample.flags
        if flags & (SAMPLE_INVALID | SAMPLE_STALE) or not all(map(math.isfinite, tick.force_tissue_n)):
            return Fault("invalid_sample", "force sample invalid or stale", tick.t_s)
        if flags & SAMPLE_SATURATED:
            return Fault("saturated", "force sensor saturated", tick.t_s)
        force = math.sqrt(sum(f * f for f in tick.force_tissue_n))
        if force > self.force_cap_n:
            return Fault("force_cap", f"contact force {force:.2f} N above the cap of {self.force_cap_n} N", tick.t_s)
        x, y, z = tick.tip_mm
        if not (_within(x, self.x_range) and _within(y, self.y_range) and _within(z, self.z_range)):
            return Fault("workspace", f"tip at ({x:.1f}, {y:.1f}, {z:.1f}) mm left the workspace box", tick.t_s)
        speed = math.sqrt(sum(v * v for v in tick.velocity_mm_s))
        if speed > self.max_speed:
            return Fault("speed", f"tip speed {speed:.0f} mm/s above the limit of {self.max_speed} mm/s", tick.t_s)
        return None


def _within(value: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] <= value <= bounds[1]
