"""The sessions' storage: what a storage error says, how full the disk is, and pruning old sessions.

A daemon that runs for months must neither die on a full disk nor fill it. A
storage error (palpd.files.STORAGE_ERRNOS) while recording or journaling is a
`storage` fault with a one-line cause; finished sessions are pruned, oldest
first, to `daemon.max_sessions_mb` and `daemon.keep_days`; an unfinished session
is never pruned.
"""
from __future__ import annotations

import json
import logging
import os
import shutil
import time
from pathlib import Path

from palpd.files import disk_usage, open_for_writing

log = logging.getLogger("palpd.storage")
MB = 1 << 20
WARN_FRACTION = 0.9  # warn when the sessions reach this share of their limit, or the filesystem of its size
KEEP = ("unfinished",)  # statuses never pruned
DAY_S = 86400.0


def fullness(directory: Path) -> str:
    """'filesystem of /state: 2.9 of 3.0 MB used (97 %)', or why that is unknown."""
    try:
        total, used, _ = disk_usage(directory)
    except OSError as exc:
        return f"filesystem of {directory}: size unknown ({exc.strerror})"
    percent = 100 * used / max(total, 1)
    return f"filesystem of {directory}: {used / MB:.1f} of {total / MB:.1f} MB used ({percent:.0f} %)"


def cause(exc: BaseException, what: str, directory: Path) -> str:
    """The storage fault's one line: what failed, where, and how full the disk is."""
    reason = getattr(exc, "strerror", None) or str(exc)
    where = getattr(exc, "filename", None)
    return f"{what}: {reason}{f' ({where})' if where else ''}; {fullness(directory)}"


def probe_writable(sessions_dir: Path) -> None:
    """Write, fsync and remove a small file where the sessions go: raises the storage error a scan would meet."""
    sessions_dir.mkdir(parents=True, exist_ok=True)
    probe = sessions_dir / ".space-check"
    try:
        with open_for_writing(probe, "wb") as handle:
            handle.write(b"\0" * 4096)
            handle.flush()
            os.fsync(handle.fileno())
    finally:
        probe.unlink(missing_ok=True)


def directory_bytes(path: Path) -> int:
    total = 0
    for root, _, files in os.walk(path):
        for name in files:
            try:
                total += os.lstat(os.path.join(root, name)).st_size
            except OSError:  # gone meanwhile
                pass
    return total


def list_sessions(sessions_dir: Path) -> list[dict]:
    """Every session, oldest first: name, status, size_mb, created (Unix time). Sizes from stat only: a
    thousand sessions are listed without reading their journals (the supervisor's loop must stay quick)."""
    sessions = []
    for path in sorted(p for p in sessions_dir.iterdir() if p.is_dir()) if sessions_dir.is_dir() else []:
        try:
            meta = json.loads((path / "session.json").read_text())
        except (OSError, ValueError):
            meta = {"status": "unreadable"}
        sessions.append({"name": path.name, "status": str(meta.get("status", "unreadable")),
                         "size_mb": round(directory_bytes(path) / MB, 3),
                         "created": float(meta.get("created") or path.stat().st_mtime)})
    return sessions


def prune(sessions_dir: Path, max_mb: float, keep_days: float, in_use: set[str]) -> list[dict]:
    """Remove finished sessions, oldest first, older than keep_days (0: no age limit) or while all of them
    together exceed max_mb. Never an unfinished session, nor one in use. Returns what went, as list_sessions."""
    sessions = list_sessions(sessions_dir)
    total_mb = sum(s["size_mb"] for s in sessions)
    now = time.time()
    pruned = []
    for session in sessions:
        if session["status"] in KEEP or session["name"] in in_use:
            continue
        too_old = keep_days > 0 and now - session["created"] > keep_days * DAY_S
        if not too_old and total_mb <= max_mb:
            continue
        shutil.rmtree(sessions_dir / session["name"], ignore_errors=True)
        total_mb -= session["size_mb"]
        pruned.append(session)
        log.info("pruned session %s (%s, %.1f MB, %.1f days old): %s", session["name"], session["status"],
                 session["size_mb"], (now - session["created"]) / DAY_S,
                 f"older than daemon.keep_days = {keep_days:g}" if too_old else
                 f"the sessions exceeded daemon.max_sessions_mb = {max_mb:g}")
    return pruned


def usage_warning(sessions_dir: Path, max_mb: float) -> str:
    """A line when the sessions use WARN_FRACTION of their limit or the filesystem is that full, else ''."""
    total_mb = sum(s["size_mb"] for s in list_sessions(sessions_dir))
    if total_mb >= WARN_FRACTION * max_mb:
        return (f"sessions use {total_mb:.1f} MB of daemon.max_sessions_mb = {max_mb:g} "
                "(unfinished ones are never pruned)")
    try:
        total, used, _ = disk_usage(sessions_dir)
    except OSError:
        return ""
    if used >= WARN_FRACTION * total:
        return f"the disk is nearly full: {fullness(sessions_dir)}"
    return ""


def filesystem(sessions_dir: Path) -> dict:
    """The sessions' filesystem as `reply.sessions` carries it (zeros when it cannot be read)."""
    try:
        total, used, free = disk_usage(sessions_dir)
    except OSError:
        total = used = free = 0
    return {"total_mb": round(total / MB, 3), "free_mb": round(free / MB, 3),
            "used_percent": round(100 * used / total, 1) if total else 0.0}


class DroppedRecording:
    """Stands in for a recording the disk had no room for: the scan goes on, its raw samples are counted
    (status `samples_dropped`) instead of written, so the journal keeps what space is left."""

    def __init__(self, drain) -> None:
        self.drain = drain  # the SampleDrain, whose `dropped` the status reports

    def write(self, topic: str, payload: dict, log_time_s: float | None = None) -> None:
        pass

    def record_samples(self, batch) -> None:
        self.drain.dropped += len(batch)

    def flush_if_due(self) -> None:
        pass

    def close(self) -> None:
        pass
