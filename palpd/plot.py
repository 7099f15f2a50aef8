"""Pictures of a scan, like the seed paper's Figure 9: probes by stiffness, lumps found and true."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; the daemon has no screen
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

from palpd.errors import PalpdError  # noqa: E402


def plot_scan(report: dict, size_mm: tuple[float, float], path: str | Path) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 5.6), dpi=110)
    half_w, half_h = size_mm[0] / 2, size_mm[1] / 2
    ax.add_patch(Rectangle((-half_w, -half_h), size_mm[0], size_mm[1], fill=False, ec="0.6", ls=":"))
    probes = [p for p in report["probes"] if p["stiffness_n_per_mm"] is not None]
    if probes:
        xs, ys = zip(*(p["xy_mm"] for p in probes))
        points = ax.scatter(xs, ys, c=[p["stiffness_n_per_mm"] for p in probes], cmap="coolwarm", s=36,
                            edgecolors="k", linewidths=0.3, zorder=3)
        fig.colorbar(points, ax=ax, label="stiffness (N/mm)")
    failed = [p["xy_mm"] for p in report["probes"] if p["stiffness_n_per_mm"] is None]
    if failed:
        ax.scatter(*zip(*failed), marker="x", c="k", s=30, label="no fit", zorder=3)
    for i, true in enumerate(report.get("truth", {}).get("lumps", [])):
        ax.add_patch(Circle(true["center_mm"], true["radius_mm"], fill=False, ec="k", lw=1.5,
                            label="true lump" if i == 0 else None))
    for i, lump in enumerate(report["lumps"]):
        bx, by = zip(*lump["boundary_mm"])
        ax.plot(bx, by, color="m", lw=2, label="estimated lump" if i == 0 else None)
        ax.plot(*lump["center_mm"], "m+", ms=10, mew=2)
    ax.set(xlim=(-half_w - 5, half_w + 5), ylim=(-half_h - 5, half_h + 5), aspect="equal",
           xlabel="x (mm)", ylabel="y (mm)", title=_title(report))
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=8)
    try:
        fig.savefig(path, bbox_inches="tight")
    except OSError as exc:
        raise PalpdError(f"{path}: cannot write the plot: {exc.strerror}") from None
    finally:
        plt.close(fig)


def _title(report: dict) -> str:
    title = f"{report.get('scene', '')} — {report['strategy']}, {report['palpations']} palpations"
    metrics = report.get("metrics")
    if metrics and metrics.get("max_center_error_mm") is not None:
        title += f"\ncentre error {metrics['max_center_error_mm']:.2f} mm, radius error {metrics['max_radius_error_mm']:.2f} mm"
    return title
