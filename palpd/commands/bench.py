"""palpd bench: benchmarks that print figures (never timed tests).

Each benchmark lives in palpd/commands/bench_<name>.py with ``add_parser`` and ``run``,
listed in BENCHMARKS.
"""
from __future__ import annotations

import importlib

BENCHMARKS: list[str] = ["loop", "stall", "learner", "tradeoff", "calibration", "drivers", "hotpath", "extremes",
                          "mechanics", "soak"]


def add_parser(subparsers):
    bench = subparsers.add_parser("bench", help="measure performance and print figures")
    kinds = bench.add_subparsers(dest="benchmark", required=True, metavar="BENCHMARK")
    for name in BENCHMARKS:
        module = importlib.import_module(f"palpd.commands.bench_{name}")
        module.add_parser(kinds).set_defaults(bench_handler=module.run)
    return bench


def run(args) -> int:
    return args.bench_handler(args)
