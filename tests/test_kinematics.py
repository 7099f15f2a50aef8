import math

import pytest
from hypothesis import assume, given, strategies as st

from drivers.phantom import model

L1, L2 = model.L1_M, model.L2_M
joint = st.tuples(st.floats(-0.8, 0.8), st.floats(-0.5, 0.9), st.floats(-0.4, 1.0))


def test_home_is_the_origin():
    assert model.forward((0.0, 0.0, 0.0)) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)


@pytest.mark.parametrize("q, expected", [
    ((0.0, 0.0, math.pi / 2), (0.0, L2, L2)),          # link 2 swung forward, level
    ((0.0, math.pi / 2, 0.0), (0.0, L1, -L1)),          # link 1 straight up
    ((math.pi / 2, 0.0, 0.0), (L1, 0.0, -L1)),          # base turned a quarter
])
def test_forward_kinematics_matches_the_published_equations(q, expected):
    assert model.forward(q) == pytest.approx(expected, abs=1e-12)


@given(joint)
def test_inverse_undoes_forward(q):
    p = model.forward(q)
    assume(q[2] - math.pi / 2 - q[1] < -1e-3)  # the elbow bent as at home: the branch inverse() picks
    assert model.inverse(p) == pytest.approx(q, abs=1e-9)


@given(joint)
def test_jacobian_matches_finite_differences(q):
    h = 1e-6
    jac = model.jacobian(q)
    for j in range(3):
        plus = list(q); plus[j] += h
        minus = list(q); minus[j] -= h
        numeric = [(a - b) / (2 * h) for a, b in zip(model.forward(plus), model.forward(minus))]
        assert [row[j] for row in jac] == pytest.approx(numeric, abs=1e-6)


@given(joint, st.tuples(*[st.floats(-5, 5)] * 3))
def test_torques_are_the_transposed_jacobian_times_force(q, force):
    # Virtual work: tau . dq == F . dp for a small joint motion.
    dq = (1e-7, -2e-7, 1.5e-7)
    tau = model.joint_torques(q, force)
    dp = [a - b for a, b in zip(model.forward([a + d for a, d in zip(q, dq)]), model.forward(q))]
    assert sum(t * d for t, d in zip(tau, dq)) == pytest.approx(sum(f * d for f, d in zip(force, dp)), abs=1e-9)


@pytest.mark.parametrize("p", [(0.0, 0.5, 0.0), (0.0, -0.1, 0.6), (0.0, 0.1695, -0.2095)])
def test_unreachable_points_are_refused_without_nan(p):
    with pytest.raises(model.UnreachableError) as error:
        model.inverse(p)
    assert "nan" not in str(error.value).lower()


def test_joint_limits_are_enforced():
    with pytest.raises(model.UnreachableError, match="joint 1"):
        model.inverse(model.forward((1.3, 0.0, 0.2)))


@given(joint)
def test_encoder_round_trip_is_within_half_a_count(q):
    back = model.counts_to_angles(model.angles_to_counts(q))
    for a, b, step in zip(q, back, model.RAD_PER_COUNT):
        assert abs(a - b) <= step / 2 + 1e-15


def test_encoder_resolution_matches_the_capstan_ratios():
    assert model.RAD_PER_COUNT[0] == pytest.approx(1.15e-4, rel=0.01)
    assert model.RAD_PER_COUNT[1] == pytest.approx(1.37e-4, rel=0.01)


@given(st.tuples(*[st.floats(-0.5, 0.5)] * 3))
def test_current_torque_round_trip_and_clamp(tau):
    assert model.currents_to_torques(model.torques_to_currents(tau)) == pytest.approx(tau, abs=1e-12)
    assert all(abs(i) <= 1.0 for i in model.torques_to_currents((10.0, -10.0, 10.0), limit_a=1.0))


@given(joint)
def test_link2_rotation_is_a_rotation_that_follows_link_2(q):
    r = model.link2_rotation(q)
    for i in range(3):
        for j in range(3):
            dot = sum(r[i][k] * r[j][k] for k in range(3))
            assert dot == pytest.approx(1.0 if i == j else 0.0, abs=1e-12)
    t1, _, t3 = q
    link = (math.sin(t1) * math.sin(t3), -math.cos(t3), math.cos(t1) * math.sin(t3))
    down = (0.0, -1.0, 0.0)
    assert [sum(r[i][k] * down[k] for k in range(3)) for i in range(3)] == pytest.approx(link, abs=1e-12)


@given(joint, joint, st.tuples(*[st.floats(-10, 10)] * 3))
def test_tilt_transforms_are_inverse(q, q0, v):
    assert model.tilt_to_base(q, q0, model.base_to_tilt(q, q0, v)) == pytest.approx(v, abs=1e-9)
