"""palpd simulate: the simulated bench served standalone (bridge over TCP or a pty, Net F/T over UDP)."""
from __future__ import annotations


def add_parser(subparsers):
    simulate = subparsers.add_parser("simulate", help="serve simulated hardware for palpd or any other program")
    simulate.add_argument("--scene", required=True, help="scene file (TOML)")
    simulate.add_argument("--bridge", default="tcp://127.0.0.1:0", metavar="tcp://HOST:PORT|pty",
                          help="where the Phantom bridge listens (port 0: any free port)")
    simulate.add_argument("--netft", metavar="HOST:PORT", help="also serve a Net F/T RDT endpoint here")
    simulate.add_argument("--seed", type=int, default=0)
    return simulate


def run(args) -> int:
    from palpd.simulator import serve_simulation

    return serve_simulation(args.scene, args.bridge, args.netft, args.seed)
