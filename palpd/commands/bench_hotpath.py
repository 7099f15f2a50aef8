"""palpd bench hotpath: the servo tick's kinematics and control math, plain floats vs numpy 3-vectors.

The plain-float side is the code the servo loop runs (model.forward, TissueFrame,
CartesianPD.currents: tau = J^T F - g(q), then currents). The numpy side is the
same math written with numpy 3-vectors and a 3x3 Jacobian, as one would write it
naturally. Both run in the same process, interleaved in rounds, on the same joint
trajectory, and must give the same currents; the figure is the median of the rounds.
"""
from __future__ import annotations

import json
import statistics
import time

ROUNDS = 5


def add_parser(subparsers):
    hotpath = subparsers.add_parser("hotpath", help="per-tick control math: plain floats vs numpy 3-vectors")
    hotpath.add_argument("--ticks", type=int, default=20000, metavar="N", help="ticks per round (default 20000)")
    hotpath.add_argument("--json", action="store_true", help="print JSON")
    hotpath.add_argument("--config", metavar="FILE", help="settings (TOML)")
    return hotpath


def run(args) -> int:
    from palpd.config import load_settings
    from palpd.errors import UsageError

    if not 100 <= args.ticks <= 10_000_000:
        raise UsageError("--ticks must be in [100, 10000000]")
    result = measure(load_settings(args.config), args.ticks)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"plain floats: {result['plain_floats_us_per_tick']} us/tick, numpy 3-vectors: "
              f"{result['numpy_us_per_tick']} us/tick ({result['numpy_over_plain']}x), {args.ticks} ticks x {ROUNDS}")
    return 0


def measure(settings, ticks: int) -> dict:
    from palpd.commands.hotpath_numpy import NumpyTick, PlainTick, joint_trajectory

    inputs = joint_trajectory(settings, ticks)
    plain, vectors = PlainTick(settings), NumpyTick(settings)
    rounds: dict[str, list[float]] = {"plain": [], "numpy": []}
    for _ in range(ROUNDS):
        for name, step in (("plain", plain.step), ("numpy", vectors.step)):
            rounds[name].append(_seconds_per_tick(step, inputs))
    difference = max(max(abs(a - b) for a, b in zip(plain.step(*x), vectors.step(*x))) for x in inputs[:200])
    plain_us, numpy_us = (1e6 * statistics.median(rounds[k]) for k in ("plain", "numpy"))
    return {"ticks": ticks, "rounds": ROUNDS, "plain_floats_us_per_tick": round(plain_us, 2),
            "numpy_us_per_tick": round(numpy_us, 2), "numpy_over_plain": round(numpy_us / plain_us, 1),
            "max_current_difference_a": difference}


def _seconds_per_tick(step, inputs) -> float:
    started = time.perf_counter()
    for q, velocity, target in inputs:
        step(q, velocity, target)
    return (time.perf_counter() - started) / len(inputs)
