"""Bringing the arm back to its path after the host was late.

While the host is late the bridge ramps to the gravity hold and the arm drifts:
a pressed tissue pushes it out (a light arm leaves at a few hundred mm/s), a
moving arm coasts on past its paused setpoint. Aiming the controller straight
back at the path would fling the arm at it with the whole error. Instead the
target takes the drift on, in position and velocity, at the first tick after
the gap, and then returns to the path the way a trajectory would: braking at
most at accel_mm_s2, then no faster than speed_mm_s (or as fast as the path
itself moves, so a coasting arm waits for its paused path to catch up).
"""
from __future__ import annotations

import math

Vec3 = tuple[float, float, float]
ZERO: Vec3 = (0.0, 0.0, 0.0)
RETURN_TIME_S = 0.05  # the offset's approach to zero slows over this time constant near the path
SETTLED_MM = 0.005


class Rejoin:
    def __init__(self, period_s: float, speed_mm_s: float = 20.0, accel_mm_s2: float = 20000.0,
                 max_offset_mm: float = 50.0, max_speed_mm_s: float = 400.0) -> None:
        self.period_s, self.speed_mm_s, self.accel_mm_s2 = period_s, speed_mm_s, accel_mm_s2
        self.max_offset_mm, self.max_speed_mm_s = max_offset_mm, max_speed_mm_s
        self.reset()

    def reset(self) -> None:
        self.offset_mm: Vec3 = ZERO
        self._velocity: Vec3 = ZERO
        self.active = False

    def drifted(self, tip_mm: Vec3, tip_velocity_mm_s: Vec3, path_mm: Vec3, path_velocity_mm_s: Vec3,
                error_before_mm: Vec3, velocity_error_before_mm_s: Vec3) -> None:
        """A tick after a gravity hold: take on where the arm is and how it moves, less the tracking errors
        it had before (at most max_offset_mm and max_speed_mm_s of it: beyond that the controller corrects)."""
        self.offset_mm = _clamped(tuple(t - p - e for t, p, e in zip(tip_mm, path_mm, error_before_mm)),
                                  self.max_offset_mm)
        self._velocity = _clamped(tuple(v - pv - e for v, pv, e in zip(tip_velocity_mm_s, path_velocity_mm_s,
                                                                       velocity_error_before_mm_s)),
                                  self.max_speed_mm_s)
        self.active = True

    def step(self, path_speed_mm_s: float) -> tuple[Vec3, Vec3]:
        """This tick's (offset, offset velocity): add them to the path's target and velocity."""
        o, w, h = self.offset_mm, self._velocity, self.period_s
        limit = max(self.speed_mm_s, path_speed_mm_s)
        wanted = (-o[0] / RETURN_TIME_S, -o[1] / RETURN_TIME_S, -o[2] / RETURN_TIME_S)
        size = math.sqrt(wanted[0] ** 2 + wanted[1] ** 2 + wanted[2] ** 2)
        if size > limit:
            wanted = (wanted[0] * limit / size, wanted[1] * limit / size, wanted[2] * limit / size)
        dw = (wanted[0] - w[0], wanted[1] - w[1], wanted[2] - w[2])
        dw_size = math.sqrt(dw[0] ** 2 + dw[1] ** 2 + dw[2] ** 2)
        most = self.accel_mm_s2 * h
        if dw_size > most:
            dw = (dw[0] * most / dw_size, dw[1] * most / dw_size, dw[2] * most / dw_size)
        w = (w[0] + dw[0], w[1] + dw[1], w[2] + dw[2])
        o = (o[0] + w[0] * h, o[1] + w[1] * h, o[2] + w[2] * h)
        self.offset_mm, self._velocity = o, w
        if math.sqrt(o[0] ** 2 + o[1] ** 2 + o[2] ** 2) < SETTLED_MM and dw_size <= most:
            self.reset()
        return o, w


def _clamped(v, most: float) -> Vec3:
    size = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v if size <= most else (v[0] * most / size, v[1] * most / size, v[2] * most / size)
