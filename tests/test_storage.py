"""Issue 52: a daemon that runs for months: a full disk is a `storage` fault, never an exit, and sessions are
bounded. `palpd serve` runs as a real process on a disk that fills up (tests/full_disk.py: the fault-injection
seam, no mount needed), in virtual time."""
import json
import sys
import time
from pathlib import Path

import pytest

from daemon_client import Daemon
from palpd.daemon.mcap import is_closed, read_messages
from palpd.daemon.session import read_journal
from palpd.daemon.storage import list_sessions, prune

FULL_DISK = Path(__file__).with_name("full_disk.py")


class FullDiskDaemon(Daemon):
    """`palpd serve` whose session files fill a disk of PALPD_TEST_DISK_BYTES (see full_disk.py)."""

    def __init__(self, tmp_path, disk_bytes: int, files: str = "*", **kwargs) -> None:
        self.freed = tmp_path / "freed"
        super().__init__(tmp_path, env={"PALPD_TEST_DISK_BYTES": str(disk_bytes), "PALPD_TEST_DISK_FILES": files,
                                        "PALPD_TEST_DISK_FREED": str(self.freed), **kwargs.pop("env", {})}, **kwargs)

    def start(self) -> "FullDiskDaemon":
        import subprocess

        self.process = subprocess.Popen([sys.executable, str(FULL_DISK), "serve", *self.args], env=self.env,
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        return self


def only_session(daemon) -> Path:
    (session,) = [p for p in (daemon.state_dir / "sessions").iterdir() if p.is_dir()]
    return session


def test_a_journal_that_cannot_be_written_stops_the_scan_with_the_probe_off_the_tissue(tmp_path):
    """Today the OSError went through the supervisor and `palpd serve` exited 1 mid-scan."""
    daemon = FullDiskDaemon(tmp_path, disk_bytes=100_000, files="journal.jsonl")  # room for 3 palpations (~30 kB each)
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 25})["ok"]
        status = daemon.wait_for(lambda s: s["state"] == "fault", timeout_s=60, what="the storage fault")
        assert status["message"].startswith("storage: journaling palpation "), status
        assert "No space left on device" in status["message"] and "MB used (100 %)" in status["message"]
        assert daemon.call("status")["state"] == "fault"  # alive, answering
        session = only_session(daemon)
        journaled = read_journal(session / "journal.jsonl")
        assert 1 <= len(journaled) == status["palpations"] < 25 and status["resumable"]
        assert daemon.call("scan.start", {"resume": True})["error"]["code"] == "invalid_state"
        recording = session / "recording-1.mcap"
        daemon.wait_for(lambda s: is_closed(recording), what="the recording closed")
    finally:
        daemon.close()
    messages = read_messages(recording)
    (fault,) = [p for t, p in messages if t == "fault"]
    assert fault["code"] == "storage"
    samples = [p for t, p in messages if t == "samples"]
    assert samples[-1]["tip_mm"][2] > 1.0 and samples[-1]["t"] > fault["t"] - 0.5  # parked clear of the tissue


def test_a_full_disk_drops_the_raw_samples_first_and_keeps_journaling(tmp_path):
    daemon = FullDiskDaemon(tmp_path, disk_bytes=100_000, files="recording-*")
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 4, "size_mm": [30, 30]})["ok"]
        status = daemon.wait_for(lambda s: s["message"] == "scan finished", timeout_s=60, what="the scan's end")
        assert status["state"] == "ready" and status["palpations"] == 4 and status["samples_dropped"] > 1000
        assert len(read_journal(only_session(daemon) / "journal.jsonl")) == 4
        listed = daemon.call("sessions")
        assert listed["ok"] and listed["samples_dropped"] == daemon.call("status")["samples_dropped"]
        assert [s["status"] for s in listed["sessions"]] == ["finished"] and listed["sessions"][0]["size_mb"] > 0.1
    finally:
        daemon.close()


def test_a_full_disk_mid_scan_then_a_restart_on_it_then_space_freed_and_reset(tmp_path):
    """Issue 52's by-hand run, through the seam: a raster of 25 on a disk that fills mid-scan ends in a storage
    fault with the daemon alive; restarted on the full disk it answers status with the cause instead of dying;
    once space is freed, reset recovers the unfinished session, which resumes."""
    first = FullDiskDaemon(tmp_path, disk_bytes=600_000)
    try:
        first.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        assert first.call("scan.start", {"strategy": "raster", "max_palpations": 25})["ok"]
        status = first.wait_for(lambda s: s["state"] == "fault", timeout_s=90, what="the storage fault")
        assert status["message"].startswith("storage: ") and first.call("status")["ok"]
        session = only_session(first)
        journaled = read_journal(session / "journal.jsonl")
        assert 1 <= len(journaled) == status["palpations"] < 25
    finally:
        first.close()
    second = FullDiskDaemon(tmp_path, disk_bytes=0)  # the disk is still full
    try:
        status = second.start().wait_for(lambda s: s["state"] == "fault", what="a fault state at start-up")
        assert status["message"].startswith("storage: start-up: recovering the sessions: No space left on device")
        refused = second.call("reset")
        assert refused["error"]["code"] == "storage" and second.call("status")["state"] == "fault"
        second.freed.touch()  # the operator frees space
        assert second.call("reset")["ok"]
        status = second.wait_for(lambda s: s["state"] == "ready", what="ready after reset")
        assert status["resumable"] and status["palpations"] == len(journaled)
        assert is_closed(session / "recording-1.mcap")  # the torn recording sealed
        reply = second.call("scan.start", {"resume": True})  # goes on from there (as after a crash: test_daemon)
        assert reply["ok"] and reply["already_done"] == len(journaled), reply
    finally:
        second.close()


def test_a_failing_disk_is_a_storage_fault_at_once(tmp_path):
    """EIO is no full disk: the recording is not quietly dropped, the scan stops."""
    daemon = FullDiskDaemon(tmp_path, disk_bytes=50_000, files="recording-*", env={"PALPD_TEST_DISK_ERRNO": "EIO"})
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 25})["ok"]
        status = daemon.wait_for(lambda s: s["state"] == "fault", timeout_s=60, what="the storage fault")
        assert status["message"].startswith("storage: recording: Input/output error"), status
        assert status["palpations"] < 25
    finally:
        daemon.close()


def make_session(root: Path, name: str, status: str, size: int, age_days: float = 0.0) -> None:
    path = root / name
    path.mkdir(parents=True)
    (path / "session.json").write_text(json.dumps({"status": status, "created": time.time() - age_days * 86400}))
    (path / "recording-1.mcap").write_bytes(b"\0" * size)


def test_pruning_removes_the_oldest_finished_sessions_first_and_never_an_unfinished_one(tmp_path):
    mb = 1 << 20
    make_session(tmp_path, "20260101-000000", "unfinished", 3 * mb, age_days=60)
    make_session(tmp_path, "20260102-000000", "finished", 2 * mb, age_days=50)
    make_session(tmp_path, "20260103-000000", "abandoned", 2 * mb, age_days=40)
    make_session(tmp_path, "20260104-000000", "finished", 2 * mb, age_days=1)
    make_session(tmp_path, "20260105-000000", "finished", 2 * mb)  # in use
    gone = prune(tmp_path, max_mb=9.5, keep_days=0, in_use={"20260105-000000"})
    assert [s["name"] for s in gone] == ["20260102-000000"]
    gone = prune(tmp_path, max_mb=1.0, keep_days=0, in_use={"20260105-000000"})
    assert [s["name"] for s in gone] == ["20260103-000000", "20260104-000000"]
    assert [s["name"] for s in list_sessions(tmp_path)] == ["20260101-000000", "20260105-000000"]
    make_session(tmp_path, "20260106-000000", "finished", 1, age_days=31)
    assert [s["name"] for s in prune(tmp_path, max_mb=100.0, keep_days=30, in_use=set())] == ["20260106-000000"]


def test_back_to_back_scans_keep_the_sessions_under_max_sessions_mb(tmp_path, run_cli):
    limit_mb = 2.0  # a 4-palpation session is about 0.85 MB: two fit
    daemon = Daemon(tmp_path, env={"PALPD_DAEMON__MAX_SESSIONS_MB": str(limit_mb)})
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        for _ in range(3):
            assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 4, "size_mm": [30, 30]})["ok"]
            daemon.wait_for(lambda s: s["message"] == "scan finished", timeout_s=60, what="the scan's end")
        listed = daemon.call("sessions")
        assert len(listed["sessions"]) == 2 and listed["total_mb"] <= limit_mb, listed
        assert listed["max_sessions_mb"] == limit_mb and listed["filesystem"]["total_mb"] > 0
        table = run_cli("--endpoint", daemon.commands, "sessions", module="palpd.palpctl")
        assert table.returncode == 0 and f"of daemon.max_sessions_mb = {limit_mb:g}" in table.stdout, table.stderr
    finally:
        daemon.close()


def test_the_soak_measures_memory_fds_shared_memory_and_storage_of_a_process(tmp_path):
    """`palpd bench soak`'s figures, read from /proc (here of this process: no servo child)."""
    import os
    from multiprocessing import shared_memory

    from palpd.commands.bench_soak import measure, summarize

    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "f").write_bytes(b"\0" * (1 << 20))
    segment = shared_memory.SharedMemory(create=True, size=4096)
    try:
        row = measure(os.getpid(), tmp_path / "s")
    finally:
        segment.close()
        segment.unlink()
    assert row["daemon_rss_mb"] > 10 and row["daemon_fds"] > 3 and row["servo_rss_mb"] is None
    assert row["shm_segments"] >= 1 and row["sessions_mb"] == 1.0
    rows = [{**row, "daemon_rss_mb": 100.0}, {**row, "daemon_rss_mb": 104.0}]
    assert summarize(rows)["daemon_rss_mb"]["change_percent"] == 4.0


def test_a_warning_at_90_percent_of_the_limit_or_of_the_filesystem(tmp_path, monkeypatch):
    from palpd.daemon import storage

    make_session(tmp_path, "20260101-000000", "finished", 950_000)
    monkeypatch.setattr(storage, "disk_usage", lambda path: (100 << 20, 50 << 20, 50 << 20))
    assert storage.usage_warning(tmp_path, max_mb=2.0) == ""
    assert storage.usage_warning(tmp_path, max_mb=1.0).startswith("sessions use 0.9 MB of daemon.max_sessions_mb = 1")
    monkeypatch.setattr(storage, "disk_usage", lambda path: (100 << 20, 95 << 20, 5 << 20))
    assert storage.usage_warning(tmp_path, max_mb=2.0).startswith("the disk is nearly full: filesystem of")


def test_a_scan_start_that_cannot_write_its_session_is_refused_as_a_storage_fault(tmp_path):
    daemon = FullDiskDaemon(tmp_path, disk_bytes=0, files=".session.json.tmp")  # session.json, written atomically
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        refused = daemon.call("scan.start", {"strategy": "raster", "max_palpations": 4})
        assert refused["error"]["code"] == "storage" and "cannot write: No space left" in refused["error"]["message"]
        status = daemon.call("status")
        assert status["state"] == "fault" and status["message"].startswith("storage: scan.start: ")
        assert not list((daemon.state_dir / "sessions").iterdir())  # no session without its session.json
        daemon.freed.touch()
        assert daemon.call("reset")["ok"]
        daemon.wait_for(lambda s: s["state"] == "ready", what="ready after reset")
        assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 1})["ok"]
    finally:
        daemon.close()
