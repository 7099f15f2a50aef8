"""Where the tissue sits relative to the robot.

Robot frame (Phantom convention): x right, y up, z towards the user.
Tissue frame: origin at the centre of the palpable rectangle, x and y along
its sides, z out of the surface, so tissue (x, y, z) = robot (x, -z, y) - origin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class TissueFrame:
    origin_m: Vec3  # tissue origin in the robot frame

    def from_robot(self, p: Vec3) -> Vec3:
        ox, oy, oz = self.origin_m
        return (p[0] - ox, -(p[2] - oz), p[1] - oy)

    def to_robot(self, p: Vec3) -> Vec3:
        ox, oy, oz = self.origin_m
        return (p[0] + ox, p[2] + oy, -p[1] + oz)

    @staticmethod
    def vector_to_robot(v: Vec3) -> Vec3:
        return (v[0], v[2], -v[1])

    @staticmethod
    def vector_from_robot(v: Vec3) -> Vec3:
        return (v[0], -v[2], v[1])


def rotate_xy(x: float, y: float, angle_deg: float) -> tuple[float, float]:
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    return c * x - s * y, s * x + c * y
