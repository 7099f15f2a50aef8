"""Sliding palpation: touch down at the start of a path, hold a set indentation modulated by a small sinusoid,
slide along the path, lift straight off at its end. The stream (position, depth, normal force) is the record;
palpd.stiffness.sliding turns it into stiffness points along the path.

Like every task, it only proposes setpoints: the servo's safety supervisor checks every tick (force cap,
lateral drag, tracking...) and a stop lifts the probe along the tissue normal before anything else moves.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from palpd.control.contact import ContactThresholds
from palpd.control.palpation import NO_CONTACT_MARGIN_MM
from palpd.control.surface import at_floor
from palpd.control.tasks import MoveTo
from palpd.control.trajectory import LinearMove

Vec3 = tuple[float, float, float]
SETTLE_CYCLES = 1.0  # modulation cycles at the start of the slide, in place, before the path begins


@dataclass
class SlidingRecord:
    start_xy_mm: tuple[float, float]
    end_xy_mm: tuple[float, float]
    contact_z_mm: float | None = None
    t_s: list[float] = field(default_factory=list)  # the sliding phase, one sample per tick
    xy_mm: list[tuple[float, float]] = field(default_factory=list)
    depth_mm: list[float] = field(default_factory=list)  # below the contact point
    force_n: list[float] = field(default_factory=list)
    max_force_n: float = 0.0
    max_lateral_n: float = 0.0
    stop_reason: str = ""


class SlidingPalpation:
    """thresholds: palpd.control.contact.ContactThresholds, scaled to the noise the tare measured (None: the
    configured floors). Contact is judged on the force low-passed like a discrete palpation's: a raw sample
    of noise above the floor, read on the way down, is not the surface (the slide would then press into air
    and lift at once for lost contact, reading nothing)."""

    def __init__(self, start_xy_mm, end_xy_mm, settings, thresholds=None) -> None:
        self.s = settings
        self.contact = thresholds or ContactThresholds(settings.contact_on_n, settings.contact_off_n,
                                                       settings.contact_filter_s)
        self._filtered_n: float | None = None
        self.record = SlidingRecord(tuple(start_xy_mm), tuple(end_xy_mm))
        self._above = (start_xy_mm[0], start_xy_mm[1], settings.clearance_mm)
        self._task = MoveTo(self._above, settings.travel_speed_mm_s, settings.accel_mm_s2)
        self._phase, self._z, self._xy = "travel", settings.clearance_mm, tuple(start_xy_mm)
        self._path: LinearMove | None = None
        self._t0 = self._last_t = 0.0
        self._winding_down = False
        self.jumped = False  # the setpoint jumped this tick (a release): the servo reads no velocity into it
        self.done = False

    def wind_down(self) -> None:
        """A stop was asked for (scan.stop, SIGTERM): lift off now, keeping what the path has read so far;
        travelling, go on to above the start and never touch down."""
        self._winding_down = True

    def step(self, tick) -> Vec3:
        dt, self._last_t = tick.motion_t_s - self._last_t, tick.motion_t_s
        self._filter(tick.normal_force_n, dt)
        if self._winding_down and self._phase in ("approach", "press", "slide"):
            self._lift("stopped")
        return getattr(self, "_" + self._phase)(tick, dt)

    def _travel(self, tick, dt) -> Vec3:
        target = self._task.step(tick)
        if self._task.done:
            self._phase = "approach"
        return target

    def _filter(self, force_n: float, dt: float) -> None:
        if self._filtered_n is None or self.contact.filter_s <= 0 or not math.isfinite(self._filtered_n):
            self._filtered_n = force_n
        else:
            self._filtered_n += (force_n - self._filtered_n) * (1.0 - math.exp(-dt / self.contact.filter_s))

    def _approach(self, tick, dt) -> Vec3:
        if self._filtered_n >= self.contact.on_n:  # the low-pass lags a rising force by its time constant:
            lag_mm = self.s.approach_speed_mm_s * self.contact.filter_s  # the surface was that much higher
            self.record.contact_z_mm, self._phase = tick.tip_mm[2] + lag_mm, "press"
            return self._setpoint()
        self._z -= self.s.approach_speed_mm_s * dt
        if self._z < -(self.s.sliding_depth_mm + NO_CONTACT_MARGIN_MM) or at_floor(tick, self.s.approach_speed_mm_s):
            self._lift("no_contact")
        return self._setpoint()

    def _press(self, tick, dt) -> Vec3:
        """Down to the set indentation at the indentation speed, then the modulation and the path begin; at
        the palpation's force limit it lifts off, as the slide does and as a discrete press stops there (on
        tissue 12 N/mm stiff the press went on past 4 N, the tip chattering on the surface, to the safety
        supervisor's 6 N cap: a force_cap fault ended the scan)."""
        goal = self.record.contact_z_mm - self.s.sliding_depth_mm
        if tick.normal_force_n >= self.s.max_force_n:
            self._lift("force", tick)
            return self._setpoint()
        if at_floor(tick, self.s.speed_mm_s):  # the contact was read late (or the sensor lies): not past the floor
            self._lift("floor")
            return self._setpoint()
        self._z = max(goal, self._z - self.s.speed_mm_s * dt)
        if self._z == goal:
            self._phase, self._t0 = "slide", tick.motion_t_s
            start, end = self.record.start_xy_mm, self.record.end_xy_mm
            self._path = LinearMove((*start, 0.0), (*end, 0.0), self.s.sliding_speed_mm_s, self.s.accel_mm_s2)
        return self._setpoint()

    def _slide(self, tick, dt) -> Vec3:
        if self._stopped_by(tick):
            return self._setpoint()
        tau = tick.motion_t_s - self._t0
        self._keep(tick)
        phase_s = tau - SETTLE_CYCLES / self.s.modulation_hz
        self._xy = self._path.at(max(0.0, phase_s))[:2]
        swing = self.s.modulation_mm * math.sin(2.0 * math.pi * self.s.modulation_hz * tau)
        self._z = self.record.contact_z_mm - (self.s.sliding_depth_mm + swing)
        if phase_s >= self._path.duration:
            self._lift("path_end")
        return self._setpoint()

    def _stopped_by(self, tick) -> bool:
        if tick.normal_force_n >= self.s.max_force_n:
            self._lift("force", tick)
        elif at_floor(tick):
            self._lift("floor")
        elif self._filtered_n < self.contact.off_n:
            self._lift("lost_contact")
        return self._phase != "slide"

    def _keep(self, tick) -> None:
        r = self.record
        r.t_s.append(tick.t_s)
        r.xy_mm.append(tick.tip_mm[:2])
        r.depth_mm.append(r.contact_z_mm - tick.tip_mm[2])
        r.force_n.append(tick.normal_force_n)
        r.max_force_n = max(r.max_force_n, tick.normal_force_n)
        r.max_lateral_n = max(r.max_lateral_n, math.hypot(*tick.force_tissue_n[:2]))

    def _lift(self, reason: str, tick=None) -> None:
        """Straight up along the normal from the setpoint: the probe leaves the tissue before it moves on. At the
        force limit the setpoint first jumps up to the tip, as a discrete press's release does
        (control.palpation): below the tip, its lead is all push on a spot too stiff to give way, and a lift
        that began there pressed on while it climbed back (5.9 N on a 12 N/mm lump, the limit 4 N)."""
        if reason == "force" and tick is not None and tick.tip_mm[2] > self._z:
            self._z, self.jumped = tick.tip_mm[2], True
        self.record.stop_reason, self._phase = reason, "retract"
        up = (*self._xy, self.s.clearance_mm)
        self._task = MoveTo(up, self.s.approach_speed_mm_s, self.s.accel_mm_s2, start=self._setpoint())

    def _retract(self, tick, dt) -> Vec3:
        target = self._task.step(tick)
        self.done = self._task.done
        return target

    def _setpoint(self) -> Vec3:
        return (self._xy[0], self._xy[1], self._z)
