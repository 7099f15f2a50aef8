"""Cartesian PD (impedance) control with gravity compensation: tau = J^T F - g(q).

Positions and forces are in the tissue frame (mm, N); the Phantom model works in metres
in its own frame, so the frame change happens here and nowhere else. The commanded
force is clamped to force_limit_n (the safety cap), so no setpoint, however wrong,
asks the arm to push harder than the tissue may be pushed.
"""
from __future__ import annotations

import math

from drivers.geometry import TissueFrame
from drivers.phantom import model

Vec3 = tuple[float, float, float]


class CartesianPD:
    def __init__(self, stiffness_n_per_mm: float, damping_n_s_per_mm: float, current_limit_a: float,
                 force_limit_n: float = math.inf) -> None:
        self.kp = stiffness_n_per_mm
        self.kd = damping_n_s_per_mm
        self.current_limit_a = current_limit_a
        self.force_limit_n = force_limit_n
        self.limited = False  # whether the last command was clamped to force_limit_n
        self.last_force_n = 0.0  # magnitude of the last commanded force

    def currents(self, q: Vec3, tip_mm: Vec3, velocity_mm_s: Vec3, target_mm: Vec3) -> Vec3:
        kp, kd = self.kp, self.kd
        fx = kp * (target_mm[0] - tip_mm[0]) - kd * velocity_mm_s[0]
        fy = kp * (target_mm[1] - tip_mm[1]) - kd * velocity_mm_s[1]
        fz = kp * (target_mm[2] - tip_mm[2]) - kd * velocity_mm_s[2]
        magnitude = math.sqrt(fx * fx + fy * fy + fz * fz)
        self.limited = magnitude > self.force_limit_n
        if self.limited:
            scale = self.force_limit_n / magnitude
            fx, fy, fz, magnitude = fx * scale, fy * scale, fz * scale, self.force_limit_n
        self.last_force_n = magnitude
        tau = model.joint_torques(q, TissueFrame.vector_to_robot((fx, fy, fz)))
        gravity = model.gravity_torques(q)
        return model.torques_to_currents(
            (tau[0] - gravity[0], tau[1] - gravity[1], tau[2] - gravity[2]), self.current_limit_a
        )
