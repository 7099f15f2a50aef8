"""`palpd serve` as a service: slow subscribers, SIGTERM that must abort, probe.at/bias, palpctl's commands."""
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import zmq

from daemon_client import Daemon, receive
from mcap_official import read_closed
from palpd.daemon.mcap import read_messages
from palpd.daemon.session import read_journal


@pytest.fixture
def daemon(tmp_path):
    d = Daemon(tmp_path, env={"PALPD_BUS__HIGH_WATER_MARK": "20"})
    yield d
    d.close()


def test_a_subscriber_that_never_reads_does_not_stall_the_daemon(daemon):
    daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
    stalled = daemon.socket(zmq.SUB)
    stalled.setsockopt(zmq.RCVHWM, 1)
    stalled.setsockopt(zmq.RCVBUF, 4096)
    stalled.subscribe("")
    stalled.connect(daemon.events)  # ...and never reads
    listener = daemon.subscriber("estimate")
    assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 4})["ok"]  # events to not read
    asker, slowest_reply_s, final = daemon.dealer(), 0.0, None
    give_up = time.monotonic() + 60
    while final is None and time.monotonic() < give_up:
        asked = time.monotonic()
        assert daemon.call("status", socket=asker, timeout_s=5.0)["ok"]
        slowest_reply_s = max(slowest_reply_s, time.monotonic() - asked)
        while (event := receive(listener, timeout_s=0.05)) is not None:
            final = event[1] if event[1]["done"] else final
    assert final is not None and final["points"] == 4, "the scan did not finish"
    assert slowest_reply_s < 2.0, f"a status request waited {slowest_reply_s:.2f} s"
    assert daemon.wait_for(lambda s: s["state"] == "ready", what="ready")["palpations"] == 4


def wait_until_palpating(sessions: Path, timeout_s: float = 20.0) -> None:
    """The raw samples in the recording (flushed each second) show 2 s of robot time: past the move and
    tare, so the first palpation is under way (a SIGTERM before it would just end the scan)."""
    give_up = time.monotonic() + timeout_s
    while time.monotonic() < give_up:
        for recording in sessions.glob("*/recording-1.mcap"):
            ticks = [p["t"] for t, p in read_messages(recording) if t == "samples"]
            if ticks and ticks[-1] - ticks[0] > 2.0:
                return
        time.sleep(0.05)
    raise AssertionError("the scan never reached its first palpation")


def test_sigterm_aborts_a_palpation_that_outlasts_stop_timeout(tmp_path):
    daemon = Daemon(tmp_path, env={"PALPD_DAEMON__STOP_TIMEOUT_S": "0.3"})
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        # 5 mm at 0.02 mm/s: one palpation is 250 s of robot time, far more than any wall time here.
        slow = {"strategy": "raster", "max_palpations": 4, "depth_mm": 5.0, "speed_mm_s": 0.02}
        assert daemon.call("scan.start", slow)["ok"]
        wait_until_palpating(tmp_path / "state" / "sessions")
        signalled = time.monotonic()
        daemon.signal(signal.SIGTERM)
        assert daemon.wait() == 0, daemon.process.stderr.read()
        assert time.monotonic() - signalled < 10.0
    finally:
        daemon.close()
    (session,) = (tmp_path / "state" / "sessions").iterdir()
    assert read_journal(session / "journal.jsonl") == []  # the aborted palpation is no palpation
    messages = [(topic, payload) for topic, payload, _ in read_closed(session / "recording-1.mcap")["messages"]]
    faults = [payload["code"] for topic, payload in messages if topic == "fault"]
    assert faults == ["estop"], messages
    assert [p["state"] for t, p in messages if t == "status"][-1] == "fault"  # the scan's recording ends with it
    assert '"unfinished"' in (session / "session.json").read_text()  # still resumable


class Lines:
    """A process's stdout lines, read on a thread so the test can wait for one with a timeout."""

    def __init__(self, process: subprocess.Popen) -> None:
        self.queue: queue.Queue = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._pump, args=(process.stdout,), daemon=True).start()

    def _pump(self, stream) -> None:
        for line in stream:
            self.queue.put(line.rstrip("\n"))

    def wait_for(self, fragment: str, timeout_s: float = 30.0) -> str:
        give_up = time.monotonic() + timeout_s
        while time.monotonic() < give_up:
            try:
                line = self.queue.get(timeout=max(0.01, give_up - time.monotonic()))
            except queue.Empty:
                break
            self.seen.append(line)
            if fragment in line:
                return line
        raise AssertionError(f"no line with {fragment!r}; got {self.seen}")


def test_palpctl_watch_probe_bias_estop_reset_and_a_probe_survives_kill_9(daemon, run_cli, tmp_path):
    daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
    endpoints = ("--endpoint", daemon.commands, "--events", daemon.events)

    def palpctl(*args):
        result = run_cli(*endpoints, *args, module="palpd.palpctl")
        assert result.returncode == 0, result.stderr
        return result

    watch = subprocess.Popen([sys.executable, "-m", "palpd.palpctl", *endpoints, "watch"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=daemon.env)
    try:
        lines = Lines(watch)
        assert lines.wait_for("status:") == "status: ready, 0 palpations"
        palpctl("scan", "start", "--strategy", "raster", "--max-palpations", "9", "--size-mm", "40", "40")
        done = lines.wait_for("(done)")
        assert done.startswith("estimate from 9 points: lump at (") and re.search(r"; model \S+ \(weight [\d.]+\)", done)
        assert any(line.startswith("palpation ") and "N/mm" in line for line in lines.seen), lines.seen
        daemon.wait_for(lambda s: s["state"] == "ready", what="scan end")

        palpctl("bias")
        assert lines.wait_for("status: scanning") == "status: scanning bias"
        lines.wait_for("status: ready")
        palpctl("probe", "5", "-5")
        probe_line = lines.wait_for("palpation 1:")
        assert "(   5.0,   -5.0) mm" in probe_line, probe_line  # the probes session counts from 1
        daemon.wait_for(lambda s: s["state"] == "ready", what="probe end")

        # an e-stop mid-scan: `scan start --wait` ends saying what the fault was, not only its code
        waiting = subprocess.Popen([sys.executable, "-m", "palpd.palpctl", *endpoints, "scan", "start", "--wait",
                                    "--strategy", "raster", "--max-palpations", "4"],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   text=True, env=daemon.env)
        try:
            lines.wait_for("status: scanning")
            palpctl("estop")
            fault_line = lines.wait_for("fault:")  # "fault: CODE MESSAGE", as watch prints it
            _, stderr = waiting.communicate(timeout=30)
        finally:
            waiting.kill()
        code, message = fault_line.removeprefix("fault: ").split(" ", 1)
        assert code == "estop" and message, fault_line
        assert waiting.returncode == 1
        assert stderr == f"palpctl: the scan ended in a fault (estop: {message})\n", stderr
        assert daemon.call("status")["state"] == "fault"
        palpctl("reset")  # the arm is brought home, supervised, then the daemon is ready again
        daemon.wait_for(lambda s: s["state"] == "ready", what="ready after reset")
        watch.send_signal(signal.SIGINT)
        assert watch.wait(30) == 0, watch.stderr.read()
    finally:
        watch.kill()
        watch.wait(10)
        watch.stdout.close()
        watch.stderr.close()
    daemon.signal(signal.SIGKILL)
    daemon.wait()
    probes = [p for p in (daemon.state_dir / "sessions").iterdir() if '"probes"' in (p / "session.json").read_text()]
    (entry,) = read_journal(probes[0] / "journal.jsonl")  # published, so journaled: kill -9 loses nothing
    assert entry["index"] == 0 and entry["target_xy_mm"] == [5.0, -5.0]
