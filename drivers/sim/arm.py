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
_JOINTS = tuple(zip(range(3), VISCOUS_NM_S, COULOMB_NM, JOINT_INERTIA_KG_M2, model.JOINT_LIMITS_RAD))


class SimArm:
    def __init__(self, q: model.Vec3 = (0.0, 0.0, 0.0)) -> None:
        self.q = list(q)
        self.qd = [0.0, 0.0, 0.0]

    def step(self, dt_s: float, tau_motor: model.Vec3, tau_external: model.Vec3) -> None:
        """Semi-implicit Euler: velocities first, then positions with the new velocities."""
        gravity = model.gravity_torques(self.q)  # type: ignore[arg-type]
        q, qd, tanh = self.q, self.qd, math.tanh
        for j, viscous, coulomb, inertia, (low, high) in _JOINTS:  # twice per servo tick: locals, no indexing
            speed = qd[j]
            friction = viscous * speed + coulomb * tanh(speed / COULOMB_SMOOTHING_RAD_S)
            torque = tau_motor[j] + tau_external[j] + gravity[j] - friction
            qd[j] = speed = speed + torque / inertia * dt_s
            q[j] = position = q[j] + speed * dt_s
            if not low <= position <= high:  # hard stop: the joint halts against it
                q[j] = min(max(position, low), high)
                qd[j] = 0.0
