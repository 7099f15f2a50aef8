"""Each setting's median robot time and accuracy over every scene × seed, the Pareto front of robot time
against accuracy (IoU, centre error), and the plot of both."""
from __future__ import annotations

import math
from statistics import median

KEY = ("strategy", "palpation", "setting")


def settings_summary(rows: list[dict]) -> list[dict]:
    """One line per setting: medians over its runs, and whether it is on each front.

    A run that found no lump has no centre error: it counts as infinitely far (it did not locate it).
    """
    groups: dict[tuple, list[dict]] = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in KEY), []).append(row)
    summary = [{**dict(zip(KEY, key)), "runs": len(mine),
                "palpations": median(r["palpations"] for r in mine),
                "robot_time_s": round(median(r["robot_time_s"] for r in mine), 2),
                "iou": round(median(r["iou"] for r in mine), 4),
                "center_error_mm": _median_error([r for r in mine if r["lumps_true"]])}
               for key, mine in groups.items()]
    for line in summary:
        line["front_iou"] = _on_front(line, summary, "iou", +1)
        line["front_center"] = _on_front(line, summary, "center_error_mm", -1)
    return sorted(summary, key=lambda line: line["robot_time_s"])


def _median_error(rows: list[dict]) -> float:
    errors = [math.inf if r["center_error_mm"] is None else r["center_error_mm"] for r in rows]
    return round(median(errors), 3) if errors else math.nan


def _on_front(line: dict, summary: list[dict], metric: str, sign: int) -> bool:
    return math.isfinite(line[metric]) and not any(_dominates(o, line, metric, sign) for o in summary)


def _dominates(a: dict, b: dict, metric: str, sign: int) -> bool:
    """a is at least as fast and as accurate as b, and better in one (sign +1: higher is better)."""
    if not math.isfinite(a[metric]):
        return False
    faster, better = a["robot_time_s"] <= b["robot_time_s"], sign * a[metric] >= sign * b[metric]
    return faster and better and (a["robot_time_s"] < b["robot_time_s"] or sign * a[metric] > sign * b[metric])


def per_scene_lead(rows: list[dict]) -> list[dict]:
    """For each scene: the discrete raster's median robot time and IoU (the seed paper's way, over its counts
    and seeds), and the best active run (discrete or sliding) within that time."""
    out = []
    for scene in sorted({r["scene"] for r in rows}):
        raster = [r for r in rows if r["scene"] == scene and r["strategy"] == "raster" and r["palpation"] == "discrete"]
        if not raster:
            continue
        time_s, iou = median(r["robot_time_s"] for r in raster), median(r["iou"] for r in raster)
        active = [r["iou"] for r in rows if r["scene"] == scene and r["strategy"] == "active"
                  and r["robot_time_s"] <= time_s]
        best = max(active, default=None)
        out.append({"scene": scene, "raster_median_time_s": round(time_s, 2), "raster_median_iou": round(iou, 4),
                    "best_active_iou": best, "lead": None if best is None else round(best - iou, 4)})
    return out


COLOURS = {("active", "discrete"): "tab:blue", ("active", "sliding"): "tab:red",
           ("raster", "discrete"): "tab:orange", ("raster", "sliding"): "tab:purple", ("random", "discrete"): "tab:green",
           ("random", "sliding"): "tab:olive"}


def plot(rows: list[dict], summary: list[dict], path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    panels = ((axes[0], "iou", "front_iou", "IoU (all lumps' area, median)"),
              (axes[1], "center_error_mm", "front_center", "centre error (mm, median)"))
    for ax, metric, flag, label in panels:
        _panel(ax, rows, summary, metric, flag)
        ax.set_xlabel("robot time per scan (s)")
        ax.set_ylabel(label)
    if any(isinstance(r["center_error_mm"], (int, float)) and r["center_error_mm"] > 0 for r in rows):
        axes[1].set_yscale("log")  # (on scenes without lumps there is no centre error to scale)
    axes[0].legend(fontsize=8, loc="lower right")
    fig.suptitle(f"speed for accuracy: {len(rows)} scans, {len({r['scene'] for r in rows})} scenes; "
                 "small dots = runs, big = setting medians, line = Pareto front")
    fig.tight_layout()
    for ax, metric, flag, _ in panels:  # once the layout is final: labels are placed where they show
        front = [s for s in summary if s[flag] and math.isfinite(s[metric])]
        medians = [(s["robot_time_s"], s[metric]) for s in summary if math.isfinite(s[metric])]
        label_front(ax, [(s["robot_time_s"], s[metric]) for s in front], [_setting_name(s) for s in front], medians)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _setting_name(line: dict) -> str:
    return f"{line['strategy']}{' sliding' if line['palpation'] == 'sliding' else ''} {line['setting']}"


def _panel(ax, rows, summary, metric: str, flag: str) -> None:
    for (strategy, palpation), colour in COLOURS.items():
        runs = [r for r in rows if (r["strategy"], r["palpation"]) == (strategy, palpation) and r[metric] is not None]
        ax.scatter([r["robot_time_s"] for r in runs], [r[metric] for r in runs], s=6, alpha=0.25, color=colour)
        mine = [s for s in summary if (s["strategy"], s["palpation"]) == (strategy, palpation)
                and math.isfinite(s[metric])]
        ax.scatter([s["robot_time_s"] for s in mine], [s[metric] for s in mine], s=40, color=colour,
                   edgecolors="black", label=f"{strategy} {palpation}" if mine else None)
    front = [s for s in summary if s[flag] and math.isfinite(s[metric])]
    ax.step([s["robot_time_s"] for s in front], [s[metric] for s in front], where="post", color="black", lw=1)


# Where a label may sit beside its point (offset in points, horizontal alignment), in order of preference.
LABEL_SPOTS = [((5, 4), "left"), ((5, -11), "left"), ((-5, 4), "right"), ((-5, -11), "right"),
               ((5, 14), "left"), ((-5, 14), "right"), ((5, -21), "left"), ((-5, -21), "right"),
               ((8, 26), "left"), ((-8, 26), "right"), ((8, -33), "left"), ((-8, -33), "right"),
               ((30, -30), "left"), ((30, 30), "left"), ((-30, 30), "right"), ((-30, -30), "right"),
               ((40, -50), "left"), ((-40, 50), "right")]
LEADER_PT = 20  # a label set further out than this is joined to its point by a thin line


def label_front(ax, points: list[tuple[float, float]], texts: list[str], avoid: list[tuple[float, float]]) -> None:
    """Each front point's label at the spot beside it with the fewest clashes (the first with none): clashes
    with labels placed before, with every setting's dot (`avoid`), and with the axes' edges. A front's points
    lie close: one fixed offset put their labels on one another."""
    from matplotlib.text import Text

    renderer = ax.figure.canvas.get_renderer()
    box = ax.get_window_extent(renderer)
    dots = [ax.transData.transform(xy) for xy in avoid]
    taken = []
    for xy, text in zip(points, texts):
        best = None
        for (dx, dy), align in LABEL_SPOTS:
            leader = {"arrowprops": {"arrowstyle": "-", "lw": 0.5, "color": "0.4"}} \
                if max(abs(dx), abs(dy)) > LEADER_PT else {}
            label = ax.annotate(text, xy, xytext=(dx, dy), textcoords="offset points", fontsize=7, ha=align,
                                va="center" if leader else "baseline", **leader)
            label.update_positions(renderer)
            extent = Text.get_window_extent(label, renderer)  # the words only, not the leader line
            clashes = _clashes(extent, taken, dots, box)
            if best is None or clashes < best[0]:
                if best is not None:
                    best[1].remove()
                best = (clashes, label, extent)
            else:
                label.remove()
            if clashes == 0:
                break
        taken.append(best[2])


def _clashes(extent, taken: list, dots: list, box) -> int:
    outside = not (box.x0 <= extent.x0 and extent.x1 <= box.x1 and box.y0 <= extent.y0 and extent.y1 <= box.y1)
    on_dots = sum(extent.x0 - 4 < x < extent.x1 + 4 and extent.y0 - 4 < y < extent.y1 + 4 for x, y in dots)
    return 100 * outside + 10 * sum(extent.overlaps(other) for other in taken) + on_dots
