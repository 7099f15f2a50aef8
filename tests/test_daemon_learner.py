"""The online learner inside `palpd serve` (real daemon processes): active scans, crash recovery, a lost servo."""
import math
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from daemon_client import Daemon, receive
from palpd.bus.messages import Estimate
from palpd.daemon.session import read_journal

PAPER_LUMP_CENTER_MM, PAPER_LUMP_RADIUS_MM = (7.5, -4.0), 10.0


def estimates_until_done(subscriber, timeout_s=60.0) -> list[dict]:
    estimates = []
    while not estimates or not estimates[-1]["done"]:
        event = receive(subscriber, timeout_s)
        assert event is not None, f"no estimate within {timeout_s} s after {len(estimates)}"
        estimates.append(Estimate.model_validate(event[1]).model_dump(mode="json"))
    return estimates


def test_kill_9_mid_active_scan_then_resume_continues_where_the_learner_says_and_finds_the_lump(tmp_path):
    budget = {"PALPD_LEARNER__MAX_PALPATIONS": "20"}  # 10 before the kill, up to 10 after: enough to prove the resume
    first = Daemon(tmp_path, env=budget).start()
    try:
        first.wait_for(lambda s: s["state"] == "ready", what="ready")
        subscriber = first.subscriber("estimate")
        reply = first.call("scan.start", {"strategy": "active"})
        assert reply["ok"] and reply["expected_total"] == 20, reply  # learner.max_palpations by default
        seen = [receive(subscriber) for _ in range(10)]  # past the 8-point first design: the learner chooses
        assert all(event is not None for event in seen)
        latest = seen[-1][1]
        assert latest["points"] == 10 and latest["next_probe_mm"] is not None
        assert latest["ambiguous_area_mm2"] is not None and latest["ambiguous_area_mm2"] > 0
        assert latest["model"]["chosen"] and 0 < latest["model"]["weight"] <= 1
        first.signal(signal.SIGKILL)
        first.wait()
    finally:
        first.close()
    (session,) = (tmp_path / "state" / "sessions").iterdir()
    journaled = read_journal(session / "journal.jsonl")
    assert 10 <= len(journaled) < 20
    second = Daemon(tmp_path, env=budget).start()
    try:
        status = second.wait_for(lambda s: s["state"] == "ready", what="ready after restart")
        assert status["resumable"] and status["palpations"] == len(journaled)
        recovered = second.call("estimate.get")["estimate"]  # the learner rebuilt from the journal
        assert recovered["points"] == len(journaled) and recovered["next_probe_mm"] is not None
        subscriber = second.subscriber("estimate")
        reply = second.call("scan.start", {"resume": True})
        assert reply["ok"] and reply["already_done"] == len(journaled), reply
        final = estimates_until_done(subscriber)[-1]
        entries = read_journal(session / "journal.jsonl")
        assert entries[:len(journaled)] == journaled and [e["index"] for e in entries] == list(range(len(entries)))
        # the first palpation after the restart went where the recovered learner said
        assert entries[len(journaled)]["target_xy_mm"] == pytest.approx(recovered["next_probe_mm"], abs=1e-9)
        assert len(entries) <= 20 and final["points"] == len(entries)
        assert final["model"]["chosen"] == "circles:1" and final["model"]["weight"] >= 0.9
        (lump,) = final["lumps"]
        assert math.dist(lump["center_mm"], PAPER_LUMP_CENTER_MM) <= 1.5
        assert abs(lump["radius_mm"] - PAPER_LUMP_RADIUS_MM) <= 1.5
        assert lump["center_sd_mm"] > 0 and len(lump["boundary_mm"]) >= 3
        second.wait_for(lambda s: s["state"] == "ready" and not s["resumable"], what="scan end")
    finally:
        second.close()
    replayed = subprocess.run([sys.executable, "-m", "palpd", "replay", str(session)], capture_output=True, text=True)
    assert replayed.returncode == 0 and "the recorded estimate is reproduced" in replayed.stdout, replayed.stdout
    resegmented = int(re.search(r"\((\d+) re-segmented", replayed.stdout).group(1))
    assert resegmented >= len(entries) - len(journaled)  # at least the resumed run's, cut from its raw samples


def servo_child_pid(daemon_pid: int) -> int:
    """The spawned servo process among the daemon's children (not multiprocessing's resource tracker)."""
    children = [pid for task in Path(f"/proc/{daemon_pid}/task").iterdir()  # any thread may have started it
                for pid in (task / "children").read_text().split()]
    for pid in children:
        command = Path(f"/proc/{pid}/cmdline").read_bytes()
        if b"spawn_main" in command:
            return int(pid)
    raise AssertionError(f"no servo process among {children}")


def test_a_servo_process_lost_while_idle_is_a_prompt_fault_and_reset_starts_a_new_one(tmp_path):
    daemon = Daemon(tmp_path).start()
    try:
        daemon.wait_for(lambda s: s["state"] == "ready", what="ready")
        faults = daemon.subscriber("fault")
        assert daemon.call("status")["ok"]  # the subscription settles while we ask
        lost_pid = servo_child_pid(daemon.process.pid)
        killed_at = time.monotonic()
        subprocess.run(["kill", "-9", str(lost_pid)], check=True)
        event = receive(faults, 10.0)
        assert event is not None and event[1]["code"] == "servo_lost", event
        assert time.monotonic() - killed_at < 5.0  # noticed by the loop, not at the next command
        assert daemon.call("status")["state"] == "fault"
        assert daemon.call("bias")["error"]["code"] == "invalid_state"
        reply = daemon.call("reset")
        assert reply["ok"] and reply["restarting"], reply
        daemon.wait_for(lambda s: s["state"] == "ready", timeout_s=60.0, what="ready with a new servo process")
        assert servo_child_pid(daemon.process.pid) != lost_pid
        assert daemon.call("bias")["ok"]  # the new servo process takes work
        status = daemon.wait_for(lambda s: s["state"] != "scanning", what="bias done")
        assert status["state"] == "ready", status
    finally:
        daemon.close()
