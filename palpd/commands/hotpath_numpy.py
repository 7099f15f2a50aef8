"""The two versions of one servo tick's math compared by `palpd bench hotpath`.

PlainTick calls the servo's own code. NumpyTick is the same math with numpy
3-vectors, kept here (not in palpd/control) because the servo does not use it:
it exists to be measured against.
"""
from __future__ import annotations

import math

import numpy as np

from drivers.geometry import TissueFrame
from drivers.phantom import model
from palpd.control.controller import CartesianPD

_TISSUE_FROM_ROBOT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # TissueFrame's axes


def _frame(settings) -> TissueFrame:
    return TissueFrame(tuple(v / 1000.0 for v in settings.tissue.origin_mm))


def joint_trajectory(settings, ticks: int) -> list:
    """(q, velocity_mm_s, target_mm) per tick along a slow sweep over the tissue, as the servo sees them."""
    frame, inputs = _frame(settings), []
    for i in range(ticks):
        phase = 2.0 * math.pi * i / ticks
        target = (20.0 * math.cos(phase), 20.0 * math.sin(phase), 2.0)
        q = model.inverse(frame.to_robot((target[0] / 1000.0 + 0.0005, target[1] / 1000.0, 0.0025)))
        inputs.append((q, (-30.0 * math.sin(phase), 30.0 * math.cos(phase), 0.0), target))
    return inputs


class PlainTick:
    """What ServoLoop._sense and CartesianPD.currents do each tick: tuples of floats."""

    def __init__(self, settings) -> None:
        control = settings.control
        self.frame = _frame(settings)
        self.controller = CartesianPD(control.stiffness_n_per_mm, control.damping_n_s_per_mm,
                                      settings.robot.current_limit_a, settings.safety.force_cap_n)

    def step(self, q, velocity_mm_s, target_mm):
        tip_m = self.frame.from_robot(model.forward(q))
        tip_mm = (tip_m[0] * 1000.0, tip_m[1] * 1000.0, tip_m[2] * 1000.0)
        return self.controller.currents(q, tip_mm, velocity_mm_s, target_mm)


class NumpyTick:
    """The same math on numpy 3-vectors: the arrays a tick would build from the tuples it is handed."""

    def __init__(self, settings) -> None:
        control = settings.control
        self.kp, self.kd = control.stiffness_n_per_mm, control.damping_n_s_per_mm
        self.force_limit_n = settings.safety.force_cap_n
        self.current_limit_a = settings.robot.current_limit_a
        self.origin_m = np.array(_frame(settings).origin_m)
        self.nm_per_a = np.array([model.torque_per_amp(j) for j in range(3)])

    def step(self, q, velocity_mm_s, target_mm):
        s1, s2, s3 = np.sin(q)
        c1, c2, c3 = np.cos(q)
        l1, l2 = model.L1_M, model.L2_M
        reach = l1 * c2 + l2 * s3
        tip_robot_m = np.array([s1 * reach, l2 - l2 * c3 + l1 * s2, -l1 + c1 * reach])
        tip_mm = 1000.0 * (_TISSUE_FROM_ROBOT @ (tip_robot_m - self.origin_m))
        force = self.kp * (np.asarray(target_mm) - tip_mm) - self.kd * np.asarray(velocity_mm_s)
        magnitude = np.linalg.norm(force)
        if magnitude > self.force_limit_n:
            force *= self.force_limit_n / magnitude
        jacobian = np.array([[c1 * reach, -s1 * l1 * s2, s1 * l2 * c3],
                             [0.0, l1 * c2, l2 * s3],
                             [-s1 * reach, -c1 * l1 * s2, c1 * l2 * c3]])
        tau = jacobian.T @ (_TISSUE_FROM_ROBOT.T @ force)
        g = model.GRAVITY_M_S2
        gravity = np.array([0.0, -g * c2 * l1 * (model.LINK1_MASS_KG / 2.0 + model.TIP_MASS_KG),
                            -g * model.TIP_MASS_KG * l2 * s3])
        return np.clip((tau - gravity) / self.nm_per_a, -self.current_limit_a, self.current_limit_a)
