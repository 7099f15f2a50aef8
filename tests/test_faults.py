"""Fault injection on the simulated bench: every fault ends with the motors cut, latched, under the cap."""
import math

import pytest

from drivers.sim.faults import RigidObject, stall
from drivers.sim.scene import Scene
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.palpation import Palpation
from palpd.control.tasks import MoveTo
from palpd.errors import ConfigError, ScanFault

CAP_N = 6.0


class Watch:
    """Spies on a bench through its hooks: when the motors were cut, the largest force commanded and felt."""

    def __init__(self, bench):
        self.bench, self.cut_at_s, self.max_commanded_n, self.forces_n = bench, None, 0.0, []
        robot, disable = bench.servo.robot, bench.servo.robot.disable

        def disable_and_note():
            disable()
            if self.cut_at_s is None:
                self.cut_at_s = bench.clock.now()

        robot.disable = disable_and_note
        bench.servo.tick_hook = self._tick
        self.inject_at_s, self.inject = math.inf, None

    def _tick(self, tick):
        self.max_commanded_n = max(self.max_commanded_n, self.bench.servo.controller.last_force_n)
        self.forces_n.append(math.dist(tick.force_tissue_n, (0, 0, 0)))
        if tick.t_s >= self.inject_at_s and self.inject is not None:
            self.inject(self.bench)
            self.inject = None


def started_bench(k=0.12):
    settings = Settings().updated(safety={"force_cap_n": CAP_N})
    bench = open_simulated_bench(settings, Scene(name="f", tissue={"stiffness_n_per_mm": k}))
    bench.servo.start()
    bench.servo.run(MoveTo((0.0, 0.0, 4.0), 80.0, 2000.0))
    return settings, bench


def freeze(b): b.world.faults.sensor_frozen = True
def nan(b): b.world.faults.nan_samples = True
def jump(b): b.world.faults.encoder_jump_counts = (0, 400, 0)
def amplifier(b): b.world.faults.amplifier_fault = True
def estop_button(b): b.world.press_estop()
def estop_command(b): b.servo.request_estop()
def loop_stall(b): stall(b.clock, 0.02)


@pytest.mark.parametrize("inject, code", [
    (freeze, "sensor_frozen"), (nan, "invalid_sample"), (jump, "encoder_jump"), (amplifier, "amplifier_fault"),
    (estop_button, "estop"), (estop_command, "estop"), (loop_stall, "loop_stall"),
])
def test_each_fault_cuts_the_motors_within_a_tick_and_latches(inject, code):
    settings, bench = started_bench()
    watch = Watch(bench)
    watch.inject_at_s, watch.inject = bench.clock.now() + 0.3, inject  # mid-indentation
    with pytest.raises(ScanFault, match=code):
        bench.servo.run(Palpation((0.0, 0.0), settings.palpation))
    fault = bench.servo.fault
    assert fault.code == code
    assert watch.cut_at_s - fault.t_s <= bench.servo.period_s + 1e-9
    assert bench.world.amplifiers_on is False and bench.world.currents_a == (0.0, 0.0, 0.0)
    assert watch.max_commanded_n <= CAP_N
    assert len(fault.last_samples) > 0 and fault.as_dict()["last_samples"][-1]["t_s"] <= fault.as_dict()["t_s"]
    with pytest.raises(ScanFault, match="reset first"):
        bench.servo.run(MoveTo((0.0, 0.0, 10.0), 20.0, 2000.0))


def test_a_hidden_rigid_object_trips_the_cap_and_the_arm_backs_out_before_the_motors_go_off():
    settings, bench = started_bench()
    bench.world.faults.rigid_objects.append(RigidObject((0.0, 0.0), 5.0, depth_mm=2.0))
    watch = Watch(bench)
    tip_when_cut = []
    disable = bench.servo.robot.disable
    bench.servo.robot.disable = lambda: (tip_when_cut.append(bench.servo.last_tick.tip_mm), disable())
    with pytest.raises(ScanFault, match="force_cap"):  # a runaway setpoint, deep into the tissue
        bench.servo.run(MoveTo((0.0, 0.0, -15.0), 20.0, 2000.0))
    one_tick_rise_n = max(b - a for a, b in zip(watch.forces_n, watch.forces_n[1:]))
    assert max(watch.forces_n) <= CAP_N + max(one_tick_rise_n, 0.05)
    assert watch.max_commanded_n <= CAP_N
    assert tip_when_cut[0][2] >= settings.palpation.clearance_mm - 0.5  # retracted, then cut
    assert watch.cut_at_s - bench.servo.fault.t_s <= settings.safety.retract_timeout_s
    assert bench.world.amplifiers_on is False and bench.servo.fault.code == "force_cap"
    bench.servo.reset()
    bench.servo.start()  # an explicit reset re-arms it
    bench.servo.run(MoveTo((10.0, 0.0, 4.0), 20.0, 2000.0))


def test_a_force_cap_above_the_sensor_range_is_refused_at_start_up():
    from drivers.geometry import TissueFrame
    from palpd.control.safety import refuse_unsafe_configuration

    with pytest.raises(ConfigError, match="at most 8.5 N; the Phantom Premium 1.5A's peak tip force"):
        Settings().updated(safety={"force_cap_n": 30.0})  # beyond what the arm can push: refused when read
    frame = TissueFrame(tuple(v / 1000.0 for v in Settings().tissue.origin_mm))
    with pytest.raises(ConfigError, match="force_cap_n = 6.0 N is not below the force sensor's range of 5.0 N"):
        refuse_unsafe_configuration(Settings(), frame, force_range_n=(5.0, 5.0, 5.0))  # a smaller sensor


def test_tissue_out_of_reach_is_refused_at_start_up():
    scene = Scene(name="far", placement={"origin_mm": (0.0, -60.0, 60.0)})  # centre reachable, near edge not
    with pytest.raises(ConfigError, match="outside the arm's reach"):
        open_simulated_bench(Settings(), scene)


def test_bench_loop_reports_servo_and_bare_loop_timing(run_cli):
    import json

    result = run_cli("bench", "loop", "--seconds", "0.3", "--json")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    for name in ("loop", "bare_loop"):
        loop = figures[name]
        assert loop["rate_hz"] == 1000.0 and 200 <= loop["ticks"] <= 400
        assert set(loop["lateness_us"]) == {"p50", "p99", "p999", "max"} and set(loop["compute_us"]) == {"p50", "p99"}
        assert 0 <= loop["lateness_us"]["p50"] <= loop["lateness_us"]["max"]
    assert figures["loop"]["compute_us"]["p50"] > figures["bare_loop"]["compute_us"]["p50"]


def test_bench_loop_refuses_a_bad_length(run_cli):
    from conftest import assert_one_line_error

    assert_one_line_error(run_cli("bench", "loop", "--seconds", "-1"), "--seconds")


def test_bench_hotpath_prints_plain_float_and_numpy_figures_for_the_same_math(run_cli):
    import json

    result = run_cli("bench", "hotpath", "--ticks", "300", "--json")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    assert figures["ticks"] == 300 and figures["plain_floats_us_per_tick"] > 0 and figures["numpy_us_per_tick"] > 0
    assert figures["max_current_difference_a"] < 1e-9  # the two versions compute the same currents


def test_bench_hotpath_refuses_a_bad_tick_count(run_cli):
    from conftest import assert_one_line_error

    assert_one_line_error(run_cli("bench", "hotpath", "--ticks", "5"), "--ticks")
