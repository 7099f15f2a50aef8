"""palpd bench soak: back-to-back scans through a real `palpd serve` on the wall clock, for N minutes.

After each scan it prints the daemon's and the servo process's resident memory,
their open file descriptors, the shared-memory segments they map and the size of
the sessions directory (pruned to daemon.max_sessions_mb), then compares the
end with the first scan: a daemon that runs for months must stay flat. Linux
only (it reads /proc). The daemon's log goes to serve.log in the state directory.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MB = 1 << 20
READY_TIMEOUT_S = 120.0
SETTLE_S = 1.0  # after a scan, before measuring: the client's event subscription has closed on the daemon's side


def add_parser(subparsers):
    soak = subparsers.add_parser("soak", help="back-to-back scans through a real daemon: memory, fds, storage per scan")
    soak.add_argument("--minutes", type=float, required=True, metavar="N", help="how long to keep scanning")
    soak.add_argument("--palpations", type=int, default=9, metavar="N", help="raster palpations per scan (default 9)")
    soak.add_argument("--max-sessions-mb", type=float, metavar="MB",
                      help="daemon.max_sessions_mb for the soak (default: the config's)")
    soak.add_argument("--state-dir", metavar="DIR", help="the daemon's state directory (default: a temporary one)")
    soak.add_argument("--config", metavar="FILE", help="settings (TOML) for the daemon")
    soak.add_argument("--json", action="store_true", help="print JSON")
    return soak


def run(args) -> int:
    from palpd.errors import UsageError

    if args.minutes <= 0 or args.palpations < 1:
        raise UsageError("bench soak: --minutes must be above 0 and --palpations at least 1")
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # stopped early: the daemon it started stops too
    with tempfile.TemporaryDirectory(prefix="palpd-soak-") as scratch:
        state = Path(args.state_dir or scratch)
        state.mkdir(parents=True, exist_ok=True)
        daemon = _start_daemon(args, state, Path(scratch))
        try:
            rows = _soak(args, daemon, state / "sessions", Path(scratch))
        finally:
            daemon.send_signal(signal.SIGTERM)
            try:
                daemon.wait(30)
            except subprocess.TimeoutExpired:
                daemon.kill()
                daemon.wait()
    summary = summarize(rows)
    if args.json:
        print(json.dumps({"minutes": args.minutes, "palpations_per_scan": args.palpations, "scans": rows,
                          "summary": summary}, indent=2))
    else:
        print(summary_line(summary, args.minutes))
    return 0 if rows and rows[-1]["state"] == "ready" else 1


def _start_daemon(args, state: Path, scratch: Path) -> subprocess.Popen:
    env = {**os.environ, "PALPD_BUS__EVENTS": f"ipc://{scratch}/events",
           "PALPD_BUS__COMMANDS": f"ipc://{scratch}/commands", "PALPD_DAEMON__HTTP": "",
           "PALPD_DAEMON__STATE_DIR": str(state), "PALPD_DAEMON__REALTIME": "true"}
    if args.max_sessions_mb is not None:
        env["PALPD_DAEMON__MAX_SESSIONS_MB"] = str(args.max_sessions_mb)
    command = [sys.executable, "-m", "palpd", "serve", *(["--config", args.config] if args.config else [])]
    with open(state / "serve.log", "a") as log:
        return subprocess.Popen(command, env=env, stdout=log, stderr=log)


def _soak(args, daemon: subprocess.Popen, sessions: Path, scratch: Path) -> list[dict]:
    from palpd.client import Client

    rows = []
    with Client(f"ipc://{scratch}/commands", f"ipc://{scratch}/events", timeout_s=10.0) as client:
        _wait_ready(client, daemon)
        started = time.monotonic()
        while time.monotonic() - started < args.minutes * 60:
            t0 = time.monotonic()
            status = client.scan("raster", wait=True, max_palpations=args.palpations, wait_timeout_s=600.0)
            wall_s = round(time.monotonic() - t0, 1)
            time.sleep(SETTLE_S)
            row = {"scan": len(rows) + 1, "wall_s": wall_s, "state": status.state,
                   "palpations": status.palpations, **measure(daemon.pid, sessions)}
            rows.append(row)
            if not args.json:
                print(row_line(row), flush=True)
            if status.state != "ready":
                print(f"bench soak: scan {row['scan']} ended in {status.message}", file=sys.stderr)
                break
    return rows


def _wait_ready(client, daemon) -> None:
    from palpd.errors import PalpdError

    give_up = time.monotonic() + READY_TIMEOUT_S
    while time.monotonic() < give_up:
        if daemon.poll() is not None:
            raise PalpdError(f"bench soak: the daemon exited {daemon.returncode} (see serve.log)")
        try:
            if client.status().state == "ready":
                return
        except TimeoutError:
            pass
        time.sleep(0.2)
    raise PalpdError(f"bench soak: the daemon was not ready within {READY_TIMEOUT_S:g} s")


def measure(pid: int, sessions: Path) -> dict:
    """Resident memory (MB) and open fds of the daemon and its servo process, the /dev/shm segments they map,
    and the sessions directory's size (MB)."""
    from palpd.daemon.storage import directory_bytes

    servo = servo_pid(pid)
    pids = [pid] + ([servo] if servo else [])
    return {"daemon_rss_mb": round(rss_mb(pid), 1), "servo_rss_mb": round(rss_mb(servo), 1) if servo else None,
            "daemon_fds": fds(pid), "servo_fds": fds(servo) if servo else None,
            "shm_segments": len(set().union(*(shm_segments(p) for p in pids))),
            "sessions_mb": round(directory_bytes(sessions) / MB, 2)}


def servo_pid(pid: int) -> int | None:
    """The daemon's servo process: the multiprocessing child it spawned (not the resource tracker)."""
    for child in children(pid):
        try:
            if b"spawn_main" in Path(f"/proc/{child}/cmdline").read_bytes():
                return child
        except OSError:
            pass
    return None


def children(pid: int) -> list[int]:
    found = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            found += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return found


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def fds(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def shm_segments(pid: int) -> set[str]:
    return {line.split()[-1] for line in Path(f"/proc/{pid}/maps").read_text().splitlines() if "/dev/shm/" in line}


def row_line(row: dict) -> str:
    return (f"scan {row['scan']:3d}  {row['wall_s']:5.1f} s  {row['state']:6s} {row['palpations']:2d} palpations  "
            f"daemon {row['daemon_rss_mb']:6.1f} MB {row['daemon_fds']:3d} fds  "
            f"servo {row['servo_rss_mb'] or 0:6.1f} MB {row['servo_fds'] or 0:3d} fds  shm {row['shm_segments']}  "
            f"sessions {row['sessions_mb']:6.2f} MB")


def summarize(rows: list[dict]) -> dict:
    if not rows:
        return {}
    first, last = rows[0], rows[-1]
    return {"scans": len(rows),
            "daemon_rss_mb": {"after_first": first["daemon_rss_mb"], "end": last["daemon_rss_mb"],
                              "max": max(r["daemon_rss_mb"] for r in rows),
                              "change_percent": round(100 * (last["daemon_rss_mb"] / first["daemon_rss_mb"] - 1), 1)},
            "servo_rss_mb": {"after_first": first["servo_rss_mb"], "end": last["servo_rss_mb"]},
            "daemon_fds": {"after_first": first["daemon_fds"], "end": last["daemon_fds"],
                           "max": max(r["daemon_fds"] for r in rows)},
            "servo_fds": {"after_first": first["servo_fds"], "end": last["servo_fds"]},
            "shm_segments_max": max(r["shm_segments"] for r in rows),
            "sessions_mb_max": max(r["sessions_mb"] for r in rows)}


def summary_line(summary: dict, minutes: float) -> str:
    if not summary:
        return "no scan finished"
    d, f = summary["daemon_rss_mb"], summary["daemon_fds"]
    return (f"{summary['scans']} scans in {minutes:g} min: daemon memory {d['after_first']:.1f} MB after the first "
            f"scan, {d['end']:.1f} MB at the end ({d['change_percent']:+.1f} %, max {d['max']:.1f}); daemon fds "
            f"{f['after_first']} -> {f['end']} (max {f['max']}); servo {summary['servo_rss_mb']['after_first']} -> "
            f"{summary['servo_rss_mb']['end']} MB, fds {summary['servo_fds']['after_first']} -> "
            f"{summary['servo_fds']['end']}; shared-memory segments at most {summary['shm_segments_max']}; "
            f"sessions at most {summary['sessions_mb_max']:.1f} MB")
