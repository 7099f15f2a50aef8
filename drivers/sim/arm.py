"""Rigid-body Phantom joints: inertia, friction, gravity, hard stops.

Each joint carries its link and the reflected rotor inertia; the coupling
between joints is small on this arm, so it is left out.
"""
from __future__ import annotations

import math

from drivers.phantom import model

JOINT_INERTIA_KG_M2 = model.JOINT_INERTIA_KG_M2
VISCOUS_NM_S = (2.0e-3, 2.0e-3, 1.5e-3)
COULOMB_NM = (2.0e-3, 2.0e-3, 2.0e-3)
COULOMB_SMOOTHING_RAD_S = 0.01  # keeps Coulomb friction continuous through zero speed


class SimArm:
    def __init__(self, q: model.Vec3 = (0.0, 0.0, 0.0)) -> None:
        self.q = list(q)
        self.qd = [0.0, 0.0, 0.0]

    def step(self, dt_s: float, tau_motor: model.Vec3, tau_external: model.Vec3) -> None:
        """Semi-implicit Euler: velocities first, then positions with the new velocities."""
        gravity = model.gravity_torques(self.q)  # type: ignore[arg-type]
        for j in range(3):
            speed = self.qd[j]
            friction = VISCOUS_NM_S[j] * speed + COULOMB_NM[j] * math.tanh(speed / COULOMB_SMOOTHING_RAD_S)
            torque = tau_motor[j] + tau_external[j] + gravity[j] - friction
            self.qd[j] = speed + torque / JOINT_INERTIA_KG_M2[j] * dt_s
            self.q[j] += self.qd[j] * dt_s
            low, high = model.JOINT_LIMITS_RAD[j]
            if not low <= self.q[j] <= high:  # hard stop: the joint halts against it
                self.q[j] = min(max(self.q[j], low), high)
                self.qd[j] = 0.0
