"""The palpd command line. Errors are one line on stderr and a non-zero exit, never a traceback.

Each subcommand lives in palpd/commands/<name>.py with two functions:
``add_parser(subparsers)`` (argparse only, no heavy imports, so ``palpd --help``
stays fast) and ``run(args) -> int``.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from drivers.errors import DriverError
from palpd.errors import EXIT_FAILURE, PalpdError

# Order is the order of `palpd --help`.
COMMAND_MODULES = ["scan", "serve", "learner", "simulate", "dataset", "study", "calibration", "schema",
                   "replay", "keygen", "bench"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="palpd", description="Robot palpation: find stiff lumps in soft tissue.")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        module = importlib.import_module(f"palpd.commands.{name}")
        command = module.add_parser(subparsers)
        command.set_defaults(handler=module.run)
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


if __name__ == "__main__":
    sys.exit(main())
