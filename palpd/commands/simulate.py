"""palpd simulate: the simulated bench served standalone (bridge over TCP or a pty, Net F/T over UDP).

It prints one line per endpoint (``bridge socket://127.0.0.1:PORT``, ``bridge serial:///dev/pts/N``,
``netft netft://127.0.0.1:PORT``) and then ``ready``, and serves until SIGINT or SIGTERM.
"""
from __future__ import annotations

from palpd.errors import PalpdError, UsageError


def add_parser(subparsers):
    simulate = subparsers.add_parser("simulate", help="serve simulated hardware for palpd or any other program")
    simulate.add_argument("--scene", required=True, metavar="FILE|NAME", help="scene file (TOML) or shipped scene name")
    simulate.add_argument("--bridge", default="tcp://127.0.0.1:0", metavar="tcp://HOST:PORT|pty",
                          help="where the Phantom bridge listens (port 0: any free port; default tcp://127.0.0.1:0)")
    simulate.add_argument("--netft", metavar="HOST:PORT", help="also serve a Net F/T RDT endpoint here")
    simulate.add_argument("--seed", type=int, default=0)
    simulate.add_argument("--fault", action="append", default=[], metavar="KIND@T[=VALUE]",
                          help="develop a fault T seconds after start (as a scene's [faults] table): sensor_frozen, "
                               "sensor_drift (VALUE N/s on the sensor's z, default -0.5), nan_samples, encoder_jump "
                               "(VALUE counts, default 400), amplifier_fault; repeatable")
    return simulate


def run(args) -> int:
    import signal
    import threading

    from palpd.shipped import load_scene_named

    scene = with_faults(load_scene_named(args.scene), args.fault)
    from drivers.clock import RealClock
    from drivers.sim.servers import SimulatorHost
    from drivers.sim.world import SimWorld

    host = SimulatorHost(SimWorld(scene, RealClock(), seed=args.seed))
    try:
        _add_endpoints(host, args)
    except OSError as exc:
        host.close()
        raise PalpdError(f"cannot serve the simulated bench: {exc.strerror or exc}") from None
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    print("ready", flush=True)
    try:
        host.serve(stop)
    finally:
        host.close()
    return 0


def with_faults(scene, specs: list[str]):
    """The scene with `--fault KIND@T[=VALUE]` added to its [faults] table (a later one of a kind wins)."""
    import sys

    from drivers.sim.faults import FAULT_KINDS
    from drivers.sim.scene import FaultAt

    faults = dict(scene.faults)
    for spec in specs:
        kind, _, rest = spec.partition("@")
        at, _, value = rest.partition("=")
        if kind not in FAULT_KINDS:
            raise UsageError(f"--fault {spec!r}: unknown kind {kind!r}; kinds: {', '.join(FAULT_KINDS)}")
        try:
            faults[kind] = FaultAt(at_s=float(at), value=float(value) if value else None)
        except ValueError:
            raise UsageError(f"--fault {spec!r}: expected KIND@SECONDS[=VALUE], e.g. sensor_drift@5=-0.5") from None
    for kind, fault in sorted(faults.items(), key=lambda item: item[1].at_s):
        value = "" if fault.value is None else f" (value {fault.value:g})"
        print(f"palpd simulate: {kind} at {fault.at_s:g} s{value}", file=sys.stderr, flush=True)
    return scene.model_copy(update={"faults": faults})


def _add_endpoints(host, args) -> None:
    from drivers.sim.netft_server import NetFtEndpoint
    from drivers.sim.servers import PtyBridgeEndpoint, TcpBridgeEndpoint

    if args.bridge == "pty":
        bridge = host.add(PtyBridgeEndpoint(host.device))
    elif args.bridge.startswith("tcp://"):
        bridge = host.add(TcpBridgeEndpoint(host.device, *_host_port(args.bridge[len("tcp://"):], "--bridge")))
    else:
        raise UsageError(f"--bridge {args.bridge!r}: expected tcp://HOST:PORT or pty")
    print(f"bridge {bridge.url}", flush=True)
    if args.netft:
        netft = host.add(NetFtEndpoint(host.world, *_host_port(args.netft, "--netft")))
        print(f"netft {netft.url}", flush=True)


def _host_port(text: str, option: str) -> tuple[str, int]:
    name, _, port = text.rpartition(":")
    if not name or not port.isdigit() or int(port) > 65535:
        raise UsageError(f"{option} {text!r}: expected HOST:PORT")
    return name, int(port)
