"""Fault injection on the simulated bench: every fault latches and stops by its category (IEC 60204-1).

Category 0 (amplifiers, encoders, e-stop) cuts the current within a tick. Category 1 (everything else)
backs the probe out along the tissue normal, parks the arm at its rest pose and only then powers off,
so the tissue is never pressed harder nor slid across after the fault. After any fault, reset and the
next scan bring the arm back, without a new simulator.
"""
import math

import pytest

from drivers.sim.faults import RigidObject, stall
from drivers.sim.scene import Scene
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.palpation import Palpation
from palpd.control.safety import CATEGORY_0, stop_category
from palpd.control.tasks import MoveTo
from palpd.errors import ConfigError, ScanFault
from palpd.scan import FixedPlan, run_scan

CAP_N = 6.0
SLIDE_MM = 0.5  # lateral motion allowed while the probe still touches the tissue after a fault


class Watch:
    """Spies on a bench: when the motors were cut, the force commanded, and the truth after the fault."""

    def __init__(self, bench):
        self.bench, self.cut_at_s, self.max_commanded_n, self.forces_n = bench, None, 0.0, []
        self.inject_at_s, self.inject = math.inf, None
        self.after = []  # (true contact force, true tip) at every physics step once a fault is latched
        robot, disable = bench.servo.robot, bench.servo.robot.disable

        def disable_and_note():
            disable()
            if self.cut_at_s is None:
                self.cut_at_s = bench.clock.now()
                self.in_stand_when_cut = bench.world.in_stand

        robot.disable = disable_and_note
        bench.servo.tick_hook = self._tick
        bench.world.step_hook = self._step

    def _tick(self, tick):
        self.max_commanded_n = max(self.max_commanded_n, self.bench.servo.controller.last_force_n)
        self.forces_n.append(math.dist(tick.force_tissue_n, (0, 0, 0)))
        if tick.t_s >= self.inject_at_s and self.inject is not None:
            self.inject(self.bench)
            self.inject = None

    def _step(self, world):
        if self.bench.servo.fault is not None:
            self.after.append((world.contact_force_n, world.tip_mm()))

    def no_press_nor_slide_after_the_fault(self) -> None:
        forces = [f for f, _ in self.after]
        assert max(forces) <= forces[0] + 0.05  # never pressed harder than when it faulted
        touching = [tip for f, tip in self.after if f > 0.0]
        if touching:
            assert max(math.dist(tip[:2], touching[0][:2]) for tip in touching) < SLIDE_MM


def started_bench(k=0.12, **scene):
    settings = Settings().updated(safety={"force_cap_n": CAP_N})
    bench = open_simulated_bench(settings, Scene(name="f", tissue={"stiffness_n_per_mm": k}, **scene))
    bench.servo.start()
    bench.servo.run(MoveTo((0.0, 0.0, 4.0), 80.0, 2000.0))
    return settings, bench


def freeze(b): b.world.faults.sensor_frozen = True
def nan(b): b.world.faults.nan_samples = True
def jump(b): b.world.faults.encoder_jump_counts = (0, 400, 0)
def amplifier(b): b.world.faults.amplifier_fault = True
def estop_button(b): b.world.press_estop()
def estop_command(b): b.servo.request_estop()
def loop_stall(b): stall(b.clock, Settings().safety.max_tick_gap_s + 0.01)


def later(bench, seconds):
    """Let simulated time pass with the motors off (the world advances on the bench's clock)."""
    bench.clock.sleep_until(bench.clock.now() + seconds)
    bench.world.advance_to(bench.clock.now())


def palpate_with(inject, k=0.12):
    """Press at the tissue centre and inject mid-indentation; returns (settings, bench, watch)."""
    settings, bench = started_bench(k)
    watch = Watch(bench)
    # ~3 mm into the indentation: from 2 mm above the surface the approach goes at the 10 mm/s indentation speed
    watch.inject_at_s, watch.inject = bench.clock.now() + 0.62, inject
    with pytest.raises(ScanFault):
        bench.servo.run(Palpation((0.0, 0.0), settings.palpation))
    return settings, bench, watch


@pytest.mark.parametrize("inject, code", [
    (jump, "encoder_jump"), (amplifier, "amplifier_fault"), (estop_button, "estop"), (estop_command, "estop"),
])
def test_category_0_faults_cut_the_current_within_a_tick_and_latch(inject, code):
    _, bench, watch = palpate_with(inject)
    fault = bench.servo.fault
    assert fault.code == code and fault.category == 0 and "at once" in fault.stop
    assert watch.cut_at_s - fault.t_s <= 2 * bench.servo.period_s + 1e-9  # the reading is a period old
    assert bench.world.amplifiers_on is False and bench.world.currents_a == (0.0, 0.0, 0.0)
    assert watch.max_commanded_n <= CAP_N
    assert len(fault.last_samples) > 0 and fault.as_dict()["last_samples"][-1]["t_s"] <= fault.as_dict()["t_s"]
    with pytest.raises(ScanFault, match="reset first"):
        bench.servo.run(MoveTo((0.0, 0.0, 10.0), 20.0, 2000.0))


@pytest.mark.parametrize("inject, code", [(freeze, "sensor_frozen"), (nan, "invalid_sample"), (loop_stall, "loop_stall")])
def test_category_1_faults_back_out_park_at_rest_and_only_then_power_off(inject, code):
    settings, bench, watch = palpate_with(inject, k=0.6)  # stiff tissue: pressing ~2.4 N when it faults
    fault = bench.servo.fault
    assert fault.code == code and fault.category == 1 and "parked" in fault.stop
    assert max(watch.forces_n) > 1.0  # it really was pressing when the fault came
    watch.no_press_nor_slide_after_the_fault()
    assert watch.in_stand_when_cut and bench.world.in_stand  # powered off in its stand, clear of the tissue
    assert watch.cut_at_s - fault.t_s <= settings.safety.retract_timeout_s + 3.0
    parked = bench.world.tip_mm()
    later(bench, 1.0)
    assert bench.world.tip_mm() == parked and bench.world.contact_force_n == 0.0  # and it stays there
    with pytest.raises(ScanFault, match="reset first"):
        bench.servo.run(MoveTo((0.0, 0.0, 10.0), 20.0, 2000.0))


def test_a_hidden_rigid_object_trips_the_cap_and_the_arm_backs_out_and_parks():
    settings, bench = started_bench()
    bench.world.faults.rigid_objects.append(RigidObject((0.0, 0.0), 5.0, depth_mm=2.0))
    watch = Watch(bench)
    with pytest.raises(ScanFault, match="force_cap"):  # a runaway setpoint, deep into the tissue
        bench.servo.run(MoveTo((0.0, 0.0, -15.0), 20.0, 2000.0))
    one_tick_rise_n = max(b - a for a, b in zip(watch.forces_n, watch.forces_n[1:]))
    assert max(watch.forces_n) <= CAP_N + max(one_tick_rise_n, 0.05)
    assert bench.world.max_contact_force_n <= CAP_N + 2 * max(one_tick_rise_n, 0.05)  # the truth, every step
    assert watch.max_commanded_n <= CAP_N
    watch.no_press_nor_slide_after_the_fault()
    assert watch.in_stand_when_cut and bench.servo.fault.category == 1
    bench.servo.reset()
    bench.servo.start()  # an explicit reset re-arms it
    bench.servo.run(MoveTo((10.0, 0.0, 4.0), 20.0, 2000.0))


def test_pushing_on_something_rigid_at_the_cap_is_rigid_contact_from_measured_force():
    settings, bench = started_bench(k=2.0, sensor={"noise_n": 0.0})  # the cap's force balances it, the tip stops
    # Isolating the rigid check needs a noise-free sensor: with any noise the force measured at the cap crosses
    # it now and then and force_cap (the same category-1 stop) comes first, and a noise-free sensor is, by
    # design, a frozen one (sensor health). So: no conversion noise, and no health monitor, in this test only.
    bench.servo.sensor.source._adc_noise_v = 0.0
    for monitor in bench.servo.supervisor.monitors:
        bench.servo.supervisor.checks.remove(monitor.check)
    with pytest.raises(ScanFault, match="rigid_contact"):
        bench.servo.run(MoveTo((0.0, 0.0, -15.0), 5.0, 2000.0))
    fault = bench.servo.fault
    assert "measured" in fault.message and fault.category == 1 and "parked" in fault.stop
    assert bench.world.max_contact_force_n <= CAP_N + 0.05


class Grip:
    """A hand holding the arm still (the simulator lets a hand override the motors)."""

    def __init__(self, q):
        self.q = q

    def q_at(self, t_s):
        return self.q


def test_a_controller_that_cannot_follow_is_a_tracking_error_not_a_rigid_or_speed_fault():
    settings, bench = started_bench()
    bench.world.hand = Grip(tuple(bench.world.arm.q))
    with pytest.raises(ScanFault, match="tracking_error"):
        bench.servo.run(MoveTo((25.0, 0.0, 4.0), 80.0, 2000.0))
    fault = bench.servo.fault
    assert fault.category == 1 and "cut" in fault.stop  # it could not back out either: the hand holds it
    assert fault.t_s - fault.last_samples[0][0] < 1.0


def test_after_a_category_0_stop_the_next_scan_brings_the_arm_home_first():
    """The e-stop drops the arm onto the tissue (nothing holds it unpowered); after releasing the button and a
    reset, a scan on the same simulated bench lifts it off, parks it, and palpates as ever."""
    settings, bench, _ = palpate_with(estop_button)
    later(bench, 1.0)
    assert not bench.world.in_stand  # it fell
    bench.world.estop = False  # the operator releases the button
    bench.servo.reset()
    report = run_scan(bench, settings, FixedPlan([(10.0, 10.0)]))
    assert report["faults"] == [] and report["probes"][0]["stiffness_n_per_mm"] == pytest.approx(0.12, rel=0.05)
    assert bench.world.in_stand and not bench.world.amplifiers_on  # parked at the end


def test_every_fault_code_has_its_stop_category():
    assert CATEGORY_0 == {"estop", "amplifier_fault", "watchdog", "over_temperature", "encoder_jump", "robot_link"}
    for code in ("force_cap", "rigid_contact", "tracking_error", "loop_stall", "stale_sample", "invalid_sample",
                 "saturated", "joint_limit", "workspace", "speed", "task_timeout", "sensor_link", "servo_lost",
                 "sensor_frozen", "sensor_drift", "indentation", "storage"):
        assert stop_category(code) == 1


def test_a_force_cap_above_the_sensor_range_is_refused_at_start_up():
    from drivers.geometry import TissueFrame
    from palpd.control.limits import refuse_unsafe_configuration

    with pytest.raises(ConfigError, match="at most 8.5 N; the Phantom Premium 1.5A's peak tip force"):
        Settings().updated(safety={"force_cap_n": 30.0})  # beyond what the arm can push: refused when read
    frame = TissueFrame(tuple(v / 1000.0 for v in Settings().tissue.origin_mm))
    with pytest.raises(ConfigError, match="force_cap_n = 6.0 N is not below the force sensor's range of 5.0 N"):
        refuse_unsafe_configuration(Settings(), frame, force_range_n=(5.0, 5.0, 5.0))  # a smaller sensor


def test_tissue_out_of_reach_is_refused_at_start_up():
    scene = Scene(name="far", placement={"origin_mm": (0.0, -60.0, 60.0)})  # centre reachable, near edge not
    with pytest.raises(ConfigError, match="outside the arm's reach"):
        open_simulated_bench(Settings(), scene)


def test_a_rest_pose_not_clear_of_the_tissue_is_refused_at_start_up():
    scene = Scene(name="high", placement={"origin_mm": (0.0, 2.0, 0.0)})  # the tissue 2 mm below home
    with pytest.raises(ConfigError, match="rest pose"):
        open_simulated_bench(Settings(), scene)


def test_a_reset_with_the_bridge_gone_names_the_lost_link_not_the_loop():
    """Issue 51: after the robot link dropped, the reset's homing (start: amplifiers on) raised the driver's
    error out of the servo loop, and the daemon met it as servo_lost ("no heartbeat for 5 s")."""
    bench = open_simulated_bench(Settings(), Scene(name="t", tissue={"stiffness_n_per_mm": 0.12}))
    servo = bench.servo
    servo.start()
    servo.robot.transport.unplugged = True  # the bridge's cable comes out
    with pytest.raises(ScanFault, match="robot_link"):
        servo.run(MoveTo((0.0, 0.0, 10.0), 80.0, 2000.0))
    servo.reset()  # what the daemon's reset does, then its homing starts the amplifiers
    with pytest.raises(ScanFault, match="robot_link: robot link lost: .*unplugged"):
        servo.start()
    assert servo.fault.code == "robot_link" and servo.fault.category == 0 and not servo.motors_on


def test_a_push_into_soft_tissue_stops_at_the_depth_bound_whatever_the_force_reads():
    """Issue 51: depth is bounded by position. A setpoint run deep into 0.12 N/mm tissue never reads near the cap
    (0.6 N at 5 mm); the tip stops at depth_mm plus the margin below the surface, as an `indentation` fault."""
    settings = Settings()
    bench = open_simulated_bench(settings, Scene(name="soft", tissue={"stiffness_n_per_mm": 0.12}))
    bench.servo.start()
    bench.servo.run(MoveTo((0.0, 0.0, 2.0), 80.0, 2000.0))
    with pytest.raises(ScanFault, match="indentation: tip 4.7"):
        bench.servo.run(MoveTo((0.0, 0.0, -15.0), 10.0, 2000.0))
    assert bench.servo.fault.category == 1 and "parked" in bench.servo.fault.stop
    assert bench.servo.max_contact_force_n < 1.0  # the force cap would never have stopped it
    assert bench.world.max_indentation_mm <= settings.palpation.depth_mm + 1.0


def test_a_press_ends_where_its_setpoint_would_bring_the_tip_to_rest():
    """surface.at_floor: the setpoint's depth counts less the lead the tissue's push surely holds the tip above
    it (the force above 3 sds of the measured noise, over the servo's stiffness); none before the noise is known."""
    from types import SimpleNamespace

    from palpd.control.contact import SensorNoise
    from palpd.control.surface import FLOOR_CLEARANCE_MM, at_floor, held_lead_mm

    noise = SensorNoise(0.05, 0.0, 200)
    assert held_lead_mm(2.0, None, 1.5) == 0.0  # no noise measured yet: nothing counted
    assert held_lead_mm(0.1, noise, 1.5) == 0.0  # within 3 sds of the noise: nothing surely pushes
    assert held_lead_mm(2.0, noise, 1.5) == pytest.approx((2.0 - 0.15) / 1.5)
    floor = -4.75

    def tick(tip_z, setpoint_z, lead):
        return SimpleNamespace(tip_mm=(0.0, 0.0, tip_z), setpoint_mm=(0.0, 0.0, setpoint_z), held_lead_mm=lead,
                               floor_z_mm=floor)

    # a stiff spot: the setpoint past the floor, and the push holds the tip 0.2 mm above the clearance
    assert not at_floor(tick(-4.3, -5.6, 1.3))
    assert at_floor(tick(-4.3, -5.6, 0.0))  # no push to hold it: the tip would follow the setpoint through
    assert at_floor(tick(floor + FLOOR_CLEARANCE_MM, -4.0, 0.0))  # the tip itself at the floor
    assert at_floor(tick(-4.3, -5.6, 1.3), speed_mm_s=40.0)  # a fast press ends sooner: the tip's stopping


def test_the_surface_is_refined_by_finished_palpations_near_them_only():
    from palpd.control.palpation import PalpationRecord
    from palpd.control.surface import SurfaceGuard

    settings = Settings()
    guard = SurfaceGuard(settings.palpation, settings.safety)
    limit = settings.palpation.depth_mm + settings.safety.indentation_margin_mm
    assert guard.floor_z_mm((0.0, 0.0, 0.0)) == -limit  # the registered surface, z = 0
    guard.learn(type("Done", (), {"record": PalpationRecord((10.0, 0.0), contact_z_mm=-1.5)})())
    assert guard.floor_z_mm((12.0, 0.0, 0.0)) == -1.5 - limit  # near a contact point: that surface
    assert guard.floor_z_mm((-10.0, 0.0, 0.0)) == -limit  # far from it: the registration
    guard.forget()
    assert guard.floor_z_mm((12.0, 0.0, 0.0)) == -limit
