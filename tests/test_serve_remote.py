"""`palpd serve` next to a bench it reaches over the wire: a separately started `palpd simulate` (Phantom bridge
over TCP, Nano17 over Net F/T), configured by nothing but the two URLs, driven by palpctl; SIGTERM, kill -9 and
resume. The simulator keeps running between daemons, as the robot does between restarts of its service."""
import json
import signal

import pytest

from conftest import SCENES
from daemon_client import Daemon
from remote_bench import bench_config, serve_simulator


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """The simulated bench as its own process, and a config that names only its URLs."""
    where = tmp_path_factory.mktemp("remote-bench")
    for endpoints in serve_simulator(where, "--bridge", "tcp://127.0.0.1:0", "--netft", "127.0.0.1:0"):
        yield bench_config(where / "bench.toml", endpoints)


def daemon_on(bench, tmp_path) -> Daemon:
    """`palpd serve --config bench.toml`: no scene (the config's [tissue] places the tissue)."""
    return Daemon(tmp_path, env={"PALPD_DAEMON__SCENE": ""}, args=("--config", bench)).start()


def palpctl(daemon, run_cli, *args):
    result = run_cli("--endpoint", daemon.commands, "--events", daemon.events, "--timeout", "10", *args,
                     module="palpd.palpctl")
    if result.returncode != 0:  # palpctl names a fault by its code; the daemon's log says what it measured
        daemon.process.kill()
        pytest.fail(f"{result.stderr}daemon log:\n{daemon.process.stderr.read()[-4000:]}")
    return json.loads(result.stdout) if result.stdout.startswith("{") else result.stdout


def test_serve_on_the_remote_bench_scans_estimates_and_resumes_after_kill_9_and_sigterm(bench, tmp_path, run_cli):
    first = daemon_on(bench, tmp_path)
    try:
        first.wait_for(lambda s: s["state"] == "ready", what="ready")
        assert palpctl(first, run_cli, "status")["state"] == "ready"
        palpctl(first, run_cli, "scan", "start", "--strategy", "raster", "--max-palpations", "4")
        first.wait_for(lambda s: s["palpations"] >= 1, timeout_s=60, what="a palpation")
        first.signal(signal.SIGKILL)  # the servo process dies with it: the bridge's watchdog takes the arm
        first.wait()
        log = first.process.stderr.read()
        assert "bench: robot socket://127.0.0.1:" in log and "force sensor netft://127.0.0.1:" in log, log
    finally:
        first.close()
    second = daemon_on(bench, tmp_path)
    try:
        status = second.wait_for(lambda s: s["state"] == "ready", what="ready after kill -9")
        assert status["resumable"] and 1 <= status["palpations"] < 4
        done_before = status["palpations"]
        assert palpctl(second, run_cli, "scan", "start", "--resume")["already_done"] == done_before
        second.wait_for(lambda s: s["palpations"] > done_before, timeout_s=60, what="one more palpation")
        second.signal(signal.SIGTERM)  # lets the palpation under way finish, then motors off
        assert second.wait() == 0
    finally:
        second.close()
    third = daemon_on(bench, tmp_path)
    try:
        status = third.wait_for(lambda s: s["state"] == "ready", what="ready after SIGTERM")
        assert status["resumable"]
        palpctl(third, run_cli, "scan", "start", "--resume", "--wait")
        estimate = palpctl(third, run_cli, "estimate")
        assert [p["index"] for p in estimate["probes"]] == [0, 1, 2, 3]
        # the 2 x 2 grid on the corners, (+-30, +-30) mm: the paper scene's tissue, 0.12 N/mm, felt through the wire
        for probe in estimate["probes"]:
            assert [abs(v) for v in probe["xy_mm"]] == pytest.approx([30.0, 30.0], abs=0.5)
            assert probe["stiffness_n_per_mm"] == pytest.approx(0.12, rel=0.1)
        assert estimate["estimate"]["points"] == 4 and estimate["estimate"]["done"]
        assert third.call("status")["resumable"] is False
    finally:
        third.close()


def test_a_frozen_net_ft_box_from_palpd_simulate_fault_stops_a_remote_scan(tmp_path, run_cli):
    """`palpd simulate --fault sensor_frozen@0`: the box keeps streaming, always the same counts."""
    for endpoints in serve_simulator(tmp_path, "--bridge", "tcp://127.0.0.1:0", "--netft", "127.0.0.1:0",
                                     "--fault", "sensor_frozen@0"):
        config = bench_config(tmp_path / "frozen.toml", endpoints)
        result = run_cli("scan", "--scene", SCENES / "paper.toml", "--config", config, "--strategy", "raster",
                         "--max-palpations", "1")
    assert result.returncode == 1 and "(sensor_frozen)" in result.stderr, result.stderr
