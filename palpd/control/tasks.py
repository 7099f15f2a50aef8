"""Tasks the servo loop runs: each step(tick) returns the setpoint (tissue frame, mm) for that tick.

Motion follows the servo's own tick clock (tick.motion_t_s: one period per tick,
whatever the real gap), so a host that stalls pauses the motion instead of
finding its setpoint jumped ahead when it wakes.
"""
from __future__ import annotations

import math

from palpd.control.trajectory import LinearMove

Vec3 = tuple[float, float, float]
PARKED_MM = 1.0  # the tip this close to the rest pose, and slower than PARKED_MM_S, is parked
PARKED_MM_S = 5.0


class MoveTo:
    """Go to goal along a straight line within the speed and acceleration limits."""

    def __init__(self, goal: Vec3, speed_mm_s: float, accel_mm_s2: float, start: Vec3 | None = None) -> None:
        self.goal, self.speed, self.accel, self.start = goal, speed_mm_s, accel_mm_s2, start
        self._move: LinearMove | None = None
        self._t0 = 0.0
        self.done = False

    def step(self, tick) -> Vec3:
        if self._move is None:
            self._move = LinearMove(self.start or tick.tip_mm, self.goal, self.speed, self.accel)
            self._t0 = tick.motion_t_s
        elapsed = tick.motion_t_s - self._t0
        if elapsed >= self._move.duration:
            self.done = True
        return self._move.at(elapsed)


class Park:
    """To the rest pose without touching the tissue: first straight up along its normal to clear_z_mm (from
    the tip, so a press releases at once), then in a straight line to rest_mm, which is above clear_z_mm.

    With from_anywhere the servo accepts the pose the arm starts in as inside its limits: after a fault the
    arm may lie on the tissue or against a stop, and this is how it comes back (under supervision)."""

    def __init__(self, rest_mm: Vec3, clear_z_mm: float, speed_mm_s: float, accel_mm_s2: float,
                 from_anywhere: bool = False) -> None:
        self.rest_mm, self.clear_z_mm = rest_mm, clear_z_mm
        self.speed, self.accel, self.from_anywhere = speed_mm_s, accel_mm_s2, from_anywhere
        self.lift: MoveTo | None = None
        self._home: MoveTo | None = None
        self.done = False

    @property
    def lifted(self) -> bool:
        return self.lift is not None and self.lift.done

    def step(self, tick) -> Vec3:
        if self.lift is None:
            x, y, z = tick.tip_mm
            self.lift = MoveTo((x, y, max(z, self.clear_z_mm)), self.speed, self.accel)
        if not self.lift.done:
            return self.lift.step(tick)
        if self._home is None:
            self._home = MoveTo(self.rest_mm, self.speed, self.accel, start=self.lift.goal)
        target = self._home.step(tick)
        # Done only with the arm itself at rest there (it may lag its path): the power goes off next.
        self.done = self._home.done and math.dist(tick.tip_mm, self.rest_mm) <= PARKED_MM \
            and math.dist(tick.velocity_mm_s, (0.0, 0.0, 0.0)) <= PARKED_MM_S
        return target


class HoldAndCollect:
    """Hold still where the tip is and keep the sensor samples (to tare the sensor, say)."""

    def __init__(self, samples: int, where: Vec3 | None = None) -> None:
        self.wanted = samples
        self.samples: list = []
        self._where = where
        self.done = False

    def step(self, tick) -> Vec3:
        if self._where is None:
            self._where = tick.tip_mm
        self.samples.append(tick.sample)
        self.done = len(self.samples) >= self.wanted
        return self._where
