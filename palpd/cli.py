"""The palpd command line. Errors are one line on stderr and a non-zero exit, never a traceback.

Each subcommand lives in palpd/commands/<name>.py with two functions:
``add_parser(subparsers)`` (argparse only, no heavy imports, so ``palpd --help``
stays fast) and ``run(args) -> int``.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from drivers.errors import DriverError
from palpd import __version__
from palpd.errors import EXIT_FAILURE, PalpdError
from palpd.threads import pin_blas_to_one_thread

# Order is the order of `palpd --help`.
COMMAND_MODULES = ["scan", "scenes", "serve", "learner", "simulate", "dataset", "study", "calibration", "schema",
                   "replay", "keygen", "files", "bench"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="palpd", description="Robot palpation: find stiff lumps in soft tissue.")
    parser.add_argument("--version", action="version", version=f"palpd {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        module = importlib.import_module(f"palpd.commands.{name}")
        command = module.add_parser(subparsers)
        command.set_defaults(handler=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    pin_blas_to_one_thread()  # before numpy loads its BLAS, and inherited by every process palpd starts
    args = build_parser().parse_args(argv)
    try:
        status = args.handler(args)
        sys.stdout.flush()  # inside the try: a reader that left shows up here, not as an exit-time traceback
        return status
    except (PalpdError, DriverError) as exc:
        print(f"palpd: {exc}", file=sys.stderr)
        return getattr(exc, "exit_code", EXIT_FAILURE)
    except KeyboardInterrupt:
        print("palpd: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `palpd ... | head`: the reader left; say nothing, as other CLI tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


if __name__ == "__main__":
    sys.exit(main())
