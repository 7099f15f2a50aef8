"""Key file hygiene: a CURVE secret key only its owner can read, key lists only their owner can change.

What ssh does for its keys: a secret key readable by group or others, a key file or directory others can
write, or a client's secret key left in the daemon's key lists is refused, in one line naming the file and
the command that fixes it. Each check returns that line, or None; the caller raises it as its own error.
"""
from __future__ import annotations

import os
import stat
from pathlib import Path

SECRET_SUFFIX = ".key_secret"
PUBLIC_SUFFIX = ".key"


def secret_key_problem(path: str | Path) -> str | None:
    """A secret key file must be this user's, mode 0600 or stricter, in a directory others cannot write."""
    path = Path(path)
    try:
        info = path.stat()
    except OSError:
        return None  # missing or unreadable: the loader says so with the reason
    mode = stat.S_IMODE(info.st_mode)
    if mode & 0o077:
        return f"{path} is open to group or others (mode {mode:04o}); a secret key must be private: chmod 600 {path}"
    if info.st_uid != os.geteuid():
        return (f"{path} belongs to uid {info.st_uid}, not to this user (uid {os.geteuid()}); "
                f"chown {os.geteuid()} {path}")
    return writable_by_others_problem(path.parent, sticky_ok=True)


def writable_by_others_problem(path: str | Path, sticky_ok: bool = False) -> str | None:
    """Anyone who can write a key list can add an operator; anyone who can write the directory of the daemon's
    secret key can swap it (unless the directory is sticky, as /tmp is: then only the file's owner can)."""
    path = Path(path)
    try:
        mode = stat.S_IMODE(path.stat().st_mode)
    except OSError:
        return None
    if mode & stat.S_IWOTH and not (sticky_ok and mode & stat.S_ISVTX):
        return f"{path} is writable by others (mode {mode:04o}), so anyone could add or swap a key: chmod o-w {path}"
    return None


def key_list_problem(directory: str | Path) -> str | None:
    """A directory of clients' public keys: not writable by others, no file in it either, and no secret keys
    (a client's secret key belongs on the client's machine, never on the daemon's)."""
    directory = Path(directory)
    problem = writable_by_others_problem(directory)
    if problem:
        return problem
    for entry in sorted(directory.iterdir()):
        if entry.name.endswith(SECRET_SUFFIX):
            return (f"{entry} is a client's secret key on the daemon's host: move it to the client's machine "
                    f"(only {entry.name[:-len(SECRET_SUFFIX)]}{PUBLIC_SUFFIX} stays here)")
        problem = writable_by_others_problem(entry) if entry.name.endswith(PUBLIC_SUFFIX) else None
        if problem:
            return problem
    return None
