"""One palpation as a state machine: above the point, approach, contact, indent, hold, retract.

Contact is detected on the bias-compensated normal force with hysteresis, by
the same segmenter that finds palpations in a hand-palpated (manual) stream, and
the record is the segment it finds. The indentation stops at the configured
depth or force, whichever comes first.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from palpd.control.segment import Segment, Segmenter
from palpd.control.tasks import MoveTo

Vec3 = tuple[float, float, float]
NO_CONTACT_MARGIN_MM = 10.0  # how far below the nominal surface to look before giving up
# speed_profile = "varying": the indentation speed swings between (1 - SWING) and (1 + SWING) times
# speed_mm_s, SPEED_CYCLES times over the depth, so the same depths are pressed slowly and quickly.
SPEED_SWING = 0.8
SPEED_CYCLES = 3


@dataclass
class PalpationRecord:
    """The force-displacement trace of one palpation (tissue frame)."""

    target_xy_mm: tuple[float, float]
    xy_mm: tuple[float, float] = (0.0, 0.0)
    contact_z_mm: float | None = None
    depth_mm: list[float] = field(default_factory=list)  # loading phase, below the contact point
    force_n: list[float] = field(default_factory=list)
    unload_depth_mm: list[float] = field(default_factory=list)
    unload_force_n: list[float] = field(default_factory=list)
    max_force_n: float = 0.0
    stop_reason: str = ""
    t_start_s: float = 0.0
    t_end_s: float = 0.0
    t_first_tick_s: float | None = None  # the task's first tick: where its segmenter began (replay starts there)


class Palpation:
    def __init__(self, xy_mm: tuple[float, float], settings) -> None:
        self.s = settings
        self.record = PalpationRecord(tuple(xy_mm))
        self._above_point = (xy_mm[0], xy_mm[1], settings.clearance_mm)
        self._phase = "above"
        self._task = MoveTo(self._above_point, settings.travel_speed_mm_s, settings.accel_mm_s2)
        self._target_z = settings.clearance_mm
        self._last_t = None
        self._hold_until = 0.0
        self.segmenter = Segmenter(settings.contact_on_n, settings.contact_off_n)
        self._segment: Segment | None = None
        self.done = False

    def step(self, tick) -> Vec3:
        # Setpoints advance on the servo's tick clock: a stalled host pauses the press instead of deepening it.
        dt = 0.0 if self._last_t is None else tick.motion_t_s - self._last_t
        if self._last_t is None:
            self.record.t_first_tick_s = tick.t_s
        self._last_t = tick.motion_t_s
        found = self.segmenter.push(tick.t_s, tick.tip_mm, tick.normal_force_n)
        if found is not None and self._segment is None:
            self._segment = found
        return getattr(self, "_" + self._phase)(tick, dt)

    def _above(self, tick, dt) -> Vec3:
        target = self._task.step(tick)
        if self._task.done:
            self._phase, self.record.t_start_s = "approach", tick.t_s
        return target

    def _approach(self, tick, dt) -> Vec3:
        if self.segmenter.in_contact:
            self.record.contact_z_mm = self.segmenter.current.contact_z_mm
            self._phase = "indent"
            return self._indent(tick, 0.0)
        self._target_z -= self.s.approach_speed_mm_s * dt
        if self._target_z < -(self.s.depth_mm + NO_CONTACT_MARGIN_MM):
            self._start_retract(tick, "no_contact")
        return self._setpoint()

    def _indent(self, tick, dt) -> Vec3:
        depth = self._keep(tick)
        if depth >= self.s.depth_mm or tick.normal_force_n >= self.s.max_force_n:
            reason = "depth" if depth >= self.s.depth_mm else "force"
            if self.s.hold_s > 0:
                self._phase, self._hold_until, self.record.stop_reason = "hold", tick.motion_t_s + self.s.hold_s, reason
            else:
                self._start_retract(tick, reason)
            return self._setpoint()
        self._target_z -= self._indent_speed_mm_s() * dt
        return self._setpoint()

    def _indent_speed_mm_s(self) -> float:
        """At one constant speed k·xⁿ and b·xⁿ·ẋ rise alike and a fit cannot tell them apart; a varying speed can."""
        if self.s.speed_profile == "constant":
            return self.s.speed_mm_s
        progress = (self.record.contact_z_mm - self._target_z) / self.s.depth_mm
        return self.s.speed_mm_s * (1.0 + SPEED_SWING * math.sin(2.0 * math.pi * SPEED_CYCLES * progress))

    def _hold(self, tick, dt) -> Vec3:
        if tick.motion_t_s >= self._hold_until:
            self._start_retract(tick, self.record.stop_reason)
        return self._setpoint()

    def _retract(self, tick, dt) -> Vec3:
        target = self._task.step(tick)
        if self._task.done:
            self.record.t_end_s = tick.t_s
            self._take_segment()
            self.done = True
        return target

    def _keep(self, tick) -> float:
        self.record.max_force_n = max(self.record.max_force_n, tick.normal_force_n)
        return self.record.contact_z_mm - tick.tip_mm[2]

    def _take_segment(self) -> None:
        """The loading and unloading traces, as the segmenter cut them out of the stream."""
        seg, rec = self._segment, self.record
        if seg is None:
            return
        rec.contact_z_mm, rec.xy_mm = seg.contact_z_mm, seg.xy_mm
        rec.depth_mm, rec.force_n = seg.depth_mm, seg.force_n
        rec.unload_depth_mm, rec.unload_force_n = seg.unload_depth_mm, seg.unload_force_n

    def _start_retract(self, tick, reason: str) -> None:
        self.record.stop_reason = reason
        self._phase = "retract"
        # From the setpoint, not the lagging tip, so the force releases smoothly.
        self._task = MoveTo(self._above_point, self.s.approach_speed_mm_s, self.s.accel_mm_s2, start=self._setpoint())

    def _setpoint(self) -> Vec3:
        return (self._above_point[0], self._above_point[1], self._target_z)
