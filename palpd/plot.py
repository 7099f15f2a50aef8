"""Pictures of a scan, like the seed paper's Figure 9: probes by stiffness, lumps found and true."""
from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np

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
        label = "true lump" if i == 0 else None
        if true.get("boundary_mm"):  # a measured map's region
            ax.plot(*np.asarray(true["boundary_mm"]).T, color="k", lw=1.5, label=label)
        else:
            ax.add_patch(Circle(true["center_mm"], true["radius_mm"], fill=False, ec="k", lw=1.5, label=label))
    draw_chosen_lumps(ax, report)
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


def draw_chosen_lumps(ax, report: dict) -> None:
    """The lumps of the hypothesis the evidence chose, each with its uncertainty: the boundary as
    reported (a circle, an ellipse or the free-form contour), a band from 2 sd inside to 2 sd outside
    it (its radius sd), and a 2-sd circle around the centre (its centre sd)."""
    model = report.get("model") or {}
    for i, lump in enumerate(report["lumps"]):
        boundary = np.asarray(lump["boundary_mm"], dtype=float)
        centre = np.asarray(lump["center_mm"], dtype=float)
        spread = 2.0 * lump["radius_sd_mm"] / max(lump["radius_mm"], 1e-9)
        outer = centre + (boundary - centre) * (1.0 + spread)
        inner = centre + (boundary - centre) * max(1.0 - spread, 0.0)
        band = np.vstack([outer, inner[::-1]])
        ax.fill(band[:, 0], band[:, 1], color="m", alpha=0.18, lw=0,
                label="±2 sd" if i == 0 else None)
        ax.plot(boundary[:, 0], boundary[:, 1], color="m", lw=2,
                label=f"chosen: {model.get('chosen', 'estimate')}" if i == 0 else None)
        ax.add_patch(Circle(centre, 2.0 * lump["center_sd_mm"], fill=False, ec="m", lw=1, ls="--"))
        ax.plot(*centre, "m+", ms=10, mew=2)


def _title(report: dict) -> str:
    title = f"{report.get('scene', '')} — {report['strategy']}, {report['palpations']} palpations"
    model = report.get("model")
    if model:
        title += f", {report.get('verdict', '')}: {model['chosen']} (weight {model['weight']:.2f})"
    metrics = report.get("metrics")
    if metrics and metrics.get("max_center_error_mm") is not None:
        title += f"\ncentre error {metrics['max_center_error_mm']:.2f} mm, radius error {metrics['max_radius_error_mm']:.2f} mm"
    return title
