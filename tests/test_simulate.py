"""palpd simulate as its own process, and palpd scan against it over socket:// and Net F/T."""
import json
import os
import time

import pytest

from conftest import SCENES, assert_one_line_error
from remote_bench import bench_config, serve_simulator


@pytest.fixture
def simulator(tmp_path):
    """A `palpd simulate` process with the bridge on TCP and Net F/T; yields its endpoint lines."""
    yield from serve_simulator(tmp_path, "--bridge", "tcp://127.0.0.1:0", "--netft", "127.0.0.1:0")


def test_scan_runs_against_a_separately_started_simulator(simulator, tmp_path, run_cli):
    bench_config(tmp_path / "remote.toml", simulator)
    assert simulator["bridge"].startswith("socket://127.0.0.1:")
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--config", "remote.toml",
                     "--max-palpations", "1", "--report", "r.json")
    assert result.returncode == 0, result.stderr
    assert "[  1/1]" in result.stderr and "1 palpations" in result.stdout
    report = json.loads((tmp_path / "r.json").read_text())
    (probe,) = report["probes"]
    assert probe["xy_mm"] == pytest.approx([0.0, 0.0], abs=0.3) and 0.4 < probe["stiffness_n_per_mm"] < 0.9  # on the lump, felt remotely
    assert report["wall_time_s"] > 0.8 * report["robot_time_s"]  # it really ran on the wall clock


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
