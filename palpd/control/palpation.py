"""One palpation as a state machine: above the point, approach, contact, indent, hold, retract.

Contact is detected on the bias-compensated, low-passed normal force with
hysteresis (thresholds scaled to the noise the tare measured: palpd.control.contact),
by the same segmenter that finds palpations in a hand-palpated (manual) stream,
and the record is the segment it finds, its contact point found again from the
whole trace once the palpation is over (`finish`, on the host: palpd.control.onset).
The indentation stops at the configured depth or force, whichever comes first.
A palpation is always recorded where it was aimed (`target_xy_mm`; `xy_mm` is
the contact point when there was one, else the target too).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from palpd.control.contact import ContactThresholds
from palpd.control.onset import refine
from palpd.control.segment import Segment, Segmenter
from palpd.control.surface import at_floor
from palpd.control.tasks import MoveTo

Vec3 = tuple[float, float, float]
NO_CONTACT_MARGIN_MM = 10.0  # how far below the nominal surface to look before giving up
SLOW_ZONE_MM = 2.5  # from this high above the nominal surface down, the approach goes at the indentation speed
ARM_MM = 1.5  # contact is looked for from here down: below the drift check (and re-tare) and the slowdown
LOOKBACK_S = 2.5  # the approach kept for finding the contact point again: from the slow zone to the margin
# speed_profile = "varying": the indentation speed swings between (1 - SWING) and (1 + SWING) times
# speed_mm_s, SPEED_CYCLES times over the depth, so the same depths are pressed slowly and quickly.
SPEED_SWING = 0.8
SPEED_CYCLES = 3
# A press stopped by the force limit within this depth of its contact point gives a bound, not a slope: over
# four encoder steps the contact point's own error (~0.03 mm) and the controller's lag are most of the
# depth, and a 100 N/mm lump fitted there read 20 ± 5 N/mm (0.086 mm deep); at 0.11 mm, 50 N/mm read 39 ± 15.
MIN_SLOPE_DEPTH_MM = 0.1
# On tissue that stiff the probe bounces: its few grams meet a spring of 100-200 N/mm, the contact lasts ~2 ms
# and the controller, a period late, cannot damp it. In flight the setpoint's lead (all push: the tip does not
# follow it) throws the tip down again, so each impact comes harder than the last (200 N/mm in 0.5 N/mm: 1.3,
# 1.4, 2.6, 2.3, 2.9, 5.5 N sampled one impact to the next, then 6.2 N, past the 6 N cap), while between impacts
# the 1 kHz samples read no force at all and the press went on. A press 4 times slower does it too once its push
# has grown: the still tip's encoder flickers a step, the damping kicks, and the bouncing grows. So such a press
# ends at the first rebound after an impact of REBOUND_STOP_FRACTION of max_force_n (its reading is a bound
# either way, and a gentler press would bounce too), and any press the limit stops that shallow releases at once
# (Palpation._release) instead of pushing on while its setpoint climbs back to the tip: a retract that began 1.7
# mm below the tip went on bouncing, up to 7.2 N.
REBOUND_STOP_FRACTION = 0.5
# ...where the limit would come within this fraction of MIN_SLOPE_DEPTH_MM at the impact's stiffness. Live, the
# contact point is the filtered force's, found late, so the depth seen falls short: 30 N/mm in 5 N/mm tissue
# bounced off at 2.9 N 0.07 mm below it, 0.11 mm below the one the whole trace gives (a press that reads a
# slope when repeated gently).
REBOUND_DEPTH_FRACTION = 0.5


@dataclass
class PalpationRecord:
    """The force-displacement trace of one palpation (tissue frame)."""

    target_xy_mm: tuple[float, float]
    xy_mm: tuple[float, float] | None = None  # the contact point; the target when there was none
    contact_z_mm: float | None = None
    contact: bool = False  # a contact point was found
    depth_mm: list[float] = field(default_factory=list)  # loading phase, below the contact point
    force_n: list[float] = field(default_factory=list)
    unload_depth_mm: list[float] = field(default_factory=list)
    unload_force_n: list[float] = field(default_factory=list)
    max_force_n: float = 0.0
    stop_reason: str = ""
    t_start_s: float = 0.0
    t_end_s: float = 0.0
    t_first_tick_s: float | None = None  # the task's first tick: where its segmenter began (replay starts there)
    t_armed_s: float | None = None  # when contact began to be looked for (replay arms its segmenter after it)
    dropped_samples: int = 0  # samples whose force was NaN or infinite, left out
    contact_on_n: float = 0.0  # the thresholds contact was judged by (scaled to the measured noise)
    contact_off_n: float = 0.0
    contact_filter_s: float = 0.0
    noise_sd_n: float | None = None
    lowest_z_mm: float = math.inf  # the deepest the tip went (tissue frame: the nominal surface is z = 0)
    force_lead_s: float = 0.0  # how much newer the force samples were than the tip readings (aligned for the fit)
    onset_spread_mm: float = 0.0  # the span of contact points the trace fits as well as the one found (onset.refine)
    rebounded: bool = False  # stopped as the tip bounced off tissue too stiff to press (palpation.REBOUND_*)

    def __post_init__(self) -> None:
        if self.xy_mm is None:
            self.xy_mm = tuple(self.target_xy_mm)


def palpation_segmenter(on_n: float, off_n: float, filter_s: float) -> Segmenter:
    """The segmenter of one autonomous palpation. Its zero is followed from the first sample while travelling
    (the sensor may have drifted since the tare) and read afresh when it is armed for the approach, then held:
    an approach lasts a second or two, and a zero still following there takes a slow rise for drift (0.005 N/mm
    pressed at 10 mm/s rises 0.05 N/s, which a 0.5 s follower lags by only 0.025 N: below a 0.03 N threshold,
    so contact never fired). No least press or depth: a palpation that hits the force limit early is the
    stiffest evidence there is."""
    segmenter = Segmenter(on_n, off_n, min_peak_n=0.0, min_depth_mm=0.0, filter_s=filter_s, lookback_s=LOOKBACK_S,
                          baseline_n=None, baseline_time_s=math.inf)
    segmenter.armed = False
    return segmenter


class Palpation:
    def __init__(self, xy_mm: tuple[float, float], settings, thresholds: ContactThresholds | None = None) -> None:
        self.s = settings
        th = thresholds or ContactThresholds(settings.contact_on_n, settings.contact_off_n, settings.contact_filter_s)
        self.record = PalpationRecord(tuple(xy_mm), contact_on_n=th.on_n, contact_off_n=th.off_n,
                                      noise_sd_n=th.noise_sd_n)
        self._above_point = (xy_mm[0], xy_mm[1], settings.clearance_mm)
        self._phase = "above"
        self._task = MoveTo(self._above_point, settings.travel_speed_mm_s, settings.accel_mm_s2)
        self._target_z = settings.clearance_mm
        self._last_t = None
        self._hold_until = 0.0
        # No least press or depth: a palpation that hits the force limit early is the stiffest evidence there is.
        self.segmenter = palpation_segmenter(th.on_n, th.off_n, th.filter_s)
        self.record.contact_filter_s = th.filter_s
        self._segment: Segment | None = None
        self._lowest_in_contact_mm = math.inf  # the tip's lowest and the highest force since contact
        self._peak_in_contact_n = 0.0
        self.jumped = False  # the setpoint jumped this tick (a release): the servo reads no velocity into it
        # The record is final but for the lift's own fields (`lifted`): the retract has taken the tip out of
        # the press whose segment was found, and the rest of it lifts to clearance. A servo process hands the
        # record back here (RemoteServo.begin) so the host fits it while the lift goes on.
        self.settled = False
        self.done = False

    def step(self, tick) -> Vec3:
        # Setpoints advance on the servo's tick clock: a stalled host pauses the press instead of deepening it.
        dt = 0.0 if self._last_t is None else tick.motion_t_s - self._last_t
        if self._last_t is None:
            self.record.t_first_tick_s = tick.t_s
        self._last_t = tick.motion_t_s
        self.record.lowest_z_mm = min(self.record.lowest_z_mm, tick.tip_mm[2])
        found = self.segmenter.push(tick.t_s, tick.tip_mm, tick.normal_force_n, tick.sample.t_s)
        if found is not None and not self.settled and (self._segment is None
                                                       or found.peak_force_n > self._segment.peak_force_n):
            # a brush before the press is not the palpation, nor a touch in the lift once the record is out
            self._segment = found
        return getattr(self, "_" + self._phase)(tick, dt)

    def _above(self, tick, dt) -> Vec3:
        target = self._task.step(tick)
        if self._task.done:
            self._phase, self.record.t_start_s = "approach", tick.t_s
            self.segmenter.forget()
        return target

    def _approach(self, tick, dt) -> Vec3:
        if self.segmenter.in_contact:
            self.record.contact_z_mm = self.segmenter.current.contact_z_mm
            self._phase = "indent"
            return self._indent(tick, 0.0)
        # Within SLOW_ZONE_MM of the surface the approach already moves at the indentation speed, so contact
        # begins at the speed the press goes on at: no start-up transient when the threshold fires.
        near = self._target_z <= SLOW_ZONE_MM
        if self._target_z <= ARM_MM and not self.segmenter.armed:
            # Armed here, below where the sensor's zero is checked (and re-tared) at each approach
            # (palpd.control.health), from a zero read just before: a re-tare is not a contact.
            self.segmenter.armed = True
            self.segmenter.forget()
            self.record.t_armed_s = tick.t_s
        speed = min(self.s.speed_mm_s, self.s.approach_speed_mm_s) if near else self.s.approach_speed_mm_s
        self._target_z -= speed * dt
        if self._target_z < -(self.s.depth_mm + NO_CONTACT_MARGIN_MM) or at_floor(tick, speed):
            self._start_retract(tick, "no_contact")
        return self._setpoint()

    def _indent(self, tick, dt) -> Vec3:
        depth = self._keep(tick)
        if self._rebounded(tick):
            self.record.rebounded = True
            self._start_retract(tick, "force")
            return self._setpoint()
        if depth >= self.s.depth_mm or tick.normal_force_n >= self.s.max_force_n or at_floor(tick, self._speed_cap()):
            reason = "depth" if depth >= self.s.depth_mm else "force" if tick.normal_force_n >= self.s.max_force_n \
                else "floor"  # short of its depth at the position bound (palpd.control.surface)
            if self.s.hold_s > 0 and not (reason == "force" and self._shallow()):
                self._phase, self._hold_until, self.record.stop_reason = "hold", tick.motion_t_s + self.s.hold_s, reason
            else:
                self._start_retract(tick, reason)
            return self._setpoint()
        self._target_z -= self._indent_speed_mm_s() * dt
        return self._setpoint()

    def _rebounded(self, tick) -> bool:
        """The tip came back up off tissue it met hard: the force fell to the release threshold after an impact
        of REBOUND_STOP_FRACTION of the force limit, at a stiffness that would meet the limit within
        REBOUND_DEPTH_FRACTION of MIN_SLOPE_DEPTH_MM. (A soft press never does this: its setpoint goes on down
        and its force up.)"""
        force, peak = tick.normal_force_n, self._peak_in_contact_n
        return (peak >= REBOUND_STOP_FRACTION * self.s.max_force_n and force <= self.record.contact_off_n
                and tick.tip_mm[2] > self._lowest_in_contact_mm
                and (self.record.contact_z_mm - self._lowest_in_contact_mm) * self.s.max_force_n
                < REBOUND_DEPTH_FRACTION * MIN_SLOPE_DEPTH_MM * peak)

    def _shallow(self) -> bool:
        """The tip has gone no deeper than MIN_SLOPE_DEPTH_MM below the contact point: a press stopped here is a bound."""
        return self.record.contact_z_mm - self._lowest_in_contact_mm < MIN_SLOPE_DEPTH_MM

    def _speed_cap(self) -> float:
        """The fastest this press goes down (a varying profile swings above its mean speed)."""
        return self.s.speed_mm_s * (1.0 + SPEED_SWING if self.s.speed_profile != "constant" else 1.0)

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
        if not self.settled and self._segment is not None and not self.segmenter.in_contact \
                and self.record.stop_reason != "no_contact":  # (a no_contact record is made at the lift's end)
            self.settled = True
        target = self._task.step(tick)
        if self._task.done:
            self.record.t_end_s = tick.t_s
            self.record.dropped_samples = self.segmenter.dropped
            if self._segment is None and self.record.stop_reason == "no_contact":
                self._segment = self._approach_segment()
            self.done = True
        return target

    def _keep(self, tick) -> float:
        self.record.max_force_n = max(self.record.max_force_n, tick.normal_force_n)
        self._lowest_in_contact_mm = min(self._lowest_in_contact_mm, tick.tip_mm[2])
        self._peak_in_contact_n = max(self._peak_in_contact_n, tick.normal_force_n)
        return self.record.contact_z_mm - tick.tip_mm[2]

    def _approach_segment(self) -> Segment | None:
        """No threshold fired all the way down: the approach itself, in case tissue too soft to reach the
        threshold was pressed after all (the onset refit tells a rise from a flat line)."""
        samples = self.segmenter.approach_samples
        if len(samples) < 8:
            return None
        seg = Segment(samples[-1][0], samples[-1][3], self.segmenter.baseline_n or 0.0, samples=samples,
                      detected_at=len(samples) - 1, force_lead_s=self.segmenter.force_lead_s)
        return seg

    def lift_end(self) -> tuple:
        """What the lift after `settled` adds to the record (and whether it ended): all the servo process
        sends back at the end of a palpation it sent back settled, not the whole task again."""
        return self.record.t_end_s, self.record.lowest_z_mm, self.segmenter.dropped, self.done

    def lifted(self, end: tuple) -> None:
        """This palpation, handed back settled, has ended (`lift_end` of its copy in the servo process). None
        of what the lift adds is read by the fit (probe.judge reads lowest_z_mm only of a no_contact record,
        which is never handed back early)."""
        rec = self.record
        rec.t_end_s, rec.lowest_z_mm, rec.dropped_samples, self.done = end

    def finish(self, refit_onset: bool = True) -> PalpationRecord:
        """The record, its contact point found again from the whole trace (host side, after the run)."""
        seg, rec = self._segment, self.record
        if seg is None:
            return rec
        if not refine(seg, refit_onset or rec.stop_reason == "no_contact") and rec.stop_reason == "no_contact":
            return rec  # an approach with no rise in it: no contact
        rec.contact, rec.contact_z_mm, rec.xy_mm = True, seg.contact_z_mm, seg.xy_mm
        rec.depth_mm, rec.force_n = seg.depth_mm, seg.force_n
        rec.unload_depth_mm, rec.unload_force_n = seg.unload_depth_mm, seg.unload_force_n
        rec.force_lead_s = seg.force_lead_s
        rec.onset_spread_mm = seg.onset_spread_mm
        rec.max_force_n = max(rec.max_force_n, seg.peak_force_n)
        return rec

    def _start_retract(self, tick, reason: str) -> None:
        self.record.stop_reason = reason
        self._phase = "retract"
        if reason == "force" and self._shallow():
            self._release()
        # From the setpoint, not the lagging tip, so the force releases smoothly.
        self._task = MoveTo(self._above_point, self.s.approach_speed_mm_s, self.s.accel_mm_s2, start=self._setpoint())

    def _release(self) -> None:
        """The setpoint up to the tip's lowest point at once: below it, the lead was all push on tissue too stiff
        to give way (MIN_SLOPE_DEPTH_MM). A jump, so the servo reads no speed into it (a kick of kd times 0.35 mm
        per tick threw the tip up and back down onto the tissue)."""
        if self._lowest_in_contact_mm > self._target_z:
            self._target_z, self.jumped = self._lowest_in_contact_mm, True

    def _setpoint(self) -> Vec3:
        return (self._above_point[0], self._above_point[1], self._target_z)
