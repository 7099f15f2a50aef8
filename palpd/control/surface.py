"""Where the tissue surface is, and how deep below it the tip may go, whatever the force sensor reads.

The force sensor decides where a palpation touches and when it has pressed far enough; a sensor that reads
the tissue lighter than it is (a drifting zero) would let it press on and on. So depth is bounded by position
too: the surface starts where the tissue was registered (z = 0 in the tissue frame) and is refined by each
palpation's contact point once that palpation has ended without a fault (never by the press under way: its own
reading is the one in doubt). The floor at a point is that surface less the deepest indentation any palpation
asks for (palpation.depth_mm, or a slide's depth and swing) less `safety.indentation_margin_mm`. A task ends
its press when the tip, or where its setpoint would bring the tip to rest, comes within FLOOR_CLEARANCE_MM of
the floor, as at its depth, and the tip below the floor is an `indentation` fault (category 1: the probe backs
out along the normal).
"""
from __future__ import annotations

import math

from palpd.control.safety import Fault

NEAR_MM = 15.0  # a contact point this close says where the surface is; farther, the registration does
FLOOR_CLEARANCE_MM = 0.25  # a task stops pressing this far above the floor: the tip's overshoot stays above it
STOPPING_S = 0.012  # a tip pressed at v comes to rest about v times this past its stopped setpoint (measured
#                     on a soft 3-D layer: 0.38 mm from 40 mm/s), so a press at v ends that much earlier
NO_FLOOR = -math.inf
HELD_NOISE_SDS = 3.0  # the push counted as holding the tip is the normal force less this many sds of the sensor's noise


def deepest_press_mm(palpation) -> float:
    """How far below the surface a palpation may ask to go: a press's depth or a slide's depth and swing."""
    return max(palpation.depth_mm, palpation.sliding_depth_mm + palpation.modulation_mm)


def at_floor(tick, speed_mm_s: float = 0.0) -> bool:
    """The tip has come as deep as a task moving it down at speed_mm_s may take it here, or its setpoint would
    bring it there: the press ends, as at its depth. The tip goes where its setpoint is, less the lead the
    tissue's push holds it above it (`held_lead_mm`), so a press stopped by the tip alone with its setpoint
    deeper than that carries the tip on: on a soft 3-D layer at 20 mm/s the setpoint led the tip by 0.25 mm,
    already past the floor, and the tip followed it through (an `indentation` fault). Counting no lead at
    all ended presses on stiff spots short instead: on the paper scene's lump (2 N, 1.3 mm of lead) every
    press ended at the floor 2.9-3.4 mm down, not at the 4 mm asked, and read the lump shallower than the
    tissue beside it. And a tip pressed at a speed comes to rest past its stopped setpoint, 0.38 mm from
    40 mm/s: the faster the task, the earlier it ends (the task's own speed, not the tip's measured one: a
    tip catching up with its setpoint after contact moved at 76 mm/s, toward the setpoint)."""
    deepest = tick.tip_mm[2] if tick.setpoint_mm is None else min(tick.tip_mm[2],
                                                                    tick.setpoint_mm[2] + tick.held_lead_mm)
    return deepest <= tick.floor_z_mm + FLOOR_CLEARANCE_MM + speed_mm_s * STOPPING_S


def held_lead_mm(normal_force_n: float, noise, stiffness_n_per_mm: float) -> float:
    """How far the tissue's push surely holds the tip above its setpoint: at rest the servo's spring (kp, its
    configured stiffness: the most it is, so the least lead) balances the push, so the lead is the force over
    kp, counting only the force above HELD_NOISE_SDS of the measured noise (`noise`: contact.SensorNoise, None
    before the sensor's noise is measured, then no lead is counted). A sensor that reads light counts less
    lead (the press ends sooner); one that reads heavy meets the force limit or the `sensor_drift` check (the
    sensor against the motors' force) first, and a tip that sinks anyway (tissue that gives way) is still the
    `indentation` fault."""
    if noise is None:
        return 0.0
    return max(normal_force_n - HELD_NOISE_SDS * noise.sd_n, 0.0) / stiffness_n_per_mm


class SurfaceGuard:
    """A monitor of the safety supervisor (check, reset) that also learns the surface (learn, forget)."""

    def __init__(self, palpation, safety) -> None:
        """palpation, safety: palpd.config.PalpationSettings, SafetySettings."""
        self.limit_mm = deepest_press_mm(palpation) + safety.indentation_margin_mm
        self.contacts: list[tuple[float, float, float]] = []
        self.recovering = False  # set by the supervisor while the arm is brought up from wherever it lay
        self.hand_guided = False  # set by the supervisor while a person moves the arm (a manual session)

    def reset(self) -> None:
        """A pause or a reset does not move the tissue: what was learned stays (forget() at a scan's start)."""

    def forget(self) -> None:
        self.contacts.clear()

    def learn(self, task) -> None:
        """A palpation that ended without a fault says where it touched (record.contact_z_mm, its target xy)."""
        record = getattr(task, "record", None)
        z = getattr(record, "contact_z_mm", None)
        xy = getattr(record, "target_xy_mm", None) or getattr(record, "start_xy_mm", None)
        if z is not None and xy is not None and math.isfinite(z):
            self.contacts.append((xy[0], xy[1], z))

    def surface_z_mm(self, x_mm: float, y_mm: float) -> float:
        best, nearest = NEAR_MM, 0.0
        for cx, cy, cz in self.contacts:  # every servo tick, over every palpation of the scan so far
            dx, dy = x_mm - cx, y_mm - cy
            if abs(dx) >= best or abs(dy) >= best:  # no nearer (the hypot is at least either): no hypot to take
                continue
            distance = math.hypot(dx, dy)
            if distance < best:
                best, nearest = distance, cz
        return nearest

    def floor_z_mm(self, tip_mm) -> float:
        return self.surface_z_mm(tip_mm[0], tip_mm[1]) - self.limit_mm

    def check(self, tick) -> Fault | None:
        below_mm = tick.floor_z_mm + self.limit_mm - tick.tip_mm[2]
        if below_mm <= self.limit_mm or self.recovering or self.hand_guided:
            return None
        return Fault("indentation", f"tip {below_mm:.2f} mm below the tissue surface, deeper than the "
                     f"{self.limit_mm:.2f} mm any palpation may go (depth plus safety.indentation_margin_mm), "
                     "whatever the force reads", tick.t_s)
