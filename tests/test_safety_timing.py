"""Safety checks that measure motion over the real time between samples, so a late tick is not a fault."""
import math
from dataclasses import replace

import pytest
from hypothesis import given, settings as hypothesis_settings, strategies as st

from drivers.interfaces import ForceSample
from drivers.phantom import model
from drivers.sim.faults import stall
from drivers.sim.scene import Scene
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.safety import SafetySupervisor
from palpd.control.servo import DEVICE_CLOCK_WRAP_S, Tick
from palpd.control.tasks import MoveTo
from palpd.errors import ScanFault

SLOW_JOINTS_RAD_S = 0.8  # above the ~0.46 rad/s of an 80 mm/s move, below what a 3.5 ms late tick looks like per period
LATE_S = 0.0035  # far shorter than max_tick_gap_s: a descheduled host, not a stalled loop


def moving_bench(**safety):
    settings = Settings().updated(safety={"max_joint_speed_rad_s": SLOW_JOINTS_RAD_S, **safety})
    bench = open_simulated_bench(settings, Scene(name="t"))
    bench.servo.start()
    bench.servo.run(MoveTo((0.0, 0.0, 10.0), 80.0, 2000.0))
    return bench


def run_with(bench, at_tick, inject):
    """Move 25 mm sideways at 80 mm/s, calling inject(bench) once at the given tick; returns the ticks."""
    ticks = []

    def hook(tick):
        ticks.append(tick)
        if len(ticks) == at_tick:
            inject(bench)

    bench.servo.tick_hook = hook
    bench.servo.run(MoveTo((25.0, 0.0, 10.0), 80.0, 2000.0))
    return ticks


def late_tick(bench):
    stall(bench.clock, LATE_S)


def test_a_late_tick_during_fast_motion_is_no_encoder_jump_and_no_speed_spike():
    bench = moving_bench()
    ticks = run_with(bench, 200, late_tick)
    assert bench.servo.fault is None
    before, after = ticks[199], ticks[200]
    step_rad = max(abs(a - b) for a, b in zip(after.q, before.q))
    assert LATE_S < after.gap_s < Settings().safety.max_tick_gap_s  # the stall, the skipped periods, the reading's age
    assert step_rad > SLOW_JOINTS_RAD_S * bench.servo.period_s + max(model.RAD_PER_COUNT)  # one-period rule trips
    speeds = [math.dist(t.velocity_mm_s, (0, 0, 0)) for t in ticks[195:210]]
    assert max(speeds) < 1.3 * 80.0  # the velocity is over the real gap: 3.5x the step is not 3.5x the speed


def test_an_encoder_jump_is_still_caught_within_one_tick_during_the_same_motion():
    bench = moving_bench()
    jumped_at = []

    def jump(b):
        jumped_at.append(b.clock.now())
        b.world.faults.encoder_jump_counts = (0, 40, 0)  # 5.5 mrad: more than 3.5 ms of motion at the limit

    with pytest.raises(ScanFault, match="encoder_jump"):
        run_with(bench, 200, jump)
    assert bench.servo.fault.t_s - jumped_at[0] <= bench.servo.period_s + 1e-9
    assert bench.world.amplifiers_on is False and bench.world.currents_a == (0.0, 0.0, 0.0)


def test_a_gap_longer_than_max_tick_gap_is_still_a_loop_stall():
    bench = moving_bench()
    with pytest.raises(ScanFault, match="loop_stall"):
        run_with(bench, 200, lambda b: stall(b.clock, Settings().safety.max_tick_gap_s + 0.001))


def test_the_bridges_wrapping_device_clock_gives_the_sample_gap():
    bench = moving_bench()
    robot, read = bench.servo.robot, bench.servo.robot.read
    offset_s = DEVICE_CLOCK_WRAP_S - bench.clock.now() - 0.1  # the 32-bit microsecond counter wraps mid-move
    robot.read = lambda: (lambda s: replace(s, device_t_s=(s.t_s + offset_s) % DEVICE_CLOCK_WRAP_S))(read())
    ticks = run_with(bench, 200, late_tick)
    assert bench.servo.fault is None and len(ticks) > 250
    assert all(t.sample_gap_s == pytest.approx(t.gap_s, abs=1e-6) for t in ticks[1:])
    assert max(t.sample_gap_s for t in ticks) > LATE_S


def supervisor():
    return SafetySupervisor(Settings().safety, (60.0, 60.0), period_s=0.001)


def tick_at(t_s, q, gap_s):
    sample = ForceSample(t_s, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    return Tick(t_s, q, (0.0, 0.0, 10.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, sample, 0, gap_s, gap_s)


@hypothesis_settings(max_examples=200, deadline=None)
@given(gap_s=st.floats(0.0002, 0.005), fraction=st.floats(-0.99, 0.99), joint=st.integers(0, 2))
def test_motion_within_the_joint_speed_limit_over_any_legal_gap_passes(gap_s, fraction, joint):
    check = supervisor()
    limit = Settings().safety.max_joint_speed_rad_s
    q = [0.1, 0.3, 0.2]
    assert check.check(tick_at(1.0, tuple(q), 0.001)) is None
    q[joint] += fraction * limit * max(gap_s, 0.001)
    assert check.check(tick_at(1.0 + gap_s, tuple(q), gap_s)) is None


@hypothesis_settings(max_examples=200, deadline=None)
@given(gap_s=st.floats(0.0, 0.005), sign=st.sampled_from((-1, 1)), joint=st.integers(0, 2))
def test_a_jump_beyond_the_longest_legal_gap_is_always_caught(gap_s, sign, joint):
    check = supervisor()
    safety = Settings().safety
    q = [0.1, 0.3, 0.2]
    assert check.check(tick_at(1.0, tuple(q), 0.001)) is None
    q[joint] += sign * 1.01 * (safety.max_joint_speed_rad_s * safety.max_tick_gap_s + model.RAD_PER_COUNT[joint])
    fault = check.check(tick_at(1.0 + gap_s, tuple(q), gap_s))
    assert fault is not None and fault.code == "encoder_jump"


def pressing_tick(t_s, force_n, tip_mm=(0.0, 0.0, -3.0), commanded_n=None, gap_s=0.001, lost_s=0.0):
    cap = Settings().safety.force_cap_n
    sample = ForceSample(t_s, (0.0, 0.0, force_n), (0.0, 0.0, 0.0))
    return Tick(t_s, (0.1, 0.3, 0.2), tip_mm, (0.0, 0.0, 0.0), (0.0, 0.0, force_n), force_n, sample, 0, gap_s,
                gap_s, t_s, tip_mm, cap if commanded_n is None else commanded_n, lost_s)


def first_fault(check, ticks):
    return next((f for f in map(check.check, ticks) if f is not None), None)


def test_commanding_the_cap_while_the_sensor_reads_nothing_is_no_rigid_contact():
    """The old rule named an instability in free space (0.07 N measured, 60 mm up) rigid contact."""
    check = supervisor()
    assert first_fault(check, [pressing_tick(1.0 + i * 0.001, 0.07) for i in range(1000)]) is None


def test_measured_force_at_the_cap_with_the_tip_still_is_rigid_contact_once_the_window_is_over():
    window_s = Settings().safety.rigid_window_s
    check = supervisor()
    ticks = [pressing_tick(1.0 + i * 0.001, 5.7) for i in range(200)]
    fault = first_fault(check, ticks)
    assert fault.code == "rigid_contact" and fault.t_s == pytest.approx(1.0 + window_s, abs=0.0011)
    moving = [pressing_tick(1.0 + i * 0.001, 5.7, tip_mm=(0.0, 0.0, -3.0 - 0.01 * i)) for i in range(200)]
    assert first_fault(supervisor(), moving) is None  # still sinking in: soft, not rigid (the cap check guards it)


@hypothesis_settings(max_examples=100, deadline=None)
@given(gaps_ms=st.lists(st.floats(0.0, 1.49), min_size=50, max_size=300))
def test_jitter_within_a_period_never_adds_up_to_a_loop_stall(gaps_ms):
    check, t = supervisor(), 1.0
    for gap_ms in gaps_ms:
        t += gap_ms / 1000.0
        assert check.check(pressing_tick(t, 0.0, commanded_n=0.0, gap_s=gap_ms / 1000.0)) is None


def test_isolated_gaps_under_the_limit_pass_and_missed_deadlines_beyond_the_budget_are_a_stall():
    safety = Settings().safety
    check, t = supervisor(), 1.0
    for _ in range(5):  # one late tick a second, just under the limit: ridden out
        for _ in range(1000):
            t += 0.001
            assert check.check(pressing_tick(t, 0.0, commanded_n=0.0)) is None
        gap = safety.max_tick_gap_s - 0.001
        t += gap
        assert check.check(pressing_tick(t, 0.0, commanded_n=0.0, gap_s=gap, lost_s=gap - 0.001)) is None
    fault = check.check(pressing_tick(t + 0.2, 0.0, commanded_n=0.0, gap_s=safety.max_tick_gap_s + 0.001))
    assert fault.code == "loop_stall"
    starved, t, fault = supervisor(), 1.0, None
    while fault is None and t < 3.0:  # 10 ms lost every 11 ms: the budget runs out well within a second
        t += 0.011
        fault = starved.check(pressing_tick(t, 0.0, commanded_n=0.0, gap_s=0.011, lost_s=0.01))
    assert fault.code == "loop_stall" and "deadlines" in fault.message and t < 1.0 + 2 * safety.late_budget_s
