"""A person palpating by hand: a smooth, imperfect tip path the simulated arm follows.

Set ``world.hand = HandSession(...)`` and the arm goes where the hand takes it
(the motors cannot overpower a hand), as when the seed paper's data was taken.
Taps vary in depth, speed and dwell; some are double taps; the hand trembles.
"""
from __future__ import annotations

import math
import random
from bisect import bisect_right
from dataclasses import dataclass

from drivers.phantom import model

HOVER_MM = 6.0
TREMOR_MM = 0.05
TREMOR_HZ = 8.0


@dataclass(frozen=True)
class Tap:
    xy_mm: tuple[float, float]
    depth_mm: float
    t_s: float  # when the press starts (at the hover height)
    press_s: float  # hover -> deepest
    double: bool = False


class HandSession:
    def __init__(self, frame, taps: list[Tap]) -> None:
        self.frame, self.taps = frame, taps
        keys = [(0.0, (taps[0].xy_mm[0], taps[0].xy_mm[1], HOVER_MM))]
        for tap in taps:
            keys += _tap_keys(tap)
        self._t = [k[0] for k in keys]
        self._p = [k[1] for k in keys]
        self.end_s = self._t[-1]

    @classmethod
    def random(cls, frame, count: int, seed: int, double_every: int = 3) -> "HandSession":
        rng = random.Random(seed)
        taps, t = [], 0.5
        for i in range(count):
            tap = Tap((rng.uniform(-25, 25), rng.uniform(-25, 25)), rng.uniform(2.0, 5.0), t,
                      rng.uniform(0.25, 0.6), double=(i % double_every == double_every - 1))
            taps.append(tap)
            t += 2.0 * tap.press_s * (2 if tap.double else 1) + rng.uniform(0.6, 1.2)
        return cls(frame, taps)

    def tip_mm(self, t_s: float) -> tuple[float, float, float]:
        i = min(max(bisect_right(self._t, t_s) - 1, 0), len(self._t) - 2)
        t0, t1 = self._t[i], self._t[i + 1]
        s = min(max((t_s - t0) / (t1 - t0), 0.0), 1.0) if t1 > t0 else 1.0
        s = 0.5 - 0.5 * math.cos(math.pi * s)  # a hand eases in and out
        a, b = self._p[i], self._p[i + 1]
        tremor = TREMOR_MM * math.sin(2 * math.pi * TREMOR_HZ * t_s)
        return (a[0] + (b[0] - a[0]) * s + tremor, a[1] + (b[1] - a[1]) * s, a[2] + (b[2] - a[2]) * s + tremor)

    def q_at(self, t_s: float) -> model.Vec3:
        x, y, z = self.tip_mm(t_s)
        return model.inverse(self.frame.to_robot((x / 1000.0, y / 1000.0, z / 1000.0)))


def _tap_keys(tap: Tap) -> list[tuple[float, tuple[float, float, float]]]:
    """Key points: move over, press, release (for a double tap: lift just off, press again, release)."""
    x, y = tap.xy_mm
    t, p = tap.t_s, tap.press_s
    keys = [(t, (x, y, HOVER_MM)), (t + p, (x, y, -tap.depth_mm))]
    if tap.double:
        keys += [(t + 1.6 * p, (x, y, 1.0)), (t + 1.7 * p, (x, y, 1.0)), (t + 2.7 * p, (x, y, -0.8 * tap.depth_mm))]
        t += 1.7 * p
    keys.append((t + 2 * p, (x, y, HOVER_MM)))
    return keys
