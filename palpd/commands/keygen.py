"""palpd keygen NAME: a CURVE key pair for the bus, NAME.key (public) and NAME.key_secret (secret, mode 0600).

Run it where the key will be used: the daemon's pair on the daemon's host (as the user palpd runs as), each
client's pair on that client's machine. Only public halves (NAME.key) travel: a client's into the daemon's
bus.operator_keys or bus.observer_keys, the daemon's to its clients (palpctl --server-key).
"""
from __future__ import annotations

import os
from pathlib import Path

from palpd.errors import PalpdError


def default_key_dir() -> Path:
    """$XDG_CONFIG_HOME/palpd/keys, else ~/.config/palpd/keys."""
    base = os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config"
    return Path(base) / "palpd" / "keys"


def add_parser(subparsers):
    keygen = subparsers.add_parser("keygen", help="write a CURVE key pair for the bus (secret 0600, public to share)")
    keygen.add_argument("name", metavar="NAME")
    keygen.add_argument("--dir", help="where to write NAME.key and NAME.key_secret: a directory you own, created "
                                      "0700 if missing (default: ~/.config/palpd/keys)")
    return keygen


def run(args) -> int:
    directory = Path(args.dir) if args.dir else default_key_dir()
    if "/" in args.name or args.name.strip() in ("", ".", ".."):
        raise PalpdError(f"keygen: {args.name!r} is not a plain name")
    _prepare(directory)
    public, secret = _write_pair(directory, args.name)
    print(f"public key: {public} (share this one)\nsecret key: {secret} (mode 0600: keep it here, never copy it)")
    return 0


def _prepare(directory: Path) -> None:
    """A directory this user owns and others cannot write (created 0700), without an earlier secret of NAME."""
    from palpd.bus.keyfiles import writable_by_others_problem

    try:
        directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        owner = directory.stat().st_uid
    except OSError as exc:
        raise PalpdError(f"keygen: cannot create {directory}: {exc.strerror}") from None
    if owner != os.geteuid():
        raise PalpdError(f"keygen: {directory} belongs to uid {owner}, not to you (uid {os.geteuid()}); keep secret "
                         "keys in a directory you own (the default is ~/.config/palpd/keys)")
    problem = writable_by_others_problem(directory)
    if problem:
        raise PalpdError(f"keygen: {problem}")


def _write_pair(directory: Path, name: str) -> tuple[Path, Path]:
    import zmq.auth

    if (directory / f"{name}.key_secret").exists():
        raise PalpdError(f"keygen: {directory / name}.key_secret exists; not overwriting a secret key")
    previous = os.umask(0o077)  # the secret is created private: never readable by others, not even for a moment
    try:
        public, secret = zmq.auth.create_certificates(directory, name)
    except OSError as exc:
        raise PalpdError(f"keygen: cannot write to {directory}: {exc.strerror}") from None
    finally:
        os.umask(previous)
    Path(public).chmod(0o644)  # the half to share
    return Path(public), Path(secret)
