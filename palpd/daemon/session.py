"""Sessions on disk: one directory per scan with session.json, the palpation journal and MCAP recordings.

The journal (JSON Lines) is fsynced after every palpation: whatever it holds
survives kill -9 or power loss, and is what crash recovery reloads.
"""
from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path

from palpd.errors import ConfigError, PalpdError, StorageError
from palpd.files import is_storage_error, open_for_writing, write_json

JOURNAL, META = "journal.jsonl", "session.json"
UNFINISHED = "unfinished"
PROBES = "probes"  # the status of a session of single palpations (probe.at): never resumed, always journaled


def state_directory(configured: str) -> Path:
    if configured:
        return Path(configured)
    if os.environ.get("STATE_DIRECTORY"):  # systemd's StateDirectory=
        return Path(os.environ["STATE_DIRECTORY"].split(":")[0])
    return Path.home() / ".local" / "state" / "palpd"


class Session:
    def __init__(self, path: Path, meta: dict, entries: list[dict]) -> None:
        self.path, self.meta, self.entries = path, meta, entries
        self._journal = None

    @classmethod
    def create(cls, sessions_dir: Path, scan_args: dict, status: str = UNFINISHED) -> "Session":
        name = time.strftime("%Y%m%d-%H%M%S")
        path = sessions_dir / name
        suffix = 1
        while path.exists():
            suffix += 1
            path = sessions_dir / f"{name}-{suffix}"
        path.mkdir(parents=True)
        session = cls(path, {"name": path.name, "status": status, "scan": scan_args, "created": time.time()}, [])
        try:
            session.save_meta()
        except PalpdError:  # a full disk: no session without its session.json left behind
            shutil.rmtree(path, ignore_errors=True)
            raise
        return session

    @classmethod
    def load(cls, path: Path) -> "Session":
        meta = json.loads((path / META).read_text())
        return cls(path, meta, read_journal(path / JOURNAL))

    @property
    def name(self) -> str:
        return self.path.name

    def save_meta(self) -> None:
        write_json(self.path / META, self.meta)

    def next_recording(self) -> Path:
        """A new MCAP file per run of the session (a crashed run's file stays as it was cut)."""
        runs = len(list(self.path.glob("recording-*.mcap")))
        return self.path / f"recording-{runs + 1}.mcap"

    def journal(self, entry: dict) -> None:
        """Append and fsync one palpation; on a storage error the journal is dropped (a torn line is cut when it
        is opened again) and the error raised: the entry counts only once it is on the disk."""
        try:
            if self._journal is None:
                self._journal = _open_for_append(self.path / JOURNAL)
            self._journal.write(json.dumps(entry) + "\n")
            self._journal.flush()
            os.fsync(self._journal.fileno())
        except OSError:
            self._drop_journal()
            raise
        self.entries.append(entry)

    def _drop_journal(self) -> None:
        journal, self._journal = self._journal, None
        if journal is not None:
            try:
                journal.close()  # flushes what the failed write left buffered: fails again, and closes anyway
            except OSError:
                pass

    def finish(self, status: str) -> None:
        self.meta["status"] = status
        self.save_meta()
        self.close()

    def close(self) -> None:
        """The journal closed, the session as it is (an unfinished one stays resumable)."""
        self._drop_journal()


def read_journal(path: Path) -> list[dict]:
    """Every complete line; a line cut by a crash is not a palpation."""
    if not path.exists():
        return []
    entries = []
    for line in path.read_text().splitlines(keepends=True):
        if not line.endswith("\n"):
            break
        try:
            entries.append(json.loads(line))
        except json.JSONDecodeError:
            break
    return entries


def _open_for_append(path: Path):
    """Cut a torn last line (from a crash) before appending, so the journal stays one entry per line."""
    if path.exists():
        data = path.read_bytes()
        keep = data.rfind(b"\n") + 1
        if keep != len(data):
            with path.open("r+b") as handle:
                handle.truncate(keep)
    return open_for_writing(path, "a")


def find_unfinished(sessions_dir: Path) -> Session | None:
    """The newest session a crash or stop left mid-scan, if any."""
    if not sessions_dir.is_dir():
        return None
    for path in sorted((p for p in sessions_dir.iterdir() if (p / META).is_file()), reverse=True):
        try:
            session = Session.load(path)
        except (OSError, json.JSONDecodeError) as exc:
            raise ConfigError(f"{path / META}: unreadable session: {exc}") from None
        if session.meta.get("status") == UNFINISHED:
            return session
    return None


def ensure_writable(directory: Path) -> Path:
    sessions = directory / "sessions"
    try:
        sessions.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        if is_storage_error(exc):
            raise StorageError(f"cannot create {sessions}: {exc.strerror}", exc.errno) from None
        raise ConfigError(f"daemon.state_dir: cannot create {sessions}: {exc.strerror}") from None
    if not os.access(sessions, os.W_OK):
        raise ConfigError(f"daemon.state_dir: {sessions} is not writable")
    return sessions
