"""palpd simulate as its own process, and palpd scan against it over socket:// and Net F/T."""
import json
import os
import signal
import time

import pytest

from conftest import SCENES, assert_one_line_error
from palpd.errors import EXIT_UNDETERMINED
from remote_bench import bench_config, serve_simulator


@pytest.fixture(scope="module")
def simulator(tmp_path_factory):
    """One `palpd simulate` for the module (bridge on TCP, Net F/T): scans run against it one after another,
    as against a bench that stays on."""
    yield from serve_simulator(tmp_path_factory.mktemp("sim"), "--bridge", "tcp://127.0.0.1:0", "--netft",
                               "127.0.0.1:0")


def test_scan_runs_against_a_separately_started_simulator(simulator, tmp_path, run_cli):
    assert simulator["bridge"].startswith("socket://127.0.0.1:")
    bench_config(tmp_path / "remote.toml", simulator)
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--config", "remote.toml", "--strategy", "raster",
                     "--max-palpations", "1", "--report", "r.json")
    assert result.returncode == EXIT_UNDETERMINED, result.stderr  # one reading decides no count of lumps
    assert "[  1/1]" in result.stderr and "1 palpations" in result.stdout
    report = json.loads((tmp_path / "r.json").read_text())
    (probe,) = report["probes"]
    assert probe["xy_mm"] == pytest.approx([0.0, 0.0], abs=0.3) and 0.4 < probe["stiffness_n_per_mm"] < 0.9  # on the lump, felt remotely
    assert report["wall_time_s"] > 0.8 * report["robot_time_s"]  # it really ran on the wall clock
    assert "max_contact_force_n" not in report["truth"]  # the truth is in the other process: not claimed


def test_a_killed_servo_process_leaves_the_arm_in_the_bridges_gravity_hold_and_the_next_scan_runs(
        simulator, tmp_path):
    """kill -9 of the servo child mid-air: the bridge's short watchdog ramps to the gravity hold the last command
    carried (not the last current for 250 ms, not a fall); a new scan takes over without a new simulator."""
    from drivers.interfaces import STATUS_AMPLIFIERS_ON, STATUS_HOLDING
    from drivers.phantom import model
    from drivers.phantom.bridge import open_bridge_robot
    from drivers.sim.scene import load_scene
    from palpd.config import load_settings
    from palpd.control.remote import open_servo_bench
    from palpd.control.tasks import HoldAndCollect, MoveTo

    settings = load_settings(bench_config(tmp_path / "remote.toml", simulator))
    bench = open_servo_bench(settings, load_scene(SCENES / "paper.toml"))
    try:
        bench.servo.start()
        bench.servo.run(MoveTo((10.0, 10.0, 20.0), 80.0, 2000.0))  # 16 mm above the tissue
        bench.servo.run(HoldAndCollect(200))  # still there (the hold settles it), and killed right after
        os.kill(bench.servo.pid, signal.SIGKILL)
        bench.servo.process.join(5)
    finally:
        bench.servo.close()
    observer = open_bridge_robot(simulator["bridge"], timeout_s=0.2)  # READs only: they command nothing
    try:
        first = observer.read()
        time.sleep(0.3)  # unpowered, the arm would have fallen the 16 mm onto the tissue by now
        later = observer.read()
    finally:
        observer.transport.close()  # (not close(): that would disable the amplifiers, as a host does)
    assert later.status & STATUS_AMPLIFIERS_ON and later.status & STATUS_HOLDING, hex(later.status)
    heights_mm = [1000.0 * bench.frame.from_robot(model.forward(s.angles_rad))[2] for s in (first, later)]
    assert heights_mm[0] > 10.0 and heights_mm[1] > heights_mm[0] - 2.0, heights_mm  # floating, not falling
    again = open_servo_bench(settings, load_scene(SCENES / "paper.toml"))  # the same simulator, still running
    try:
        again.servo.start()  # what a scan does first: takes the arm over and brings it home, supervised
        again.servo.stop()  # parked in its stand, powered off
        assert again.servo.fault is None and again.servo.last_tick.tip_mm[2] > 50.0, (again.servo.fault,
                                                                                     again.servo.last_tick.tip_mm)
    finally:
        again.servo.close()


@pytest.fixture
def pty_simulator(tmp_path):
    yield from serve_simulator(tmp_path, "--bridge", "pty")


def test_simulate_serves_the_bridge_on_a_pty_that_a_serial_client_drives(pty_simulator):
    from drivers.interfaces import STATUS_AMPLIFIERS_ON
    from drivers.phantom.bridge import open_bridge_robot

    url = pty_simulator["bridge"]
    assert url.startswith("serial:///dev/") and os.path.exists(url[len("serial://"):])  # the printed device path
    with open_bridge_robot(url, timeout_s=0.5) as robot:  # pyserial opens the pty as a serial port
        parked = robot.read()
        robot.enable()
        robot.write((0.0, 0.3, 0.0))
        time.sleep(0.05)
        moved = robot.read()
        assert moved.status & STATUS_AMPLIFIERS_ON and moved.device_t_s > parked.device_t_s
        assert moved.counts != parked.counts  # the simulated arm answered the current on joint 2
        robot.disable()
        assert robot.read().status & STATUS_AMPLIFIERS_ON == 0


def test_simulate_refuses_a_bad_bridge_option(run_cli):
    result = run_cli("simulate", "--scene", SCENES / "paper.toml", "--bridge", "udp://x")
    assert_one_line_error(result, "--bridge", "tcp://HOST:PORT or pty")


def test_scan_with_an_absent_bridge_fails_in_one_line(tmp_path, run_cli):
    (tmp_path / "c.toml").write_text('[robot]\nurl = "socket://127.0.0.1:1"\n[sensor]\nbackend = "netft://127.0.0.1:1"\n')
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--config", "c.toml")
    assert_one_line_error(result, "socket://127.0.0.1:1")
