"""Pictures of a scan: what the learner believes (P(lump) with its 50 % contour and uncertainty band), the
probes numbered in order (failed ones where they were aimed), the lumps with their uncertainty, and the truth.

Colour scales never turn noise into structure: P(lump) is always drawn on [0, 1], and the stiffness scale spans
at least MIN_CONTRAST of the median stiffness, so plain tissue stays one colour however small its noise.
Each layer is its own function (draw_posterior, draw_probes, draw_lumps, draw_truth) so a picture can add
layers (e.g. other lump shapes) without touching the others.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")  # files only; the daemon has no screen
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402
from matplotlib.patheffects import withStroke  # noqa: E402
from matplotlib.transforms import offset_copy  # noqa: E402

from palpd.errors import PalpdError  # noqa: E402

TITLE_WIDTH = 60  # characters per line of the title's last line, why a scan ended undetermined (map-wide)
PROBE_NUMBER_PT = 8  # probe numbers: readable in a README-sized picture
MIN_CONTRAST = 0.3  # the stiffness colour scale spans at least this fraction of the median (scan.min_contrast)
LUMP, TRUTH, FAILED, SOFT = "#d0009c", "k", "#c00000", "#1f77b4"


def plot_scan(report: dict, size_mm: tuple[float, float], path: str | Path, posterior: dict | None = None) -> None:
    """The scan's map as a PNG (or any format matplotlib writes, by the file's suffix)."""
    fig, ax = plt.subplots(figsize=(7.6, 6.0), dpi=110)
    half_w, half_h = size_mm[0] / 2, size_mm[1] / 2
    ax.set(xlim=(-half_w - 5, half_w + 5), ylim=(-half_h - 5, half_h + 5), aspect="equal")
    ax.add_patch(Rectangle((-half_w, -half_h), size_mm[0], size_mm[1], fill=False, ec="0.6", ls=":"))
    if posterior is not None:
        draw_posterior(fig, ax, posterior)
    draw_probes(fig, ax, report["probes"])
    draw_truth(ax, report.get("truth", {}).get("lumps", []))
    draw_lumps(ax, report["lumps"], report.get("model"))
    draw_soft_regions(ax, report.get("model"))
    ax.set(xlim=(-half_w - 5, half_w + 5), ylim=(-half_h - 5, half_h + 5), aspect="equal",
           xlabel="x (mm, tissue frame)", ylabel="y (mm, tissue frame)", title=_title(report))
    if ax.get_legend_handles_labels()[0]:
        # below the x label whatever the tissue's proportions (an offset in points, not in axes heights)
        below = offset_copy(ax.transAxes, fig=fig, y=-30, units="points")
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, 0.0), bbox_transform=below, ncol=3, fontsize=7,
                  frameon=False)
    try:
        fig.savefig(path, bbox_inches="tight")
    except OSError as exc:
        raise PalpdError(f"{path}: cannot write the plot: {exc.strerror}") from None
    finally:
        plt.close(fig)


def draw_posterior(fig, ax, posterior: dict) -> None:
    """P(lump) on a fixed [0, 1] scale, its 50 % contour, and the band where 1 - c < P < c hatched."""
    xs, ys, p = np.asarray(posterior["xs_mm"]), np.asarray(posterior["ys_mm"]), np.asarray(posterior["p_lump"])
    c = posterior["confidence"]
    image = ax.pcolormesh(xs, ys, p, cmap="Purples", vmin=0.0, vmax=1.0, shading="nearest", alpha=0.8, zorder=0)
    fig.colorbar(image, ax=ax, label="P(lump)", fraction=0.046, pad=0.02, shrink=_bar_shrink(ax))
    if p.min() < 1.0 - c < p.max() or p.min() < c < p.max():
        ax.contourf(xs, ys, p, levels=[1.0 - c, c], colors="none", hatches=["////"], zorder=1)
        ax.plot([], [], color="0.4", lw=4, alpha=0.4, label=f"uncertain: {1 - c:.0%} < P < {c:.0%}")
    if p.min() < 0.5 < p.max():
        ax.contour(xs, ys, p, levels=[0.5], colors="k", linewidths=1.2, zorder=2)
        ax.plot([], [], color="k", lw=1.2, label="P(lump) = 50 %")


def _bar_shrink(ax) -> float:
    """A colour bar as tall as the map: a tissue wider than tall draws a shorter map in the same box."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return min(1.0, (y1 - y0) / (x1 - x0))


def stiffness_norm(values) -> Normalize:
    """A colour scale over the stiffness values that spans at least MIN_CONTRAST of their median."""
    k = np.asarray([v for v in values if v is not None], dtype=float)
    if k.size == 0:
        return Normalize(0.0, 1.0)
    low, high, median = float(k.min()), float(k.max()), float(np.median(k))
    span = max(high - low, MIN_CONTRAST * median, 1e-9)
    middle = (low + high) / 2 if high - low >= MIN_CONTRAST * median else median
    return Normalize(middle - span / 2, middle + span / 2)


def draw_probes(fig, ax, probes: list[dict]) -> None:
    """Fitted probes coloured by stiffness, failed ones as crosses where they were aimed; each numbered in order."""
    fitted = [(i, p) for i, p in enumerate(probes, 1) if p["stiffness_n_per_mm"] is not None]
    failed = [(i, p) for i, p in enumerate(probes, 1) if p["stiffness_n_per_mm"] is None]
    if fitted:
        xy = np.array([p["xy_mm"] for _, p in fitted])
        points = ax.scatter(xy[:, 0], xy[:, 1], c=[p["stiffness_n_per_mm"] for _, p in fitted], cmap="viridis",
                            norm=stiffness_norm(p["stiffness_n_per_mm"] for _, p in fitted), s=30,
                            edgecolors="k", linewidths=0.4, zorder=4, label="probe (number: order)")
        beside = len(fig.axes) > 1  # the P(lump) bar is there already
        bar = fig.colorbar(points, ax=ax, label="stiffness (N/mm)", fraction=0.046, pad=0.16 if beside else 0.03,
                           shrink=_bar_shrink(ax))
        if beside:
            bar.ax.yaxis.set_label_position("left")  # clear of the P(lump) bar beside it
            bar.ax.yaxis.set_ticks_position("left")
    if failed:
        aimed = np.array([p.get("target_xy_mm") or p["xy_mm"] for _, p in failed])
        ax.scatter(aimed[:, 0], aimed[:, 1], marker="x", c=FAILED, s=36, linewidths=1.6, zorder=4,
                   label="failed probe, where aimed")
    for i, p in fitted + failed:
        x, y = p["xy_mm"] if p["stiffness_n_per_mm"] is not None else (p.get("target_xy_mm") or p["xy_mm"])
        # above the lump outlines, with a white halo: readable on any colour of the map under it
        ax.annotate(str(i), (x, y), xytext=(3.5, 3.5), textcoords="offset points", fontsize=PROBE_NUMBER_PT,
                    zorder=9, path_effects=[withStroke(linewidth=2.2, foreground="white")])


def draw_lumps(ax, lumps: list[dict], model: dict | None = None) -> None:
    """The lumps of the hypothesis that draws them (model.drawn_by: the chosen one, unless it misses the
    readings), each with its uncertainty: its boundary as reported (a circle, an ellipse or a free-form
    contour), a band from 1 sd inside to 1 sd outside it (its radius sd, the boundary scaled about the
    centre), and its centre with a 1-sd disc."""
    chosen = (model or {}).get("drawn_by") or (model or {}).get("chosen")
    for i, lump in enumerate(lumps):
        boundary = np.asarray(lump["boundary_mm"], dtype=float)
        centre = np.asarray(lump["center_mm"], dtype=float)
        spread = lump["radius_sd_mm"] / max(lump["radius_mm"], 1e-9)
        outer = centre + (boundary - centre) * (1.0 + spread)
        inner = centre + (boundary - centre) * max(1.0 - spread, 0.0)
        band = np.vstack([outer, inner[::-1]])
        ax.fill(band[:, 0], band[:, 1], color=LUMP, alpha=0.2, lw=0, zorder=6,
                label="boundary ± 1 sd" if i == 0 else None)
        ax.plot(boundary[:, 0], boundary[:, 1], color=LUMP, lw=2, zorder=6,
                label=(f"estimated lump ({chosen})" if chosen else "estimated lump") if i == 0 else None)
        ax.add_patch(Circle(centre, max(lump["center_sd_mm"], 0.2), color=LUMP, alpha=0.35, zorder=6,
                            label="centre ± 1 sd" if i == 0 else None))
        if lump.get("depth_mm") is not None:  # how deep its top lies, below its boundary's lowest point
            ax.annotate(f"top {lump['depth_mm']:.1f} ± {lump['depth_sd_mm']:.1f} mm deep",
                        (centre[0], boundary[:, 1].min()), xytext=(0, -4), textcoords="offset points",
                        ha="center", va="top", fontsize=PROBE_NUMBER_PT, color=LUMP, zorder=9,
                        path_effects=[withStroke(linewidth=2.2, foreground="white")])


def draw_soft_regions(ax, model: dict | None) -> None:
    """The soft regions the chosen model draws (none+soft:1): no lump, tissue softer there, dashed."""
    for i, soft in enumerate((model or {}).get("soft_regions") or []):
        ax.plot(*np.asarray(soft["boundary_mm"], dtype=float).T, color=SOFT, lw=1.5, ls="--", zorder=6,
                label="soft region (no lump)" if i == 0 else None)


def draw_truth(ax, lumps: list[dict]) -> None:
    """True lumps: a circle, or a measured map's region as its polygon."""
    for i, true in enumerate(lumps):
        label = "true lump" if i == 0 else None
        if true.get("boundary_mm"):
            ax.plot(*np.asarray(true["boundary_mm"], dtype=float).T, color=TRUTH, lw=1.5, zorder=5, label=label)
        else:
            ax.add_patch(Circle(true["center_mm"], true["radius_mm"], fill=False, ec=TRUTH, lw=1.5, zorder=5,
                                label=label))


def _title(report: dict) -> str:
    """One short line per fact, so the title stays over the map and clear of the colour bars beside it."""
    source = report.get("scene") or (f"session {report['session']}" if report.get("session") else "palpd")
    lines = [f"{source} — {report.get('strategy') or 'scan'}, {report['palpations']} palpations"]
    model = report.get("model")
    if model:
        said = f"{report['verdict']}: " if report.get("verdict") else "model "  # a live estimate has no verdict yet
        lines.append(f"{said}{model['chosen']} (weight {model['weight']:.2f})" + _drawn_by(model))
    metrics = report.get("metrics")
    if metrics and metrics.get("max_center_error_mm") is not None:
        lines.append(f"centre error {metrics['max_center_error_mm']:.2f} mm, "
                     f"radius error {metrics['max_radius_error_mm']:.2f} mm")
    if report.get("verdict") == "undetermined" and model and model.get("undecided"):
        lines.append(textwrap.fill(f"why: {model['undecided']}", TITLE_WIDTH))  # why, where one looks
    elif report.get("verdict") == "lumps" and model and model.get("boundary_doubt"):  # the count, not the boundary
        lines.append(textwrap.fill(f"boundary not known to the tolerance: {model['boundary_doubt']}", TITLE_WIDTH))
    return "\n".join(lines)


def _drawn_by(model: dict) -> str:
    """When the lumps are not the chosen hypothesis's (decision.drawn_by): whose they are."""
    drawn = model.get("drawn_by")
    return f", drawn by {drawn}" if drawn and drawn != model["chosen"] else ""


def posterior_of(planner, report: dict, settings, size_mm) -> dict | None:
    """The posterior behind a scan's picture: the active planner's own learner, else one fed the scan's probes."""
    from palpd.posterior import learned_from_probes, posterior_grid

    learner = getattr(planner, "learner", None)
    if learner is None:
        learner = learned_from_probes(report["probes"], size_mm, settings, report.get("seed") or 0)
    return posterior_grid(learner)
