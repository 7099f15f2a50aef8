"""palpd bench learner: one update plus next-probe choice at N points on a G × G grid,
next to a plain scikit-learn GaussianProcessRegressor refit-and-predict of the same size."""
from __future__ import annotations

import json
import time
import warnings

TRIALS = 15


def add_parser(kinds):
    bench = kinds.add_parser("learner", help="learner update + next-probe latency vs a plain sklearn GP")
    bench.add_argument("--points", type=int, default=200, metavar="N")
    bench.add_argument("--grid", type=int, default=121, metavar="G", help="candidate grid points per side")
    bench.add_argument("--json", action="store_true")
    return bench


def run(args) -> int:
    import numpy as np

    from palpd.errors import UsageError

    if args.points < 2 or not 11 <= args.grid <= 401:
        raise UsageError("--points must be at least 2 and --grid between 11 and 401")
    rng = np.random.default_rng(0)
    xy = rng.uniform(-30.0, 30.0, size=(args.points + TRIALS, 2))
    k = 0.12 + 0.68 / (1.0 + (np.hypot(xy[:, 0] - 7.5, xy[:, 1] + 4.0) / 10.0) ** 10) + rng.normal(0, 0.003, len(xy))
    update_ms = _learner_updates(xy, k, args.points, args.grid)
    sklearn_ms = _sklearn_refits(xy[:args.points], k[:args.points], args.grid)
    result = {"points": args.points, "grid": args.grid,
              "update_ms": {"p50": round(float(np.median(update_ms)), 2), "max": round(float(np.max(update_ms)), 2)},
              "sklearn_refit_predict_ms": {"p50": round(float(np.median(sklearn_ms)), 1),
                                           "max": round(float(np.max(sklearn_ms)), 1)}}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"learner update + next probe, {args.points} points, {args.grid}x{args.grid} grid: "
              f"median {result['update_ms']['p50']} ms, max {result['update_ms']['max']} ms")
        print(f"sklearn GaussianProcessRegressor fit + predict (mean, std), same size: "
              f"median {result['sklearn_refit_predict_ms']['p50']} ms")
    return 0


def _learner_updates(xy, k, points: int, grid: int) -> list[float]:
    """Times of the updates that take the learner from `points` - TRIALS/2 to `points` + TRIALS/2,
    refits included when the learner's own policy makes one there."""
    from palpd.config import LearnerSettings
    from palpd.learner import Learner

    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=grid, initial_points=0, max_palpations=10**4), 0.3)
    start = max(points - TRIALS // 2, 0)
    for i in range(start):
        learner.observe(xy[i], float(k[i]), 0.003)
    times = []
    for i in range(start, start + TRIALS):
        t0 = time.perf_counter()
        learner.observe(xy[i], float(k[i]), 0.003)
        learner.next_probe()
        times.append(1000.0 * (time.perf_counter() - t0))
    return times


def _sklearn_refits(xy, k, grid: int, repeats: int = 3) -> list[float]:
    import numpy as np
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    g = np.linspace(-30.0, 30.0, grid)
    gx, gy = np.meshgrid(g, g)
    candidates = np.column_stack([gx.ravel(), gy.ravel()])
    times = []
    warnings.simplefilter("ignore")  # sklearn's bound warnings say nothing about the timing
    for _ in range(repeats):
        t0 = time.perf_counter()
        kernel = ConstantKernel() * Matern(length_scale=5.0, nu=2.5) + WhiteKernel(1e-4)
        gpr = GaussianProcessRegressor(kernel, alpha=0.003**2, normalize_y=True).fit(xy, k)
        gpr.predict(candidates, return_std=True)
        times.append(1000.0 * (time.perf_counter() - t0))
    return times
