"""palpctl: talk to a running palpd over its command socket (DEALER to the daemon's ROUTER)."""
from __future__ import annotations

import argparse
import json
import sys
import uuid

import zmq

from palpd.config import BusSettings

DEFAULT_TIMEOUT_S = 3.0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="palpctl", description="Control and watch a running palpd.")
    parser.add_argument("--endpoint", default=BusSettings().commands, help="the daemon's command endpoint")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, metavar="S")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands.add_parser("status", help="lifecycle state and progress")
    scan = commands.add_parser("scan", help="start or stop a scan")
    scan.add_argument("action", choices=["start", "stop"])
    scan.add_argument("--strategy", choices=["active", "raster", "random"])
    scan.add_argument("--max-palpations", type=int)
    commands.add_parser("estop", help="stop the robot now (latched)")
    commands.add_parser("reset", help="clear a latched fault")
    commands.add_parser("estimate", help="the current lump estimate")
    return parser


def request_for(args) -> tuple[str, dict]:
    if args.command == "scan":
        options = {"strategy": args.strategy, "max_palpations": args.max_palpations}
        return f"scan.{args.action}", {k: v for k, v in options.items() if v is not None}
    return {"estimate": "estimate.get"}.get(args.command, args.command), {}


def call(endpoint: str, cmd: str, cmd_args: dict, timeout_s: float) -> dict:
    """One request, one reply; raises TimeoutError when the daemon does not answer in time."""
    request_id = uuid.uuid4().hex
    with zmq.Context() as context, context.socket(zmq.DEALER) as socket:
        socket.setsockopt(zmq.LINGER, 0)
        socket.connect(endpoint)
        socket.send_json({"id": request_id, "cmd": cmd, "args": cmd_args})
        if not socket.poll(int(timeout_s * 1000)):
            raise TimeoutError(f"no reply from {endpoint} within {timeout_s:g} s (is `palpd serve` running?)")
        return socket.recv_json()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    cmd, cmd_args = request_for(args)
    try:
        reply = call(args.endpoint, cmd, cmd_args, args.timeout)
    except (TimeoutError, zmq.ZMQError, ValueError) as exc:
        print(f"palpctl: {exc}", file=sys.stderr)
        return 1
    if not reply.get("ok"):
        error = reply.get("error", {})
        print(f"palpctl: {cmd} refused ({error.get('code', '?')}): {error.get('message', '')}", file=sys.stderr)
        return 1
    print(json.dumps({k: v for k, v in reply.items() if k not in ("id", "ok")}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
