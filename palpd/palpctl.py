"""palpctl: talk to a running palpd over its command socket (DEALER to the daemon's ROUTER) and its events (SUB).

With CURVE (a daemon on the network): --server-key is the daemon's public key
file, --key this client's key pair file (NAME.key_secret from `palpd keygen`).
"""
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
    parser.add_argument("--events", default=BusSettings().events, help="the daemon's event endpoint (watch)")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, metavar="S")
    parser.add_argument("--server-key", metavar="FILE", help="the daemon's public key (CURVE)")
    parser.add_argument("--key", metavar="FILE", help="this client's secret key file (CURVE)")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands.add_parser("status", help="lifecycle state and progress")
    scan = commands.add_parser("scan", help="start or stop a scan")
    scan.add_argument("action", choices=["start", "stop"])
    scan.add_argument("--strategy", choices=["active", "raster", "random"])
    scan.add_argument("--max-palpations", type=int)
    scan.add_argument("--seed", type=int)
    scan.add_argument("--center-mm", type=float, nargs=2, metavar=("X", "Y"), help="centre of the region")
    scan.add_argument("--size-mm", type=float, nargs=2, metavar=("W", "H"), help="size of the region")
    scan.add_argument("--depth-mm", type=float)
    scan.add_argument("--speed-mm-s", type=float)
    scan.add_argument("--resume", action="store_true", help="continue the unfinished session")
    commands.add_parser("estop", help="stop the robot now (latched)")
    commands.add_parser("reset", help="clear a latched fault")
    commands.add_parser("estimate", help="the current lump estimate")
    commands.add_parser("bias", help="tare the force sensor out of contact")
    probe = commands.add_parser("probe", help="one palpation at a point")
    probe.add_argument("xy_mm", type=float, nargs=2, metavar=("X", "Y"))
    commands.add_parser("watch", help="one line per palpation and estimate, until interrupted")
    plot = commands.add_parser("plot", help="map of probes and lumps with their uncertainty")
    plot.add_argument("file", metavar="FILE.png")
    return parser


def request_for(args) -> tuple[str, dict]:
    if args.command == "scan":
        names = ("strategy", "max_palpations", "seed", "center_mm", "size_mm", "depth_mm", "speed_mm_s")
        options = {name: getattr(args, name) for name in names} | {"resume": args.resume or None}
        return f"scan.{args.action}", {k: v for k, v in options.items() if v is not None} if args.action == "start" else {}
    if args.command == "probe":
        return "probe.at", {"xy_mm": args.xy_mm}
    return {"estimate": "estimate.get", "plot": "estimate.get"}.get(args.command, args.command), {}


def curve_options(args) -> dict:
    if not args.server_key and not args.key:
        return {}
    if not (args.server_key and args.key):
        raise ValueError("CURVE needs both --server-key and --key")
    import zmq.auth

    server_public, _ = zmq.auth.load_certificate(args.server_key)
    public, secret = zmq.auth.load_certificate(args.key)
    if secret is None:
        raise ValueError(f"{args.key} holds no secret key")
    return {"curve_serverkey": server_public, "curve_publickey": public, "curve_secretkey": secret}


def _socket(context, kind, endpoint, curve: dict):
    socket = context.socket(kind)
    socket.setsockopt(zmq.LINGER, 0)
    for option, value in curve.items():
        setattr(socket, option, value)
    socket.connect(endpoint)
    return socket


def call(endpoint: str, cmd: str, cmd_args: dict, timeout_s: float, curve: dict | None = None) -> dict:
    """One request, one reply; raises TimeoutError when the daemon does not answer in time."""
    request_id = uuid.uuid4().hex
    with zmq.Context() as context, _socket(context, zmq.DEALER, endpoint, curve or {}) as socket:
        socket.setsockopt(zmq.SNDTIMEO, int(timeout_s * 1000))  # a refused CURVE handshake leaves no peer
        try:
            socket.send_json({"id": request_id, "cmd": cmd, "args": cmd_args})
        except zmq.Again:
            raise TimeoutError(f"cannot reach {endpoint} within {timeout_s:g} s (are the keys right?)") from None
        if not socket.poll(int(timeout_s * 1000)):
            raise TimeoutError(f"no reply from {endpoint} within {timeout_s:g} s "
                               "(is `palpd serve` running, and are the keys right?)")
        return socket.recv_json()


def watch_line(topic: str, event: dict) -> str | None:
    if topic == "stiffness":
        x, y = event["xy_mm"]
        return f"palpation {event['index'] + 1}: ({x:6.1f}, {y:6.1f}) mm  k = {event['stiffness_n_per_mm']:.3f} N/mm"
    if topic == "estimate":
        lumps = "; ".join(f"lump at ({l['center_mm'][0]:.1f}, {l['center_mm'][1]:.1f}) r {l['radius_mm']:.1f} mm"
                          for l in event["lumps"]) or "no lump"
        return f"estimate from {event['points']} points: {lumps}{' (done)' if event.get('done') else ''}"
    if topic in ("status", "fault"):
        return f"{topic}: {event.get('state', event.get('code'))} {event.get('message', '')}".rstrip()
    return None


def watch(args, curve: dict) -> int:
    with zmq.Context() as context, _socket(context, zmq.SUB, args.events, curve) as socket:
        socket.subscribe(b"")
        status = call(args.endpoint, "status", {}, args.timeout, curve)  # late joiner: ask, then listen
        print(f"status: {status.get('state')}, {status.get('palpations')} palpations", flush=True)
        try:
            while True:
                topic, payload = socket.recv_multipart()
                line = watch_line(topic.decode(), json.loads(payload))
                if line:
                    print(line, flush=True)
        except KeyboardInterrupt:
            return 0


def plot(reply: dict, path: str) -> None:
    from palpd.plot import plot_scan

    estimate = reply.get("estimate") or {"lumps": [], "points": 0}
    report = {"strategy": "palpd", "palpations": len(reply["probes"]), "probes": reply["probes"],
              "lumps": estimate["lumps"]}
    plot_scan(report, tuple(reply["tissue_size_mm"]), path)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    cmd, cmd_args = request_for(args)
    try:
        curve = curve_options(args)
        if args.command == "watch":
            return watch(args, curve)
        reply = call(args.endpoint, cmd, cmd_args, args.timeout, curve)
        if reply.get("ok") and args.command == "plot":
            plot(reply, args.file)
            print(f"map written to {args.file}")
            return 0
    except (TimeoutError, zmq.ZMQError, ValueError, OSError) as exc:
        print(f"palpctl: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # PalpdError from plotting, say
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
