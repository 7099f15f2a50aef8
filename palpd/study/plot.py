"""Pictures of a study: FP+FN per method and algorithm (the paper's Figure 10) and maps (Figure 9)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

from palpd.errors import PalpdError  # noqa: E402
from palpd.study.methods import METHODS  # noqa: E402

COLOURS = {"lr": "tab:blue", "gda": "tab:orange", "svm": "tab:green", None: "tab:gray"}


def plot_study(results: list[dict], tests: list, path) -> None:
    fig = plt.figure(figsize=(13, 8.5), dpi=100)
    _bars(fig.add_subplot(2, 1, 1), results)
    first = tests[0]
    for i, method in enumerate(METHODS):
        chosen = [r for r in results if r["method"] == method and r["test"] == _name(first)
                  and r["algorithm"] in ("svm", None)]
        if chosen:
            _map(fig.add_subplot(2, len(METHODS), len(METHODS) + i + 1), first, chosen[0])
    fig.tight_layout()
    try:
        fig.savefig(path)
    except OSError as exc:
        raise PalpdError(f"{path}: cannot write the plot: {exc.strerror}") from None
    finally:
        plt.close(fig)


def _name(test) -> str:
    from pathlib import Path

    return Path(test.path).name


def _bars(ax, results: list[dict]) -> None:
    """Mean (FP+FN)/n over the test sets, one group per method, one bar per algorithm."""
    for m, method in enumerate(METHODS):
        algorithms = sorted({r["algorithm"] for r in results if r["method"] == method}, key=str)
        for a, algorithm in enumerate(algorithms):
            rows = [r for r in results if r["method"] == method and r["algorithm"] == algorithm]
            rate = 100.0 * np.mean([(r["fp"] + r["fn"]) / r["n"] for r in rows])
            ax.bar(m + (a - (len(algorithms) - 1) / 2) * 0.25, rate, 0.24, color=COLOURS[algorithm],
                   label=algorithm or "k-means" if m in (0, 3) else None)
    ax.axhline(10.0, color="k", ls=":", lw=1, label="paper ~10 %")
    ax.set_xticks(range(len(METHODS)), METHODS)
    ax.set_ylabel("FP + FN (% of test points)")
    ax.legend(fontsize=8)


def _map(ax, test, result: dict) -> None:
    ax.scatter(*test.xy_mm.T, c=test.stiffness_n_per_mm, cmap="coolwarm", s=14, edgecolors="k", linewidths=0.2)
    tumor = test.tumor.astype(bool)
    ax.scatter(*test.xy_mm[tumor].T, facecolors="none", edgecolors="k", s=40, lw=0.8)
    if result["center_mm"] is not None:
        ax.add_patch(Circle(result["center_mm"], result["radius_mm"], fill=False, ec="m", lw=1.5))
        ax.plot(*result["center_mm"], "m+")
    ax.set(aspect="equal", title=f"{result['method']}\n{result['algorithm'] or 'k-means'}: "
                                 f"FP {result['fp']}, FN {result['fn']}")
    ax.title.set_fontsize(8)
    ax.tick_params(labelsize=6)
