"""Motor torque limits and the I²t thermal limit, alone and as the bridge driver applies them to every write."""
import math

import pytest
from hypothesis import given, strategies as st

import drivers
from drivers.clock import VirtualClock
from drivers.phantom import model
from drivers.sim.scene import Scene
from drivers.sim.world import SimWorld

TICK_S = 0.001
BUDGET_S = model.PEAK_DURATION_S  # how long the peak current lasts from cold


def run_at(limit: model.ThermalLimit, currents, seconds: float):
    """Command currents every tick for seconds; the last output."""
    out = None
    for _ in range(round(seconds / TICK_S)):
        out = limit.limit(currents, TICK_S)
    return out


def test_torque_limits_follow_the_motor_ratings_through_the_capstans():
    for joint in range(3):
        nominal, peak = model.torque_limits_nm(joint)
        assert nominal == pytest.approx(model.NOMINAL_CURRENT_A * model.MOTOR_KT_NM_PER_A * model.CAPSTAN_RATIO[joint])
        assert peak / nominal == pytest.approx(model.PEAK_CURRENT_A / model.NOMINAL_CURRENT_A)
    assert model.torque_limits_nm(0)[1] == pytest.approx(5.5 * 0.0234 * 13.3)  # 1.71 N·m at joint 1


def test_the_peak_lasts_its_budget_from_cold_then_only_nominal():
    limit = model.ThermalLimit()
    assert run_at(limit, (9.0, -9.0, 0.5), BUDGET_S - 0.01) == (5.5, -5.5, 0.5)  # clamped to the peak, not yet hot
    assert not limit.limited()
    assert run_at(limit, (9.0, -9.0, 0.5), 0.02) == (1.24, -1.24, 0.5)  # budget spent on joints 1, 2 only
    assert limit.limited()


def test_cooling_below_nominal_buys_back_peak_time_in_proportion():
    limit = model.ThermalLimit()
    run_at(limit, (5.5, 0.0, 0.0), BUDGET_S + 0.01)
    assert limit.limit((5.5, 0.0, 0.0), TICK_S)[0] == 1.24  # hot
    # idle, the winding sheds nominal^2 per second: a full budget takes budget / nominal^2 seconds
    cool_s = limit.budget_a2s / model.NOMINAL_CURRENT_A ** 2
    assert run_at(limit, (0.0, 0.0, 0.0), 0.5 * cool_s) == (0.0, 0.0, 0.0)
    assert run_at(limit, (5.5, 0.0, 0.0), 0.45 * BUDGET_S)[0] == 5.5  # half the budget back: half the peak time
    assert run_at(limit, (5.5, 0.0, 0.0), 0.1 * BUDGET_S)[0] == 1.24


def test_a_limit_below_nominal_is_a_hard_cap_hot_or_cold():
    limit = model.ThermalLimit(peak_a=0.8)
    assert run_at(limit, (3.0, -3.0, 0.7), 5.0) == (0.8, -0.8, 0.7)


@given(st.tuples(*[st.floats(allow_nan=True, allow_infinity=True)] * 3),
       st.floats(min_value=0.0, max_value=10.0), st.floats(min_value=0.1, max_value=5.5))
def test_output_is_finite_within_the_cap_and_never_pushes_harder(currents, dt_s, peak_a):
    limit = model.ThermalLimit(peak_a=peak_a)
    for _ in range(3):
        out = limit.limit(currents, dt_s)
        for asked, given_a in zip(currents, out):
            assert math.isfinite(given_a) and abs(given_a) <= peak_a
            assert given_a == 0.0 if math.isnan(asked) else (abs(given_a) <= abs(asked) and given_a * asked >= 0)
        assert all(0.0 <= h <= limit.budget_a2s for h in limit.heat_a2s)


def _bridge_robot(current_limit_a: float = model.PEAK_CURRENT_A):
    world = SimWorld(Scene(name="t", tissue={"stiffness_n_per_mm": 0.2}), VirtualClock())
    robot = drivers.open_robot("sim://", world=world, clock=world.clock, current_limit_a=current_limit_a)
    robot.enable()
    return world, robot


def _write_for(world, robot, currents, seconds: float) -> None:
    for _ in range(round(seconds / TICK_S)):
        world.clock.sleep_until(world.clock.now() + TICK_S)
        robot.write(currents)


def test_bridge_writes_reach_the_motors_clamped_and_thermally_limited():
    world, robot = _bridge_robot()
    _write_for(world, robot, (9.0, 0.5, -9.0), 0.1)
    assert world.currents_a == pytest.approx((5.5, 0.5, -5.5))
    _write_for(world, robot, (9.0, 0.5, -9.0), BUDGET_S)
    assert world.currents_a == pytest.approx((1.24, 0.5, -1.24))  # what reached the simulated amplifiers
    robot.write((math.nan, 0.2, 0.0))
    assert world.currents_a == pytest.approx((0.0, 0.2, 0.0))


def test_the_configured_current_limit_caps_bridge_writes():
    world, robot = _bridge_robot(current_limit_a=2.0)
    _write_for(world, robot, (3.0, -3.0, 1.5), 0.05)
    assert world.currents_a == pytest.approx((2.0, -2.0, 1.5))
