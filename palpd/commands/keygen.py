"""palpd keygen NAME: a CURVE key pair (NAME.key public, NAME.key_secret secret) for the bus."""
from __future__ import annotations

from pathlib import Path

from palpd.errors import PalpdError


def add_parser(subparsers):
    keygen = subparsers.add_parser("keygen", help="write a CURVE key pair for the bus")
    keygen.add_argument("name", metavar="NAME")
    keygen.add_argument("--dir", default=".", help="where to write NAME.key and NAME.key_secret (default: here)")
    return keygen


def run(args) -> int:
    import zmq.auth

    directory = Path(args.dir)
    if "/" in args.name or not args.name.strip():
        raise PalpdError(f"keygen: {args.name!r} is not a plain name")
    if (directory / f"{args.name}.key_secret").exists():
        raise PalpdError(f"keygen: {directory / args.name}.key_secret exists; not overwriting a secret key")
    try:
        directory.mkdir(parents=True, exist_ok=True)
        public, secret = zmq.auth.create_certificates(directory, args.name)
    except OSError as exc:
        raise PalpdError(f"keygen: cannot write to {directory}: {exc.strerror}") from None
    Path(secret).chmod(0o600)
    print(f"public key: {public}\nsecret key: {secret} (keep it private)")
    return 0
