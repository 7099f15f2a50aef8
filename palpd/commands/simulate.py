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
    return simulate


def run(args) -> int:
    import signal
    import threading

    from palpd.shipped import load_scene_named

    scene = load_scene_named(args.scene)
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
