"""The Phantom Premium 1.5A as a mechanism: kinematics, encoders, motors, gravity.

Frame and equations follow Cavusoglu et al. (the PHANToM kinematic model):
x right, y up, z towards the user; home (all joints at zero) is the origin.
Every function here works on plain floats and tuples because the servo loop
calls them each millisecond and 3-vectors in numpy cost more than they save.
"""
from __future__ import annotations

import math

L1_M = 0.2095
L2_M = 0.1695
SPAN_MM = 2000.0 * (L1_M + L2_M)  # no two spots farther apart than this are both within the arm's reach
CAPSTAN_RATIO = (13.3, 11.2, 11.2)
ENCODER_COUNTS_PER_REV = 1024 * 4  # 1024 CPR read in quadrature
RAD_PER_COUNT = tuple(2.0 * math.pi / (ENCODER_COUNTS_PER_REV * eta) for eta in CAPSTAN_RATIO)
MOTOR_KT_NM_PER_A = 0.0234  # Maxon RE25
NOMINAL_CURRENT_A = 1.24
PEAK_CURRENT_A = 5.5
# Joint ranges of the 1.5A, generous enough for its published workspace.
JOINT_LIMITS_RAD = ((-1.0, 1.0), (-0.6, 1.2), (-0.6, 1.2))
HOME_Q = (0.0, 0.0, 0.0)  # where the arm rests in its stand at power-up (the calibration pose)
# Each joint's link plus reflected rotor inertia (the coupling between joints is small on this arm).
JOINT_INERTIA_KG_M2 = (3.0e-3, 2.5e-3, 1.5e-3)

# Lumped gravity model: link-1 mass at its midpoint, link-2 and tip mass at the tip.
# The real arm is counterbalanced; these are the residual, uncompensated masses.
LINK1_MASS_KG = 0.045
TIP_MASS_KG = 0.035
GRAVITY_M_S2 = 9.81

Vec3 = tuple[float, float, float]


def forward(q: Vec3) -> Vec3:
    """Tip position (m) for joint angles q (rad)."""
    t1, t2, t3 = q
    reach = L1_M * math.cos(t2) + L2_M * math.sin(t3)
    return (
        math.sin(t1) * reach,
        L2_M - L2_M * math.cos(t3) + L1_M * math.sin(t2),
        -L1_M + math.cos(t1) * reach,
    )


def jacobian(q: Vec3) -> tuple[Vec3, Vec3, Vec3]:
    """Rows d(x, y, z)/d(q1, q2, q3)."""
    t1, t2, t3 = q
    s1, c1 = math.sin(t1), math.cos(t1)
    s2, c2 = math.sin(t2), math.cos(t2)
    s3, c3 = math.sin(t3), math.cos(t3)
    reach = L1_M * c2 + L2_M * s3
    return (
        (c1 * reach, -s1 * L1_M * s2, s1 * L2_M * c3),
        (0.0, L1_M * c2, L2_M * s3),
        (-s1 * reach, -c1 * L1_M * s2, c1 * L2_M * c3),
    )


def joint_torques(q: Vec3, force_n: Vec3) -> Vec3:
    """tau = J^T F: the joint torques that push the tip with force_n."""
    j = jacobian(q)
    fx, fy, fz = force_n
    return (
        j[0][0] * fx + j[1][0] * fy + j[2][0] * fz,
        j[0][1] * fx + j[1][1] * fy + j[2][1] * fz,
        j[0][2] * fx + j[1][2] * fy + j[2][2] * fz,
    )


def lightest_tip_mass_kg(q: Vec3) -> float:
    """The smallest mass the tip presents along any one joint's motion at q: I_j / |dp/dq_j|^2.

    J's columns have lengths reach, L1 and L2 (reach = the tip's distance from the base axis), so
    this is cheap enough to ask on a late tick.
    """
    _, t2, t3 = q
    reach = L1_M * math.cos(t2) + L2_M * math.sin(t3)
    i1, i2, i3 = JOINT_INERTIA_KG_M2
    return min(i1 / max(reach * reach, 1e-6), i2 / (L1_M * L1_M), i3 / (L2_M * L2_M))


def tip_inertia_force_n(q: Vec3, accel_m_s2: Vec3) -> Vec3:
    """The force on the tip that accelerates it by accel_m_s2 at q: J^-T M J^-1 a (M: each joint's inertia)."""
    j = jacobian(q)
    qdd = _solve3(j, accel_m_s2)
    tau = tuple(i * a for i, a in zip(JOINT_INERTIA_KG_M2, qdd))
    return _solve3(tuple(zip(*j)), tau)  # type: ignore[arg-type]


def _det3(a00, a01, a02, a10, a11, a12, a20, a21, a22) -> float:
    return a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20) + a02 * (a10 * a21 - a11 * a20)


def _solve3(m, v: Vec3) -> Vec3:
    """x with m x = v (Cramer's rule; a singular m, at the workspace's edge, gives no force). Written out: the
    sensor-health check solves two of these every few servo ticks, and nested lists cost more than the sums."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = m
    v0, v1, v2 = v
    d = _det3(m00, m01, m02, m10, m11, m12, m20, m21, m22)
    if abs(d) < 1e-12:
        return (0.0, 0.0, 0.0)
    return (_det3(v0, m01, m02, v1, m11, m12, v2, m21, m22) / d,
            _det3(m00, v0, m02, m10, v1, m12, m20, v2, m22) / d,
            _det3(m00, m01, v0, m10, m11, v1, m20, m21, v2) / d)


def tip_velocity(q: Vec3, qdot: Vec3) -> Vec3:
    j = jacobian(q)
    return tuple(row[0] * qdot[0] + row[1] * qdot[1] + row[2] * qdot[2] for row in j)  # type: ignore[return-value]


class UnreachableError(ValueError):
    """The requested tip position is outside the arm's reach or joint limits."""


def inverse(p: Vec3) -> Vec3:
    """Joint angles for tip position p (m), elbow as at home; refuses what the arm cannot reach."""
    x, y, z = p
    reach = math.hypot(x, z + L1_M)
    height = y - L2_M
    cos_elbow = (reach * reach + height * height - L1_M * L1_M - L2_M * L2_M) / (2.0 * L1_M * L2_M)
    if not -1.0 <= cos_elbow <= 1.0 or reach < 1e-9:
        raise UnreachableError(f"tip position {_mm(p)} mm is out of the arm's reach")
    # phi = t3 - pi/2 is link 2's absolute angle; elbow = phi - t2 stays negative as at home.
    elbow = -math.acos(cos_elbow)
    t2 = math.atan2(height, reach) - math.atan2(L2_M * math.sin(elbow), L1_M + L2_M * math.cos(elbow))
    q = (math.atan2(x, z + L1_M), t2, elbow + t2 + math.pi / 2.0)
    check_joint_limits(q, p)
    return q


def check_joint_limits(q: Vec3, p: Vec3 | None = None) -> None:
    for i, (angle, (low, high)) in enumerate(zip(q, JOINT_LIMITS_RAD)):
        if not low <= angle <= high:
            where = f" for tip position {_mm(p)} mm" if p is not None else ""
            raise UnreachableError(
                f"joint {i + 1} would be at {angle:.3f} rad{where}, outside its limits [{low}, {high}] rad"
            )


def gravity_torques(q: Vec3) -> Vec3:
    """Joint torques gravity applies (from the potential of the lumped masses)."""
    _, t2, t3 = q
    return (
        0.0,
        -GRAVITY_M_S2 * math.cos(t2) * L1_M * (LINK1_MASS_KG / 2.0 + TIP_MASS_KG),
        -GRAVITY_M_S2 * TIP_MASS_KG * L2_M * math.sin(t3),
    )


_R0, _R1, _R2 = RAD_PER_COUNT


def counts_to_angles(counts: tuple[int, int, int]) -> Vec3:
    c0, c1, c2 = counts
    return (c0 * _R0, c1 * _R1, c2 * _R2)


def angles_to_counts(q: Vec3) -> tuple[int, int, int]:
    q0, q1, q2 = q
    return (round(q0 / _R0), round(q1 / _R1), round(q2 / _R2))


def torque_per_amp(joint: int) -> float:
    return CAPSTAN_RATIO[joint] * MOTOR_KT_NM_PER_A


_NM_PER_A = tuple(torque_per_amp(joint) for joint in range(3))
_A0, _A1, _A2 = (1.0 / nm for nm in _NM_PER_A)


def torques_to_currents(tau: Vec3, limit_a: float = PEAK_CURRENT_A) -> Vec3:
    """Motor currents for joint torques, clamped to +-limit_a (unrolled: twice every servo tick)."""
    a0, a1, a2 = tau[0] * _A0, tau[1] * _A1, tau[2] * _A2
    return (limit_a if a0 > limit_a else -limit_a if a0 < -limit_a else a0,
            limit_a if a1 > limit_a else -limit_a if a1 < -limit_a else a1,
            limit_a if a2 > limit_a else -limit_a if a2 < -limit_a else a2)


def currents_to_torques(currents: Vec3) -> Vec3:
    i0, i1, i2 = currents
    return (i0 * _NM_PER_A[0], i1 * _NM_PER_A[1], i2 * _NM_PER_A[2])


def link2_rotation(q: Vec3) -> tuple[Vec3, Vec3, Vec3]:
    """Orientation of link 2 (rows of a rotation matrix, base frame): yaw by q1, pitch by q3."""
    t1, _, t3 = q
    s1, c1, s3, c3 = math.sin(t1), math.cos(t1), math.sin(t3), math.cos(t3)
    # Ry(t1) @ Rx(-t3): pitching link 2 forward by t3 about the x axis, then yawing the whole arm.
    return (
        (c1, -s1 * s3, s1 * c3),
        (0.0, c3, s3),
        (-s1, -c1 * s3, c1 * c3),
    )


def _mm(p: Vec3) -> str:
    return "(" + ", ".join(f"{1000.0 * v:.1f}" for v in p) + ")"


def _transpose_times(m, v: Vec3) -> Vec3:
    return (
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    )


def _times(m, v: Vec3) -> Vec3:
    return (
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    )


class SensorTilt:
    """tilt_to_base for one q_aligned, with the aligned pose's rotation worked out once (the servo's per-tick form)."""

    def __init__(self, q_aligned: Vec3) -> None:
        self._aligned = link2_rotation(q_aligned)

    def to_base(self, q: Vec3, v: Vec3) -> Vec3:
        return _times(link2_rotation(q), _transpose_times(self._aligned, v))

    def from_base(self, q: Vec3, v: Vec3) -> Vec3:
        """What the tilted sensor reads of a vector v given in base axes (base_to_tilt)."""
        return _times(self._aligned, _transpose_times(link2_rotation(q), v))


def tilt_to_base(q: Vec3, q_aligned: Vec3, v: Vec3) -> Vec3:
    """A vector measured by a sensor fixed to link 2, aligned with the base at q_aligned, in base axes.

    The sensor turns with link 2, so away from q_aligned its axes tilt: the
    seed paper's error source when only the sensor's z axis is read.
    """
    return _times(link2_rotation(q), _transpose_times(link2_rotation(q_aligned), v))


def base_to_tilt(q: Vec3, q_aligned: Vec3, v: Vec3) -> Vec3:
    """Inverse of tilt_to_base."""
    return _times(link2_rotation(q_aligned), _transpose_times(link2_rotation(q), v))


# -- torque and thermal limits ---------------------------------------------------------------
PEAK_DURATION_S = 2.0  # how long a motor may carry the peak current from cold before I2t limits it


def torque_limits_nm(joint: int) -> tuple[float, float]:
    """(nominal, peak) joint torque: what the motor carries continuously and what it gives for a moment."""
    return NOMINAL_CURRENT_A * torque_per_amp(joint), PEAK_CURRENT_A * torque_per_amp(joint)


class ThermalLimit:
    """I2t protection: currents above nominal heat the windings; once the budget is spent, nominal only.

    The budget (peak^2 - nominal^2) * PEAK_DURATION_S is what the motor may absorb above its
    continuous rating; running below nominal cools it at the same rate.
    """

    def __init__(self, nominal_a: float = NOMINAL_CURRENT_A, peak_a: float = PEAK_CURRENT_A,
                 peak_duration_s: float = PEAK_DURATION_S) -> None:
        # A peak configured below nominal is a hard cap: never let the nominal rating exceed it.
        self.nominal_a, self.peak_a = min(nominal_a, peak_a), peak_a
        self.budget_a2s = (peak_a * peak_a - self.nominal_a * self.nominal_a) * peak_duration_s
        self.heat_a2s = [0.0, 0.0, 0.0]

    def limit(self, currents_a: Vec3, dt_s: float) -> Vec3:
        """Clamp each current to the peak, or to nominal once that joint's budget is spent; then account."""
        heat = self.heat_a2s
        return (self._joint(0, currents_a[0], dt_s, heat), self._joint(1, currents_a[1], dt_s, heat),
                self._joint(2, currents_a[2], dt_s, heat))

    def _joint(self, joint: int, amps: float, dt_s: float, heat: list) -> float:
        budget = self.budget_a2s
        cap = self.nominal_a if heat[joint] >= budget else self.peak_a
        if amps != amps:  # NaN: no current rather than an undefined one
            amps = 0.0
        amps = cap if amps > cap else -cap if amps < -cap else amps
        warmer = heat[joint] + (amps * amps - self.nominal_a * self.nominal_a) * dt_s
        heat[joint] = budget if warmer > budget else 0.0 if warmer < 0.0 else warmer
        return amps

    def limited(self) -> bool:
        return any(h >= self.budget_a2s for h in self.heat_a2s)
