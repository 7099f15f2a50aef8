"""Tasks the servo loop runs: each step(tick) returns the setpoint (tissue frame, mm) for that tick."""
from __future__ import annotations

from palpd.control.trajectory import LinearMove

Vec3 = tuple[float, float, float]


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
            self._t0 = tick.t_s
        elapsed = tick.t_s - self._t0
        if elapsed >= self._move.duration:
            self.done = True
        return self._move.at(elapsed)


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
