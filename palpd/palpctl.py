"""palpctl: control and watch a running palpd, through palpd.client (commands to its ROUTER, events from its PUB).

With CURVE (a daemon on the network): --server-key is the daemon's public key
file, --key this client's key pair file (NAME.key_secret from `palpd keygen`).
Errors are one line on stderr and exit 1; usage errors exit 2; never a traceback.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time

from palpd import __version__
from palpd.bus.replies import ScanStartReply
from palpd.client import DEFAULT_TIMEOUT_S, Client, CommandRefused
from palpd.errors import PalpdError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="palpctl", description="Control and watch a running palpd.")
    parser.add_argument("--version", action="version", version=f"palpctl {__version__}")
    parser.add_argument("--endpoint", help="the daemon's command endpoint (default: bus.commands)")
    parser.add_argument("--events", help="the daemon's event endpoint, for watch (default: bus.events)")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, metavar="S")
    parser.add_argument("--server-key", metavar="FILE", help="the daemon's public key (CURVE)")
    parser.add_argument("--key", metavar="FILE", help="this client's secret key file (CURVE)")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands.add_parser("status", help="lifecycle state and progress")
    scan = commands.add_parser("scan", help="start or stop a scan")
    scan.add_argument("action", choices=["start", "stop"])
    scan.add_argument("--strategy", choices=["active", "raster", "random"],
                      help="active (default): where the online learner is least sure; raster: a square grid; "
                           "random: uniform points")
    scan.add_argument("--max-palpations", type=int, metavar="N")
    scan.add_argument("--seed", type=int, metavar="N")
    scan.add_argument("--center-mm", type=float, nargs=2, metavar=("X", "Y"), help="centre of the region")
    scan.add_argument("--size-mm", type=float, nargs=2, metavar=("W", "H"), help="size of the region")
    scan.add_argument("--depth-mm", type=float, metavar="D")
    scan.add_argument("--speed-mm-s", type=float, metavar="V")
    scan.add_argument("--palpation", choices=["discrete", "sliding"],
                      help="press point by point, or slide along paths (--max-palpations then counts paths); "
                           "default: the daemon's palpation.mode")
    resume = scan.add_mutually_exclusive_group()
    resume.add_argument("--resume", action="store_true", help="continue the unfinished session")
    resume.add_argument("--discard", action="store_true",
                        help="abandon the unfinished session and start anew (without either, palpd refuses)")
    scan.add_argument("--wait", action="store_true", help="return once the scan has ended (exit 1 on a fault)")
    commands.add_parser("estop", help="stop the robot now (latched)")
    commands.add_parser("reset", help="clear a latched fault")
    commands.add_parser("estimate", help="the latest estimate and the session's palpations (JSON)")
    commands.add_parser("bias", help="tare the force sensor out of contact; returns once the daemon is idle again")
    probe = commands.add_parser(
        "probe", help="one palpation at a point; waits for it and prints what it read",
        description="Palpate once at (X, Y) and print the reading: outcome (fit, no_contact, too_stiff, too_soft, "
                    "rejected) and stiffness in N/mm. X and Y are in mm in the tissue frame: origin at the centre "
                    "of the palpable rectangle, x and y along its sides (e.g. `palpctl probe 7.5 -4`).")
    probe.add_argument("x_mm", type=float, metavar="X", help="mm along the tissue's x side, from its centre")
    probe.add_argument("y_mm", type=float, metavar="Y", help="mm along the tissue's y side, from its centre")
    sessions = commands.add_parser("sessions", help="the sessions on disk: size and state, and the storage limits")
    sessions.add_argument("--json", action="store_true", help="the reply as JSON instead of a table")
    commands.add_parser("watch", help="one line per palpation, estimate, state change and fault, until interrupted")
    plot = commands.add_parser("plot", help="picture of the posterior map, probes and lumps with their uncertainty")
    plot.add_argument("file", metavar="FILE.png")
    return parser


def scan_options(args) -> dict:
    names = ("max_palpations", "seed", "center_mm", "size_mm", "depth_mm", "speed_mm_s", "palpation")
    options = {name: getattr(args, name) for name in names if getattr(args, name) is not None}
    return options | ({"resume": True} if args.resume else {}) | ({"discard": True} if args.discard else {})


def run(client, args) -> int:
    if args.command == "watch":
        return watch(client)
    if args.command == "plot":
        from palpd.files import check_writable

        check_writable(args.file)  # as `palpd scan --plot` does, and before asking the daemon
        print(f"map written to {plot(client.estimate(), args.file)}")
        return 0
    if args.command == "scan" and args.action == "start":
        reply = client.scan(args.strategy or "active", wait=args.wait, **scan_options(args))
        _note_raster(args, reply)
        if args.wait and reply.state == "fault":
            return _ended_in_fault(client, reply, "the scan")
    elif args.command == "probe":
        return _probe(client, args)
    elif args.command == "sessions" and not args.json:
        print(sessions_table(client.call("sessions")))
        return 0
    elif args.command == "bias":
        reply = client.bias(wait=True)  # idle again when it returns: `palpctl bias; palpctl probe X Y` works
        if reply.state == "fault":
            return _ended_in_fault(client, reply, "the tare")
    else:
        cmd = {"scan": "scan.stop", "estimate": "estimate.get"}.get(args.command, args.command)
        reply = client.call(cmd)
    print(json.dumps(reply.model_dump(mode="json", exclude={"id", "ok"}), indent=2))
    return 0


def sessions_table(reply) -> str:
    lines = [f"{'session':<20} {'status':<11} {'MB':>9}"]
    lines += [f"{s.name:<20} {s.status:<11} {s.size_mb:>9.1f}" for s in reply.sessions]
    fs = reply.filesystem
    lines.append(f"{len(reply.sessions)} sessions, {reply.total_mb:.1f} MB of daemon.max_sessions_mb = "
                 f"{reply.max_sessions_mb:g}" + (f", kept {reply.keep_days:g} days" if reply.keep_days else "")
                 + f"; filesystem {fs.used_percent:.0f} % full, {fs.free_mb:.0f} MB free"
                 + (f"; {reply.samples_dropped} raw samples not recorded (disk full)" if reply.samples_dropped else ""))
    return "\n".join(lines)


def _ended_in_fault(client, status, what: str) -> int:
    fault = client.last_fault
    said = f"{fault.code}: {fault.message}" if fault is not None else status.message
    print(f"palpctl: {what} ended in a fault ({said})", file=sys.stderr)
    return 1


def _note_raster(args, reply) -> None:
    """A raster budget a square grid cannot use whole is said (3 palpating one spot surprises); the start's
    reply says what the daemon planned (with --wait, the reply is the end's status: nothing to compare)."""
    if args.strategy != "raster" or not args.max_palpations or not isinstance(reply, ScanStartReply):
        return
    from palpd.strategies import raster_note

    note = raster_note(args.max_palpations)
    if note and reply.expected_total < args.max_palpations:
        print(f"palpctl: {note}", file=sys.stderr)


def _probe(client, args) -> int:
    """One palpation; what it read, once the daemon has finished it (JSON, as the other commands)."""
    status = client.probe(args.x_mm, args.y_mm, wait=True)
    if status.state == "fault":
        return _ended_in_fault(client, status, "the probe")
    palpation, stiffness = client.heard.get("palpation"), client.heard.get("stiffness")
    if palpation is None:
        raise TimeoutError("the probe ended but its palpation was not heard on the event endpoint (--events?)")
    reading = {"xy_mm": palpation.xy_mm, "target_xy_mm": palpation.target_xy_mm, "outcome": palpation.outcome,
               "stiffness_n_per_mm": stiffness.stiffness_n_per_mm if stiffness else None,
               "stiffness_sd_n_per_mm": stiffness.stiffness_sd_n_per_mm if stiffness else None,
               "stiffness_bound_n_per_mm": palpation.stiffness_bound_n_per_mm, "rejected": palpation.rejected}
    print(json.dumps(reading, indent=2))
    return 0


def watch_line(event, last_status: list) -> str | None:
    topic = type(event).__name__
    if topic == "Stiffness":
        x, y = event.xy_mm
        return f"palpation {event.index + 1}: ({x:6.1f}, {y:6.1f}) mm  k = {event.stiffness_n_per_mm:.3f} N/mm"
    if topic == "Palpation" and event.rejected:
        x, y = event.target_xy_mm or event.xy_mm
        return f"palpation {event.index + 1}: ({x:6.1f}, {y:6.1f}) mm  no fit: {event.rejected}"
    if topic == "Estimate":
        lumps = "; ".join(f"lump at ({l.center_mm[0]:.1f}, {l.center_mm[1]:.1f}) r {l.radius_mm:.1f} mm"
                          for l in event.lumps) or "no lump"
        model = f"; model {event.model.chosen} (weight {event.model.weight:.2f})" if event.model else ""
        return f"estimate from {event.points} points: {lumps}{model}{' (done)' if event.done else ''}"
    if topic == "Status":
        if (event.state, event.message) == tuple(last_status):  # the heartbeat: said already
            return None
        last_status[:] = [event.state, event.message]
        return f"status: {event.state} {event.message}".rstrip()
    if topic == "FaultMsg":
        return f"fault: {event.code} {event.message}"
    return None


def watch(client) -> int:
    client.status()  # a daemon that does not answer is said at once, in one line
    # Ctrl-C as a flag, not a KeyboardInterrupt: one raised while a finaliser runs is swallowed ("Exception
    # ignored in ..."), and watch would go on; the flag is seen within a poll slice.
    stopping: list[bool] = []
    previous = signal.signal(signal.SIGINT, lambda *_: stopping.append(True))
    try:
        # One subscription for the whole watch: a new one misses what is published while it connects. It
        # has connected once it hears its first event (a status heartbeat comes every second); the state
        # asked for after that is where the lines start, and no later change is missed.
        first_by = time.monotonic() + client.timeout_s  # a heartbeat comes every second from a live daemon
        heard: list[bool] = []
        events = client.events(stop=lambda: bool(stopping) or (not heard and time.monotonic() > first_by))
        if next(events, None) is None:
            if stopping:
                return 0
            raise TimeoutError(f"nothing answered on {client.events_endpoint} within {client.timeout_s:g} s "
                               "(is --events the daemon's event endpoint?)")
        heard.append(True)
        status = client.status()  # a late joiner: the state now, then every change
        print(f"status: {status.state}, {status.palpations} palpations", flush=True)
        last_status = [status.state, status.message]
        for event in events:
            line = watch_line(event, last_status)
            if line:
                print(line, flush=True)
    finally:
        signal.signal(signal.SIGINT, previous)
    return 0


def plot(reply, path: str) -> str:
    from palpd.plot import plot_scan

    estimate = reply.estimate
    report = {"session": reply.session, "strategy": "", "palpations": len(reply.probes),
              "probes": [p.model_dump(mode="json") for p in reply.probes],
              "lumps": [l.model_dump(mode="json") for l in estimate.lumps] if estimate else [],
              "model": estimate.model.model_dump(mode="json") if estimate and estimate.model else None}
    plot_scan(report, reply.tissue_size_mm, path, reply.map.model_dump() if reply.map else None)
    return path


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        with Client(args.endpoint, args.events, timeout_s=args.timeout, server_key=args.server_key,
                    key=args.key) as client:
            status = run(client, args)
        sys.stdout.flush()  # inside the try: a reader that left shows up here, not as an exit-time traceback
        return status
    except BrokenPipeError:  # `palpctl estimate | head`: the reader left; say nothing, as other tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except KeyboardInterrupt:
        return 130
    except (CommandRefused, PalpdError, TimeoutError, ValueError, OSError) as exc:
        print(f"palpctl: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - a user never sees a traceback (zmq errors, a bad key file...)
        print(f"palpctl: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
