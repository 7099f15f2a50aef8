"""Writing result files so that a crash never leaves half a file behind."""
from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
from pathlib import Path

from palpd.errors import PalpdError, StorageError

# What the storage, not the caller, got wrong: a full disk or quota, a failing disk, a filesystem remounted
# read-only. The daemon makes these a `storage` fault; anything else stays a bug or a configuration error.
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS})


def open_for_writing(path: str | Path, mode: str = "w"):
    """Every file the daemon writes its sessions to is opened here: the one seam where tests put a disk that fills
    up after N bytes (tests/full_disk.py), so the storage faults are tested without mounting anything."""
    return open(path, mode)


def disk_usage(path: str | Path):
    """(total, used, free) bytes of the filesystem holding `path` (the seam's other half: how full it is)."""
    return shutil.disk_usage(path)


def is_storage_error(exc: BaseException) -> bool:
    return isinstance(exc, StorageError) or (isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS)


def check_writable(*paths: str | Path | None) -> None:
    """Fail now, not after a long scan, when one of `paths` (None: not asked for) could not be written later."""
    for path in paths:
        if path is not None:
            _check_writable(Path(path))


def _check_writable(path: Path) -> None:
    """Its directory must exist and be writable (never made: a typo would make a tree, as root a root-owned
    one); the path must not be a directory. `palpd scan --report`, `palpctl plot` and the rest say it alike."""
    parent = path.parent if str(path.parent) else Path(".")
    if parent.is_file():
        raise PalpdError(f"{path}: cannot write: {parent} is a file, not a directory")
    if not parent.is_dir():
        raise PalpdError(f"{path}: cannot write: there is no directory {parent}")
    if path.is_dir():
        raise PalpdError(f"{path}: cannot write: Is a directory")
    try:  # a file made there and dropped: os.access says yes to root wherever permissions are the only bar (/proc too)
        with tempfile.TemporaryFile(dir=path.parent):
            pass
    except OSError as exc:
        raise PalpdError(f"{path}: cannot write: {exc.strerror or exc}") from None
    if path.exists() and not os.access(path, os.W_OK):
        raise PalpdError(f"{path}: cannot write: Permission denied")


def write_json(path: str | Path, data) -> None:
    write_text(path, json.dumps(data, indent=2) + "\n")


def write_text(path: str | Path, text: str) -> None:
    """Write to a temporary file, fsync, then rename over the target."""
    path = Path(path)
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        with open_for_writing(temporary, "w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except OSError as exc:
        if exc.errno in STORAGE_ERRNOS:
            raise StorageError(f"{path}: cannot write: {exc.strerror}", exc.errno) from None
        raise PalpdError(f"{path}: cannot write: {exc.strerror}") from None
