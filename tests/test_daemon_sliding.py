"""Sliding palpation through `palpd serve` (a real process, driven with pyzmq and JSON, virtual time): a
sliding scan journals, records and publishes like a discrete one; a stop mid-slide lifts the probe off the
tissue where it is, and an e-stop mid-slide moves it no further along the path."""
import json
import math
import signal
import subprocess
import sys
import time

import pytest

from daemon_client import Daemon, receive
from mcap_official import read_closed
from palpd.bus.messages import EVENT_MODELS
from palpd.daemon.mcap import read_messages
from palpd.daemon.session import read_journal
from test_daemon import collect_until_done

PAPER_LUMP_MM = (7.5, -4.0)  # config/scenes/paper.toml
IN_TISSUE_MM = -0.5  # the tip below the nominal surface (sliding holds it 1.5-3.5 mm in)
SLOW_MM_S, ROW_MM = 1.0, 60.0
LIFTING_ABOVE_MM = -1.35  # shallower than sliding ever holds the tip (2.5 - 1 mm, less 0.15 mm of overshoot)


def test_a_sliding_scan_set_in_the_config_runs_through_the_daemon(tmp_path):
    daemon = Daemon(tmp_path, env={"PALPD_PALPATION__MODE": json.dumps("sliding")})  # refused before issue 15b
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        subscriber = daemon.subscriber()
        reply = daemon.call("scan.start", {"strategy": "active", "max_palpations": 2})  # 2 paths
        assert reply["ok"] and reply["expected_total"] == 2, reply
        seen = collect_until_done(subscriber)
        status = daemon.wait_for(lambda s: s["state"] == "ready", what="scan end")
    finally:
        daemon.close()
    for topic, payloads in seen.items():
        for payload in payloads:
            EVENT_MODELS[topic].model_validate(payload)
    final = seen["estimate"][-1]
    readings = seen["stiffness"]
    assert len(readings) >= 10 and final["points"] == len(readings)  # a reading per modulation cycle
    # two paths place it roughly, and say how roughly: the centre within 3 of its stated sds of the truth (on one
    # machine's BLAS 0.5 mm sd and 1 mm off, on another's 4.6 mm sd and 9 mm off: few readings, a wide posterior)
    (lump,) = final["lumps"]
    assert math.dist(lump["center_mm"], PAPER_LUMP_MM) < 3.0 * max(lump["center_sd_mm"], 0.5), lump
    session = daemon.state_dir / "sessions" / status["session"]
    meta = json.loads((session / "session.json").read_text())
    assert meta["status"] == "finished" and meta["scan"]["palpation"] == "sliding"
    entries = read_journal(session / "journal.jsonl")
    assert len(entries) == status["palpations"] == len(seen["palpation"])
    assert {e["palpation"] for e in entries} == {"sliding"} and {e["path"] for e in entries} == {0, 1}
    recorded = read_messages(session / "recording-1.mcap")
    assert [p for t, p in recorded if t == "estimate"][-1] == final
    replayed = subprocess.run([sys.executable, "-m", "palpd", "replay", str(session)], capture_output=True, text=True)
    assert replayed.returncode == 0 and "the recorded estimate is reproduced" in replayed.stdout, replayed.stdout


def test_a_sliding_scan_presses_the_spots_too_stiff_to_slide_on_journals_them_and_replays(tmp_path):
    """stiff-tissue's 12 N/mm lump stops every row that meets it at the force limit: the daemon's slide presses
    each such spot (a discrete palpation within the path) and goes on; those presses are journaled with their
    path like its cycles, and `palpd replay` cuts them again from the raw samples to the same estimate."""
    daemon = Daemon(tmp_path, scene="stiff-tissue.toml", env={"PALPD_PALPATION__MODE": json.dumps("sliding")})
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        subscriber = daemon.subscriber()
        assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 3})["ok"]
        collect_until_done(subscriber)
        status = daemon.wait_for(lambda s: s["state"] == "ready", what="scan end")
    finally:
        daemon.close()
    session = daemon.state_dir / "sessions" / status["session"]
    entries = read_journal(session / "journal.jsonl")
    assert {e["path"] for e in entries} == {0, 1, 2} and {e["palpation"] for e in entries} == {"sliding"}
    pressed = [e for e in entries if e["stop_reason"] == "force" and (e["stiffness_n_per_mm"] or 0.0) > 6.0]
    assert len(pressed) >= 3  # the middle row, across the lump
    replayed = subprocess.run([sys.executable, "-m", "palpd", "replay", str(session)], capture_output=True, text=True)
    assert replayed.returncode == 0 and "the recorded estimate is reproduced" in replayed.stdout, replayed.stdout
    assert "re-segmented from raw samples" in replayed.stdout


def samples_of(recording) -> list[dict]:
    return [p for t, p in read_messages(recording) if t == "samples"] if recording.exists() else []


def in_tissue(sample: dict) -> bool:
    return sample["tip_mm"][2] < IN_TISSUE_MM


def wait_until_sliding(recording, contact_s: float = 1.5, timeout_s: float = 30.0) -> None:
    """The recorded samples (flushed each second) show the probe in the tissue for contact_s of robot time:
    pressed in (0.5 s) and sliding."""
    give_up = time.monotonic() + timeout_s
    while time.monotonic() < give_up:
        touching = [p["t"] for p in samples_of(recording) if in_tissue(p)]
        if touching and touching[-1] - touching[0] > contact_s:
            return
        time.sleep(0.05)
    raise AssertionError(f"no slide under way in {recording}")


def last_slide(samples: list[dict], flicker: int = 5) -> list[dict]:
    """The last stretch of samples with the tip in the tissue. A lift crosses IN_TISSUE_MM with the encoder
    step's flicker (in, out, in, out within a few ticks: one run's stretch ended on a single sample), so an
    excursion of up to `flicker` samples does not end the stretch."""
    inside = [i for i, p in enumerate(samples) if in_tissue(p)]
    first = last = inside[-1]
    for i in reversed(inside[:-1]):
        if first - i > flicker:
            break
        first = i
    return samples[first:last + 1]


def test_estop_and_sigterm_mid_slide_never_drag_the_probe_along_the_tissue(tmp_path):
    # 1 mm/s: a 60 mm row takes 60 s of robot time (seconds of wall time even in virtual time, on a busy
    # machine too), so each stop lands mid-slide, never after the row
    daemon = Daemon(tmp_path, env={"PALPD_PALPATION__SLIDING_SPEED_MM_S": str(SLOW_MM_S)})
    sessions = tmp_path / "state" / "sessions"
    try:
        daemon.start().wait_for(lambda s: s["state"] == "ready", what="ready")
        faults = daemon.subscriber("fault")
        assert daemon.call("scan.start", {"strategy": "raster", "palpation": "sliding", "max_palpations": 3})["ok"]
        (session,) = sessions.iterdir()
        wait_until_sliding(session / "recording-1.mcap")
        assert daemon.call("estop")["ok"]  # category 0: the current is cut where the probe is
        assert receive(faults)[1]["code"] == "estop"
        daemon.wait_for(lambda s: s["state"] == "fault", what="fault")
        assert daemon.call("reset")["ok"]
        daemon.wait_for(lambda s: s["state"] == "ready", what="home after the reset")
        assert daemon.call("scan.start", {"resume": True})["ok"]
        wait_until_sliding(session / "recording-2.mcap")
        daemon.signal(signal.SIGTERM)
        assert daemon.wait() == 0, daemon.process.stderr.read()
    finally:
        daemon.close()
    cut = last_slide(samples_of(session / "recording-1.mcap"))  # the e-stop ended the run (and its recording)
    assert cut[-1]["t"] - cut[0]["t"] > 1.5 and math.dist(cut[-1]["tip_mm"][:2], cut[0]["tip_mm"][:2]) < ROW_MM / 2
    resumed = samples_of(session / "recording-2.mcap")
    assert resumed[0]["tip_mm"][2] > 50.0  # the reset took the arm up off the tissue and home

    slid = last_slide(resumed)
    assert slid[-1]["t"] - slid[0]["t"] > 1.5  # SIGTERM came mid-slide...
    assert math.dist(slid[-1]["tip_mm"][:2], slid[0]["tip_mm"][:2]) < ROW_MM / 2  # ...and the row went no further
    # The lift at 20 mm/s: straight up where it was (sliding on, 0.1 s would be 0.1 mm along the row, the x
    # axis). Sliding holds the tip 1.5-3.5 mm in (2.5 +- 1 mm of modulation), so the samples shallower than
    # its shallowest point (and a margin for the controller's overshoot) are the way up, down to the line
    # 0.5 mm in. (The last 100 samples, taken before, held the modulation's last rise when the stop came at
    # its shallowest: 0.095 mm of the controller's lateral jitter, with the lift itself within 0.03 mm.)
    way_up = next(i for i in range(len(slid) - 1, -1, -1) if slid[i]["tip_mm"][2] <= LIFTING_ABOVE_MM) + 1
    leaving = slid[way_up:]
    assert leaving and leaving[0]["tip_mm"][2] < leaving[-1]["tip_mm"][2] - 0.5
    assert max(abs(p["tip_mm"][0] - leaving[-1]["tip_mm"][0]) for p in leaving) < 0.08
    assert resumed[-1]["tip_mm"][2] > 50.0 and abs(resumed[-1]["normal_force_n"]) < 0.05  # parked at home
    messages = [(t, p) for t, p, _ in read_closed(session / "recording-2.mcap")["messages"]]
    assert [p["code"] for t, p in messages if t == "fault"] == []  # a gentle stop, not a fault
    entries = read_journal(session / "journal.jsonl")
    assert entries and {e["path"] for e in entries} == {0}  # what the stopped row read is kept
    assert json.loads((session / "session.json").read_text())["status"] == "unfinished"  # resumable
