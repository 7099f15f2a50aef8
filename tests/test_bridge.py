"""The host bridge driver against the simulated bridge over sim://, TCP (socket://) and a pty (serial://)."""
import threading
import time

import pytest

import drivers
from drivers.clock import RealClock, VirtualClock
from drivers.errors import DriverInitializationError, DriverOperationError, DriverTimeoutError
from drivers.interfaces import STATUS_AMPLIFIERS_ON, STATUS_HOLDING, STATUS_WATCHDOG_TRIPPED
from drivers.phantom import codec, model
from drivers.phantom.bridge import open_bridge_robot
from drivers.sim.bridge_device import BridgeDevice
from drivers.sim.scene import Scene
from drivers.sim.servers import PtyBridgeEndpoint, SimulatorHost, TcpBridgeEndpoint
from drivers.sim.world import SimWorld

TIMEOUT_S = 0.1


def make_world(clock):
    return SimWorld(Scene(name="t", tissue={"stiffness_n_per_mm": 0.2}), clock)


def braked(world, hold):
    """The hold currents plus the brake a silent host's hold adds for the arm's present speed (PROTOCOL.md): the
    hold (0.45 A on joint 2) is not gravity compensation here, so the arm moves, and the brake acts on it."""
    from drivers.sim.bridge_device import brake_currents

    return tuple(h + b for h, b in zip(hold, brake_currents(world.arm.qd)))


@pytest.fixture(params=["tcp", "pty"])
def served(request):
    """(host, endpoint) with the simulator serving in a thread; stopped and closed afterwards."""
    host = SimulatorHost(make_world(RealClock()))
    endpoint = host.add(TcpBridgeEndpoint(host.device) if request.param == "tcp" else PtyBridgeEndpoint(host.device))
    stop = threading.Event()
    thread = threading.Thread(target=host.serve, args=(stop,), daemon=True)
    thread.start()
    yield host, endpoint
    stop.set()
    thread.join(2)
    host.close()


def test_currents_reach_the_simulated_motors_and_encoders_come_back(served):
    host, endpoint = served
    # The hold comes after 0.5 s of silence, not the default 1.5 ms: a test process preempted between the
    # command and its check (a busy machine) would otherwise see the hold instead of the command.
    with open_bridge_robot(endpoint.url, timeout_s=TIMEOUT_S, hold_after_s=0.5) as robot:
        robot.enable()
        robot.write((0.0, 0.4, 0.0), (0.0, 0.45, 0.0))
        robot.read()  # the command's reply: the state as the bridge applied it
        assert host.world.currents_a == pytest.approx((0.0, 0.4, 0.0))
        time.sleep(0.6)  # a silent host: the bridge ramps to the hold the command carried
        state = robot.read()
        assert state.status & STATUS_AMPLIFIERS_ON and state.status & STATUS_HOLDING
        assert host.world.currents_a == pytest.approx(braked(host.world, (0.0, 0.45, 0.0)), abs=0.005)
        assert 0 < state.device_t_s <= host.world.t_s and all(isinstance(c, int) for c in state.counts)
        robot.write((0.0, 0.3, 0.0))  # a command ends the hold
        assert not robot.read().status & STATUS_HOLDING and host.world.currents_a == pytest.approx((0.0, 0.3, 0.0))
        robot.disable()
        assert robot.read().status & STATUS_AMPLIFIERS_ON == 0
        assert host.world.currents_a == (0.0, 0.0, 0.0)


def test_the_bridge_watchdog_holds_first_then_cuts_the_motors_when_the_host_goes_silent(served):
    host, endpoint = served
    with open_bridge_robot(endpoint.url, timeout_s=TIMEOUT_S, watchdog_s=0.2) as robot:
        robot.enable()
        robot.write((0.3, 0.3, 0.3), (0.0, 0.45, 0.0))
        time.sleep(0.05)  # past the short watchdog: holding, still powered
        assert host.world.amplifiers_on
        assert host.world.currents_a == pytest.approx(braked(host.world, (0.0, 0.45, 0.0)), abs=0.005)
        time.sleep(0.4)  # past the long one: cut and latched
        assert host.world.amplifiers_on is False and host.world.currents_a == (0.0, 0.0, 0.0)
        robot.write((0.3, 0.3, 0.3))  # ignored while latched
        assert robot.read().status & STATUS_WATCHDOG_TRIPPED and not host.world.amplifiers_on
        robot.enable()  # enable + clear
        assert robot.read().status & STATUS_WATCHDOG_TRIPPED == 0


def test_the_watchdog_ramps_to_the_hold_in_physics_time_and_the_arm_then_floats():
    """Virtual time: the ramp begins hold_after_s after the last command, lasts hold_ramp_s, and the arm under
    its gravity hold neither falls nor is pushed; watchdog_s after the last frame the power goes."""
    world = make_world(VirtualClock())
    robot = drivers.open_robot("sim://", world=world, clock=world.clock, watchdog_s=1.0, hold_after_s=0.002,
                               hold_ramp_s=0.004)
    currents = []
    world.step_hook = lambda w: currents.append((round(w.t_s, 6), w.currents_a[1], w.tip_mm()))
    robot.enable()
    hold = model.torques_to_currents(tuple(-g for g in model.gravity_torques(model.HOME_Q)))
    robot.write((0.0, 0.6, 0.0), hold)  # held 2 ms as it is, then ramped to gravity compensation
    world.clock.sleep_until(world.clock.now() + 0.9)
    robot.read()  # a READ feeds the cut-off watchdog but does not end the hold
    by_time = dict((t, i) for t, i, _ in currents)
    t0 = currents[0][0] - 0.0005
    assert by_time[round(t0 + 0.002, 6)] == pytest.approx(0.6)
    assert by_time[round(t0 + 0.004, 6)] == pytest.approx(0.6 + 0.5 * (hold[1] - 0.6), abs=0.02)
    assert by_time[round(t0 + 0.0065, 6)] == pytest.approx(hold[1], abs=0.001)  # mA on the wire
    heights = [tip[2] for t, _, tip in currents]
    assert max(heights) - min(heights) < 1.0  # it floats: 0.9 s in the hold, not a millimetre of fall or rise
    world.clock.sleep_until(world.clock.now() + 1.2)
    robot.transport.device.check_watchdog(world.clock.now())
    assert not world.amplifiers_on and robot.transport.device.tripped


def test_a_host_gone_silent_leaves_the_arm_braked_to_rest_not_coasting():
    """Virtual time: a correction in flight when the host dies (20 ms of 0.3 A over gravity on joint 2) sets
    the arm moving; the hold cancels gravity, and from HOLD_DAMP_AFTER_S of silence on it brakes the joints, so
    the arm comes to rest within a few time constants instead of coasting on its light friction."""
    from drivers.sim.bridge_device import HOLD_DAMP_AFTER_S, HOLD_DAMPING_TAU_S

    world = make_world(VirtualClock())
    robot = drivers.open_robot("sim://", world=world, clock=world.clock, watchdog_s=5.0)
    robot.enable()
    for _ in range(20):
        hold = model.torques_to_currents(tuple(-g for g in model.gravity_torques(tuple(world.arm.q))))
        robot.write((hold[0], hold[1] + 0.3, hold[2]), hold)
        world.clock.sleep_until(world.clock.now() + 0.001)
    last_command_s = world.t_s
    samples = []
    world.step_hook = lambda w: samples.append((w.t_s - last_command_s, abs(w.arm.qd[1]), w.tip_mm()))
    world.clock.sleep_until(world.clock.now() + 0.5)
    robot.read()
    moving = max(speed for t, speed, _ in samples if t <= HOLD_DAMP_AFTER_S)
    assert moving > 0.05  # rad/s: the correction did set it moving
    settled = HOLD_DAMP_AFTER_S + 8 * HOLD_DAMPING_TAU_S
    assert max(speed for t, speed, _ in samples if t >= settled) < 0.01 * moving
    tips = [tip for t, _, tip in samples if t >= settled]
    assert max(abs(a - b) for a, b in zip(tips[0], tips[-1])) < 0.05  # mm: at rest, not coasting


def test_a_stalled_bridge_is_detected_within_one_timeout(served):
    host, endpoint = served
    with open_bridge_robot(endpoint.url, timeout_s=TIMEOUT_S) as robot:
        host.device.stalled = True
        started = time.monotonic()
        with pytest.raises(DriverTimeoutError, match="did not answer within 100 ms"):
            robot.read()
        assert time.monotonic() - started < TIMEOUT_S + 0.05
        host.device.stalled = False
        robot.read()  # the late answers are told apart by their sequence number


def test_an_unplugged_bridge_is_detected_within_one_timeout(served):
    host, endpoint = served
    robot = open_bridge_robot(endpoint.url, timeout_s=TIMEOUT_S)
    robot.read()
    endpoint.unplug()
    started = time.monotonic()
    with pytest.raises((DriverOperationError, DriverTimeoutError)):
        for _ in range(3):  # a TCP reset may surface on the write after the one that fails
            robot.read()
    assert time.monotonic() - started < TIMEOUT_S + 0.1
    robot.transport.close()


def test_corrupted_host_frames_are_counted_and_never_acted_on():
    world = make_world(VirtualClock())
    device = BridgeDevice(world)
    frame = bytearray(codec.encode_command(1, codec.Command(True, True, 250, (1000, 1000, 1000))))
    frame[8] ^= 0x40
    assert device.handle(b"\x00garbage" + bytes(frame)) == b""
    assert world.amplifiers_on is False
    (reply,) = codec.FrameDecoder().feed(device.handle(codec.encode_frame(codec.READ, 2)))
    assert codec.decode_state(reply.payload).rx_errors >= 1


def test_sim_url_goes_through_the_codec_in_process():
    world = make_world(VirtualClock())
    robot = drivers.open_robot("sim://", world=world, clock=world.clock)
    robot.enable()
    robot.write((0.0, 0.5, 0.0))
    assert world.currents_a == (0.0, 0.5, 0.0)
    robot.read()  # collects the command's reply: no second exchange
    assert robot.transport.device.decoder.rejected_frames == 0 and robot.state.ack_seq == robot._seq
    assert robot.exchanges == 3  # the opening READ, the enable, the command


def test_opening_an_absent_device_fails_at_once_naming_it(tmp_path):
    for url, fragment in [("socket://127.0.0.1:1", "127.0.0.1:1"), (f"serial://{tmp_path}/ttyNONE", "ttyNONE"),
                          ("bogus://x", "known schemes")]:
        started = time.monotonic()
        with pytest.raises(DriverInitializationError, match=fragment):
            open_bridge_robot(url, timeout_s=TIMEOUT_S)
        assert time.monotonic() - started < 1.0


def test_bench_drivers_prints_both_paths_side_by_side(run_cli):
    import json

    from conftest import SCENES

    result = run_cli("bench", "drivers", "--scene", SCENES / "paper.toml", "--ticks", "200", "--json")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    assert set(figures) == {"sim:// + DAQ", "sim-direct"}
    assert all(f["ticks"] == 200 and f["cpu_us_per_tick"] > 0 for f in figures.values())
