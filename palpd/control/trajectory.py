"""Straight moves with a trapezoidal speed profile (speed and acceleration limited)."""
from __future__ import annotations

import math

Vec3 = tuple[float, float, float]


class LinearMove:
    """From start to goal along a line; at(t) gives the setpoint t seconds after the start."""

    def __init__(self, start: Vec3, goal: Vec3, speed: float, accel: float) -> None:
        self.start, self.goal = start, goal
        delta = (goal[0] - start[0], goal[1] - start[1], goal[2] - start[2])
        self.length = math.sqrt(delta[0] ** 2 + delta[1] ** 2 + delta[2] ** 2)
        self._unit = tuple(d / self.length for d in delta) if self.length > 0 else (0.0, 0.0, 0.0)
        self._accel = accel
        if self.length * accel < speed * speed:  # too short to reach full speed: a triangle
            speed = math.sqrt(self.length * accel)
        self._speed = speed
        self._ramp_s = speed / accel if accel > 0 else 0.0
        cruise = self.length - speed * self._ramp_s
        self.duration = 2.0 * self._ramp_s + (cruise / speed if speed > 0 else 0.0)

    def distance_at(self, t: float) -> float:
        if t <= 0.0:
            return 0.0
        if t >= self.duration:
            return self.length
        ramp = self._ramp_s
        if t < ramp:
            return 0.5 * self._accel * t * t
        if t > self.duration - ramp:
            left = self.duration - t
            return self.length - 0.5 * self._accel * left * left
        return 0.5 * self._accel * ramp * ramp + self._speed * (t - ramp)

    def at(self, t: float) -> Vec3:
        s = self.distance_at(t)
        u = self._unit
        return (self.start[0] + u[0] * s, self.start[1] + u[1] * s, self.start[2] + u[2] * s)
