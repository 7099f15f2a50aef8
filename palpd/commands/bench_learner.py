"""palpd bench learner: one observe + next-probe choice at N points on a G × G grid, every update timed
from the first point to --spikes-to points, side by side with two scikit-learn baselines of the same size.

The baselines are what a user would write without palpd's incremental learner, each refitting a
GaussianProcessRegressor on all points and predicting mean and sd over the grid for every new point:
- `sklearn_fixed_kernel`: the kernel given and held (optimizer=None): the cost of refit + predict alone;
- `sklearn_optimised`: its own marginal-likelihood optimiser on every refit (the default use).
"""
from __future__ import annotations

import json
import time
import warnings

TRIALS = 15
FULL_UPDATE_POINTS = 40  # palpd.learner.model.FULL_UPDATE_POINTS (not imported: --help stays light; a test holds them equal)


def add_parser(kinds):
    bench = kinds.add_parser("learner", help="learner update + next-probe latency vs scikit-learn baselines")
    bench.add_argument("--points", type=int, default=200, metavar="N", help="median taken around N points")
    bench.add_argument("--grid", type=int, default=121, metavar="G", help="candidate grid points per side")
    bench.add_argument("--spikes-to", type=int, default=None, metavar="M",
                       help="time every update up to M points and report the largest (default: N + 7)")
    bench.add_argument("--json", action="store_true")
    return bench


def run(args) -> int:
    import numpy as np

    from palpd.errors import UsageError
    from palpd.threads import blas_threads

    spikes_to = args.spikes_to or args.points + TRIALS // 2
    if args.points < 2 or not 11 <= args.grid <= 401 or spikes_to < args.points:
        raise UsageError("--points must be at least 2, --grid between 11 and 401, --spikes-to at least --points")
    xy, k = _field(max(spikes_to, args.points + TRIALS))
    update_ms, cpu_ms = _learner_updates(xy, k, spikes_to, args.grid)
    window = slice(max(args.points - TRIALS // 2, 0), args.points + TRIALS // 2)
    around = update_ms[window]
    result = {"points": args.points, "grid": args.grid, "blas_threads": blas_threads(),
              "update_ms": {"p50": _round(np.median(around)), "max": _round(np.max(around))},
              # the process's own CPU time: what the update costs, whatever else the machine runs
              "update_cpu_ms": {"p50": _round(np.median(cpu_ms[window])), "max": _round(np.max(cpu_ms[window])),
                                "max_to_spikes": _round(np.max(cpu_ms)),
                                "over_50_ms": int(np.count_nonzero(np.asarray(cpu_ms) > 50.0))},
              "spikes": {"to_points": spikes_to, "max_ms": _round(np.max(update_ms)),
                         "at_points": int(np.argmax(update_ms)) + 1,
                         # beyond the readings where every update refits every hypothesis (learner/model.py)
                         "max_ms_after_full_refits": _round(np.max(update_ms[FULL_UPDATE_POINTS:] or [0.0]))},
              "sklearn_fixed_kernel_ms": _stats(_sklearn_refits(xy[:args.points], k[:args.points], args.grid, False)),
              "sklearn_optimised_ms": _stats(_sklearn_refits(xy[:args.points], k[:args.points], args.grid, True))}
    print(json.dumps(result) if args.json else _text(result))
    return 0


def _field(count: int):
    """Points over a 60 mm square and the paper scene's lump under them, with 3 µN/mm of noise."""
    import numpy as np

    rng = np.random.default_rng(0)
    xy = rng.uniform(-30.0, 30.0, size=(count, 2))
    k = 0.12 + 0.68 / (1.0 + (np.hypot(xy[:, 0] - 7.5, xy[:, 1] + 4.0) / 10.0) ** 10) + rng.normal(0, 0.003, count)
    return xy, k


def _learner_updates(xy, k, count: int, grid: int) -> tuple[list[float], list[float]]:
    """The wall and CPU time of every update (observe + next probe) from the first point to `count`,
    as the learner runs in a scan (its own refit policy), fed points it did not choose."""
    from palpd.config import LearnerSettings
    from palpd.learner import Learner

    # A tolerance it never meets: every update also chooses the next probe, as during a scan.
    settings = LearnerSettings(grid_points=grid, initial_points=0, max_palpations=10**4, tolerance_mm=1e-6)
    learner = Learner((60.0, 60.0), settings, 0.3)
    times, cpu = [], []
    for i in range(count):
        t0, c0 = time.perf_counter(), time.process_time()
        learner.observe(xy[i], float(k[i]), 0.003)
        learner.next_probe()
        times.append(1000.0 * (time.perf_counter() - t0))
        cpu.append(1000.0 * (time.process_time() - c0))
    return times, cpu


def _sklearn_refits(xy, k, grid: int, optimise: bool, repeats: int = 3) -> list[float]:
    import numpy as np
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    g = np.linspace(-30.0, 30.0, grid)
    gx, gy = np.meshgrid(g, g)
    candidates = np.column_stack([gx.ravel(), gy.ravel()])
    kernel = ConstantKernel(1.0) * Matern(length_scale=5.0, nu=2.5) + WhiteKernel(1e-4)
    times = []
    with warnings.catch_warnings():  # sklearn's bound warnings say nothing about the timing
        warnings.simplefilter("ignore")
        for _ in range(repeats):
            t0 = time.perf_counter()
            gpr = GaussianProcessRegressor(kernel, alpha=0.003**2, normalize_y=True,
                                           optimizer="fmin_l_bfgs_b" if optimise else None).fit(xy, k)
            gpr.predict(candidates, return_std=True)
            times.append(1000.0 * (time.perf_counter() - t0))
    return times


def _stats(times_ms) -> dict:
    import numpy as np

    return {"p50": _round(np.median(times_ms)), "max": _round(np.max(times_ms))}


def _round(value) -> float:
    return round(float(value), 2)


def _text(r: dict) -> str:
    n, g = r["points"], r["grid"]
    return "\n".join([
        f"palpd learner, observe + next probe at {n} points, {g}x{g} grid (BLAS threads: {r['blas_threads']}): "
        f"median {r['update_ms']['p50']} ms, max {r['update_ms']['max']} ms",
        f"  largest single update from 1 to {r['spikes']['to_points']} points: {r['spikes']['max_ms']} ms "
        f"(at {r['spikes']['at_points']} points); beyond {FULL_UPDATE_POINTS} points: "
        f"{r['spikes']['max_ms_after_full_refits']} ms",
        f"  CPU time (this process only): median {r['update_cpu_ms']['p50']} ms, max {r['update_cpu_ms']['max']} ms; "
        f"largest to {r['spikes']['to_points']} points {r['update_cpu_ms']['max_to_spikes']} ms, "
        f"{r['update_cpu_ms']['over_50_ms']} updates over 50 ms",
        "sklearn GaussianProcessRegressor refit + predict (mean, sd) on the same grid, per new point:",
        f"  kernel fixed (optimizer=None):      median {r['sklearn_fixed_kernel_ms']['p50']} ms",
        f"  with its optimiser (fmin_l_bfgs_b): median {r['sklearn_optimised_ms']['p50']} ms",
    ])
