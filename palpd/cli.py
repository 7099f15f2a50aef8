"""The palpd command line. Errors are one line on stderr and a non-zero exit, never a traceback."""
from __future__ import annotations

import argparse
import sys

from drivers.errors import DriverError
from palpd.errors import EXIT_FAILURE, PalpdError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="palpd", description="Robot palpation: find stiff lumps in soft tissue.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    scan = commands.add_parser("scan", help="palpate a scene end to end and estimate its lumps")
    scan.add_argument("--scene", required=True, help="scene file (TOML)")
    scan.add_argument("--strategy", choices=["active", "raster", "random"], help="where to palpate (default raster)")
    scan.add_argument("--max-palpations", type=int, metavar="N")
    scan.add_argument("--confidence", type=float, metavar="P", help="stopping confidence (active strategy)")
    scan.add_argument("--seed", type=int, metavar="N")
    scan.add_argument("--depth-mm", type=float, metavar="D", help="indentation depth")
    scan.add_argument("--speed-mm-s", type=float, metavar="V", help="indentation speed")
    scan.add_argument("--report", metavar="FILE.json")
    scan.add_argument("--plot", metavar="FILE.png")
    scan.add_argument("--realtime", action="store_true", help="run on the wall clock instead of simulated time")
    scan.add_argument("--config", metavar="FILE", help="settings (TOML); default: built-in, as config/palpd.toml")
    scan.add_argument("--quiet", action="store_true", help="no progress lines")
    scan.set_defaults(handler=_scan)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except (PalpdError, DriverError) as exc:
        print(f"palpd: {exc}", file=sys.stderr)
        return getattr(exc, "exit_code", EXIT_FAILURE)
    except KeyboardInterrupt:
        print("palpd: interrupted", file=sys.stderr)
        return 130


def _scan(args) -> int:
    from palpd.commands.scan import scan_command

    return scan_command(args)


if __name__ == "__main__":
    sys.exit(main())
