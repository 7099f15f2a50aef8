"""palpd simulate as its own process, and palpd scan against it over socket:// and Net F/T."""
import json
import subprocess
import sys

import pytest

from conftest import SCENES, assert_one_line_error


@pytest.fixture
def simulator(tmp_path):
    """A `palpd simulate` process; yields its endpoint lines; terminated afterwards."""
    process = subprocess.Popen(
        [sys.executable, "-m", "palpd", "simulate", "--scene", str(SCENES / "paper.toml"),
         "--bridge", "tcp://127.0.0.1:0", "--netft", "127.0.0.1:0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    endpoints = {}
    try:
        for line in process.stdout:
            if line.strip() == "ready":
                break
            kind, url = line.split()
            endpoints[kind] = url
        yield endpoints
    finally:
        process.terminate()
        process.wait(5)


def test_scan_runs_against_a_separately_started_simulator(simulator, tmp_path, run_cli):
    # Real time on a shared CI machine without real-time scheduling: generous timeouts and a tolerance for
    # stalls of the test host. What is under test here is the wire path, not the timing (bench loop measures that).
    (tmp_path / "remote.toml").write_text(
        f'[robot]\nurl = "{simulator["bridge"]}"\ntimeout_s = 0.2\n'
        f'[sensor]\nbackend = "{simulator["netft"]}"\ntimeout_s = 0.5\nstale_after_s = 0.1\n'
        '[safety]\nmax_tick_gap_s = 0.5\nmax_tip_speed_mm_s = 2000.0\n')
    assert simulator["bridge"].startswith("socket://127.0.0.1:")
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--config", "remote.toml",
                     "--max-palpations", "1", "--report", "r.json")
    assert result.returncode == 0, result.stderr
    assert "[  1/1]" in result.stderr and "1 palpations" in result.stdout
    report = json.loads((tmp_path / "r.json").read_text())
    (probe,) = report["probes"]
    assert probe["xy_mm"] == pytest.approx([0.0, 0.0], abs=0.3) and 0.4 < probe["stiffness_n_per_mm"] < 0.9  # on the lump, felt remotely
    assert report["wall_time_s"] > 0.8 * report["robot_time_s"]  # it really ran on the wall clock


def test_simulate_refuses_a_bad_bridge_option(run_cli):
    result = run_cli("simulate", "--scene", SCENES / "paper.toml", "--bridge", "udp://x")
    assert_one_line_error(result, "--bridge", "tcp://HOST:PORT or pty")


def test_scan_with_an_absent_bridge_fails_in_one_line(tmp_path, run_cli):
    (tmp_path / "c.toml").write_text('[robot]\nurl = "socket://127.0.0.1:1"\n[sensor]\nbackend = "netft://127.0.0.1:1"\n')
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--config", "c.toml")
    assert_one_line_error(result, "socket://127.0.0.1:1")
