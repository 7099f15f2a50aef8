"""ATI .cal calibration files: gauge voltages <-> force/torque, as ATI's ATIDAQ library does it.

The user matrix comes from the UserAxis rows. A file also carries the raw
Axis rows with their scale and the BasicTransform that was applied to them
(T' = T - d x F); check_agreement() recomputes the user matrix from those and
says how far apart the two are. Internally everything is N and N*mm.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from drivers.errors import DriverInitializationError

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
FORCE_N = {"N": 1.0, "lbf": 4.4482216152605, "klbf": 4448.2216152605, "kN": 1000.0, "g": 0.00980665,
           "kgf": 9.80665}
TORQUE_N_MM = {"N-mm": 1.0, "N-m": 1000.0, "lbf-in": 112.98482933833, "lbf-ft": 1355.8179483314,
               "kN-m": 1.0e6, "kgf-cm": 98.0665, "g-cm": 0.0980665}
DIST_MM = {"mm": 1.0, "m": 1000.0, "cm": 10.0, "in": 25.4, "ft": 304.8}
ANGLE_RAD = {"degrees": math.pi / 180.0, "radians": 1.0}


@dataclass(frozen=True)
class Calibration:
    serial: str
    body_style: str
    part_number: str
    force_units: str
    torque_units: str
    dist_units: str
    gauges: int
    matrix: np.ndarray  # 6 x gauges, file units: (F, T) = matrix @ volts
    ranges: tuple[float, ...]  # calibrated full scale per axis, file units
    axis_matrix: np.ndarray | None = None  # Axis rows / scale, before BasicTransform
    basic_transform: tuple[float, ...] = (0.0,) * 6  # Dx, Dy, Dz (dist units), Rx, Ry, Rz (degrees)
    output_range_v: float = 20.0
    bipolar: bool = True

    def in_units(self, force_units: str = "N", torque_units: str = "N-mm") -> "Calibration":
        """The same calibration giving forces and torques in other units."""
        force = _factor(FORCE_N, self.force_units, "force") / _factor(FORCE_N, force_units, "force")
        torque = _factor(TORQUE_N_MM, self.torque_units, "torque") / _factor(TORQUE_N_MM, torque_units, "torque")
        scale = np.array([force] * 3 + [torque] * 3)
        return replace(self, force_units=force_units, torque_units=torque_units,
                       matrix=self.matrix * scale[:, None], ranges=tuple(np.array(self.ranges) * scale),
                       axis_matrix=None if self.axis_matrix is None else self.axis_matrix * scale[:, None])

    def with_tool_transform(self, offset: tuple[float, float, float], rotation_deg=(0.0, 0.0, 0.0)) -> "Calibration":
        """Report the load at a tool point offset (dist units) from the sensor origin, in axes turned by rotation."""
        return replace(self, matrix=tool_transform(offset, rotation_deg, self._dist_in_torque_units()) @ self.matrix)

    def check_agreement(self) -> float | None:
        """Largest |UserAxis - BasicTransform(Axis/scale)| entry, or None when the file has no Axis rows."""
        if self.axis_matrix is None:
            return None
        d, r = self.basic_transform[:3], self.basic_transform[3:]
        recomputed = tool_transform(d, r, self._dist_in_torque_units()) @ self.axis_matrix
        return float(np.max(np.abs(recomputed - self.matrix)))

    def _dist_in_torque_units(self) -> float:
        """Torque units per (force unit x distance unit), so d x F lands in torque units."""
        force_n = _factor(FORCE_N, self.force_units, "force")
        return force_n * _factor(DIST_MM, self.dist_units, "distance") / _factor(TORQUE_N_MM, self.torque_units, "torque")

    def as_dict(self) -> dict:
        return {"serial": self.serial, "body_style": self.body_style, "part_number": self.part_number,
                "force_units": self.force_units, "torque_units": self.torque_units, "dist_units": self.dist_units,
                "gauges": self.gauges, "ranges": dict(zip(AXES, self.ranges)),
                "basic_transform": list(self.basic_transform), "axis_disagreement": self.check_agreement(),
                "user_matrix": [[float(v) for v in row] for row in self.matrix]}


def tool_transform(offset, rotation_deg, torque_per_force_dist: float = 1.0) -> np.ndarray:
    """6x6 matrix: move the reference point by offset (T' = T - d x F), then turn the axes by R = Rz Ry Rx."""
    dx, dy, dz = (v * torque_per_force_dist for v in offset)
    cross = np.array([[0.0, -dz, dy], [dz, 0.0, -dx], [-dy, dx, 0.0]])  # d x F as a matrix
    rotation = _rotation(*(math.radians(a) for a in rotation_deg))
    out = np.zeros((6, 6))
    out[:3, :3] = rotation
    out[3:, 3:] = rotation
    out[3:, :3] = -rotation @ cross
    return out


def _rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return (z @ y @ x).T  # axes turned by R: a vector's components in the new axes are R^T v


def _factor(table: dict, unit: str, what: str) -> float:
    if unit not in table:
        raise DriverInitializationError(f"unknown {what} unit {unit!r}; known: {', '.join(table)}")
    return table[unit]
