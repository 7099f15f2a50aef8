"""Cartesian PD (impedance) control with gravity compensation: tau = J^T F - g(q).

Positions and forces are in the tissue frame (mm, N); the Phantom model works in metres
in its own frame, so the frame change happens here and nowhere else.
"""
from __future__ import annotations

from drivers.geometry import TissueFrame
from drivers.phantom import model

Vec3 = tuple[float, float, float]


class CartesianPD:
    def __init__(self, stiffness_n_per_mm: float, damping_n_s_per_mm: float, current_limit_a: float) -> None:
        self.kp = stiffness_n_per_mm
        self.kd = damping_n_s_per_mm
        self.current_limit_a = current_limit_a

    def currents(self, q: Vec3, tip_mm: Vec3, velocity_mm_s: Vec3, target_mm: Vec3) -> Vec3:
        kp, kd = self.kp, self.kd
        force_tissue = (
            kp * (target_mm[0] - tip_mm[0]) - kd * velocity_mm_s[0],
            kp * (target_mm[1] - tip_mm[1]) - kd * velocity_mm_s[1],
            kp * (target_mm[2] - tip_mm[2]) - kd * velocity_mm_s[2],
        )
        tau = model.joint_torques(q, TissueFrame.vector_to_robot(force_tissue))
        gravity = model.gravity_torques(q)
        return model.torques_to_currents(
            (tau[0] - gravity[0], tau[1] - gravity[1], tau[2] - gravity[2]), self.current_limit_a
        )
