"""Cartesian PD (impedance) control with gravity compensation: tau = J^T F - g(q).

Positions and forces are in the tissue frame (mm, N); the Phantom model works in metres
in its own frame, so the frame change happens here and nowhere else. The commanded
force is clamped to force_limit_n (the safety cap), so no setpoint, however wrong,
asks the arm to push harder than the tissue may be pushed.

The gains are a discrete-time design, not the continuous PD's. The loop is sampled
(each command is held until the next), it reads the encoders up to 1.25 periods late (the
reply to the last command is this tick's reading: one wire exchange per tick) and
its damping acts on a low-pass filtered velocity. For a joint presenting mass m to
the tip, such a loop is stable only while kd*h/m stays below a bound that depends
on those delays; `damping_bound` finds it once, numerically, from the loop's own
state-space model. Every tick the gains are capped for the lightest mass the tip
presents at that pose (far out in the workspace the first joint is light), and
after a late tick for the hold just seen (a late host is likely late again soon):
no command is held longer than max_hold_s, since beyond it the bridge ramps the
currents to the gravity hold each command carries (PROTOCOL.md).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from drivers.geometry import TissueFrame
from drivers.phantom import model

Vec3 = tuple[float, float, float]
SPECTRAL_RADIUS_MAX = 0.97  # the capped loop's slowest mode shrinks at least 3 % a period
READING_AGE_PERIODS = 1.25  # the design holds for encoder readings up to this old (older ones are read afresh)
LATE_FACTOR = 1.5  # a gap this many periods long is a late tick


class CartesianPD:
    def __init__(self, stiffness_n_per_mm: float, damping_n_s_per_mm: float, current_limit_a: float,
                 force_limit_n: float = math.inf, period_s: float = 0.001, max_hold_s: float | None = None,
                 velocity_filter_hz: float = 100.0) -> None:
        self.kp = stiffness_n_per_mm
        self.kd = damping_n_s_per_mm
        self.current_limit_a = current_limit_a
        self.force_limit_n = force_limit_n
        self.period_s = period_s
        self.max_hold_s = max(max_hold_s or period_s, period_s)
        # kd * h / m may not exceed this (kp scaled with kd): from the loop's discrete model.
        self.damping_bound = damping_bound(self.kp / self.kd if self.kd else 0.0, period_s, velocity_filter_hz)
        self.limited = False  # whether the last command was clamped to force_limit_n
        self.last_force_n = 0.0  # magnitude of the last commanded force
        self.last_force_vec_n: Vec3 = (0.0, 0.0, 0.0)  # the last commanded force itself (tissue frame, N)
        self.hold_a: Vec3 = (0.0, 0.0, 0.0)  # gravity compensation alone at the last pose: what a silent host leaves on

    def currents(self, q: Vec3, tip_mm: Vec3, velocity_mm_s: Vec3, target_mm: Vec3,
                 target_velocity_mm_s: Vec3 = (0.0, 0.0, 0.0), gap_s: float = 0.0) -> Vec3:
        """Motor currents for this tick; the damping acts on the velocity relative to the setpoint's, so a
        moving setpoint is followed without a speed-proportional lag."""
        kp, kd = self.gains(q, gap_s)
        vx, vy, vz = target_velocity_mm_s
        fx = kp * (target_mm[0] - tip_mm[0]) + kd * (vx - velocity_mm_s[0])
        fy = kp * (target_mm[1] - tip_mm[1]) + kd * (vy - velocity_mm_s[1])
        fz = kp * (target_mm[2] - tip_mm[2]) + kd * (vz - velocity_mm_s[2])
        magnitude = math.sqrt(fx * fx + fy * fy + fz * fz)
        self.limited = magnitude > self.force_limit_n
        if self.limited:
            scale = self.force_limit_n / magnitude
            fx, fy, fz, magnitude = fx * scale, fy * scale, fz * scale, self.force_limit_n
        self.last_force_n = magnitude
        self.last_force_vec_n = (fx, fy, fz)
        tau = model.joint_torques(q, TissueFrame.vector_to_robot((fx, fy, fz)))
        g0, g1, g2 = model.gravity_torques(q)
        limit = self.current_limit_a
        self.hold_a = model.torques_to_currents((-g0, -g1, -g2), limit)
        return model.torques_to_currents((tau[0] - g0, tau[1] - g1, tau[2] - g2), limit)

    def gains(self, q: Vec3, gap_s: float = 0.0) -> tuple[float, float]:
        """(kp N/mm, kd N s/mm) for this tick: the configured ones, capped for the lightest mass at q and,
        after a late tick, for a hold as long as the gap (at most max_hold_s)."""
        hold_s = self.period_s
        if gap_s > LATE_FACTOR * self.period_s:
            hold_s = min(gap_s, self.max_hold_s)
        kd_max = self.damping_bound * model.lightest_tip_mass_kg(q) / hold_s / 1000.0
        if kd_max >= self.kd:
            return self.kp, self.kd
        return self.kp * kd_max / self.kd, kd_max


@functools.lru_cache(maxsize=16)
def damping_bound(kp_over_kd_per_s: float, period_s: float, filter_hz: float,
                  age_periods: float = READING_AGE_PERIODS, radius_max: float = SPECTRAL_RADIUS_MAX) -> float:
    """The largest b = kd*h/m (with kp = kp_over_kd * kd) for which the sampled loop's spectral radius stays
    at most radius_max: a mass under a zero-order-held PD, its position read age_periods late (1 to 2) and
    its velocity a first-order filtered difference of those readings. Found by bisection on b."""
    low, high = 0.0, 4.0
    for _ in range(40):
        b = (low + high) / 2
        radius = _spectral_radius(b, kp_over_kd_per_s * period_s, period_s, filter_hz, age_periods)
        low, high = (b, high) if radius <= radius_max else (low, b)
    return low


def _spectral_radius(b: float, kp_h_over_kd: float, h: float, filter_hz: float, age_periods: float) -> float:
    """For m = 1 kg: kd = b/h, kp = kp_h_over_kd * kd / h. State (x, v, x one and two periods ago, the
    previous reading, the filtered velocity); the reading interpolates between the past positions."""
    kd = b / h
    kp = kp_h_over_kd * kd / h
    a = math.exp(-2.0 * math.pi * filter_hz * h)
    late = min(max(age_periods, 1.0), 2.0) - 1.0

    def step(s):
        x, v, x1, x2, y_prev, v_hat = s
        y = (1.0 - late) * x1 + late * x2
        v_hat = a * v_hat + (1.0 - a) * (y - y_prev) / h
        force = -kp * y - kd * v_hat
        return (x + v * h + force * h * h / 2.0, v + force * h, x, x1, y, v_hat)

    matrix = np.column_stack([step(tuple(unit)) for unit in np.eye(6)])
    return float(max(abs(np.linalg.eigvals(matrix))))
