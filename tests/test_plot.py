"""The scan picture's and the scan command's words: what they say of the model chosen and of each lump."""
import numpy as np

from palpd.plot import _title

MODEL = {"chosen": "ellipse:1", "weight": 0.994}


def test_a_finished_scan_says_its_verdict_and_a_live_estimate_its_model():
    finished = _title({"scene": "paper", "strategy": "active", "palpations": 21, "verdict": "lumps", "model": MODEL})
    assert finished == "paper — active, 21 palpations\nlumps: ellipse:1 (weight 0.99)"
    live = _title({"session": "20261126-204938", "palpations": 19, "model": MODEL})  # palpctl plot: no verdict yet
    assert live == "session 20261126-204938 — scan, 19 palpations\nmodel ellipse:1 (weight 0.99)"
    assert _title({"session": "s", "palpations": 2, "model": None}) == "session s — scan, 2 palpations"


def test_an_undetermined_scan_s_picture_says_why():
    why = ("circles:1, the likeliest, misses its readings by 9.0x their noise floor, more than the tissue's texture "
           "accounts for: no hypothesis on offer explains them")
    title = _title({"scene": "blotches", "strategy": "active", "palpations": 40, "verdict": "undetermined",
                    "model": {**MODEL, "undecided": why}})
    first, second, *why_lines = title.split("\n")
    assert (first, second) == ("blotches — active, 40 palpations", "undetermined: ellipse:1 (weight 0.99)")
    assert " ".join(why_lines) == f"why: {why}" and all(len(line) <= 60 for line in why_lines)
    decided = _title({"scene": "p", "palpations": 9, "verdict": "lumps", "model": {**MODEL, "undecided": None}})
    assert "why" not in decided and "boundary" not in decided


def test_a_count_decided_at_the_budget_says_in_its_picture_that_the_boundary_is_not_known_to_the_tolerance():
    doubt = "the boundary's expected error is 0.82 mm, over the 0.25 mm asked"
    title = _title({"scene": "garg", "strategy": "active", "palpations": 40, "verdict": "lumps",
                    "model": {**MODEL, "undecided": None, "boundary_doubt": doubt}})
    assert " ".join(title.split("\n")[2:]) == f"boundary not known to the tolerance: {doubt}"
    undetermined = _title({"scene": "g", "palpations": 40, "verdict": "undetermined",
                           "model": {**MODEL, "undecided": "ellipse:1 misses", "boundary_doubt": doubt}})
    assert "boundary" not in undetermined  # the count's doubt comes first: that is what undetermined is about


def test_lumps_drawn_by_another_model_than_the_chosen_one_say_so_in_the_picture_and_the_verdict_line():
    """Once the chosen fit misses its readings, the free-form map may draw the lumps (decision.drawn_by)."""
    from palpd.commands.scan import _verdict_line

    drawn = {**MODEL, "runner_up": "circles:1", "drawn_by": "free-form", "undecided": "ellipse:1 misses"}
    title = _title({"scene": "r", "strategy": "active", "palpations": 40, "verdict": "undetermined", "model": drawn})
    assert title.split("\n")[1] == "undetermined: ellipse:1 (weight 0.99), drawn by free-form"
    line = _verdict_line({"verdict": "undetermined", "lumps": [], "model": drawn})
    assert "model ellipse:1, weight 0.994, runner-up circles:1; lumps drawn by free-form" in line, line
    same = {**drawn, "drawn_by": "ellipse:1"}
    assert "drawn" not in _title({"scene": "r", "palpations": 9, "verdict": "lumps", "model": same})
    assert "drawn" not in _verdict_line({"verdict": "lumps", "lumps": [], "model": same})


def test_the_picture_s_title_stays_over_the_map_and_its_probe_numbers_above_the_lumps_at_8_pt(tmp_path, monkeypatch):
    """`palpctl plot`'s title ran into the colour bar; probe numbers were 5.5 pt, under the lump outlines."""
    import matplotlib.pyplot as plt

    from palpd import plot

    kept = {}
    monkeypatch.setattr(plt, "close", lambda fig: kept.setdefault("fig", fig))
    probes = [{"xy_mm": [x, 0.0], "target_xy_mm": [x, 0.0], "stiffness_n_per_mm": 0.1 + 0.1 * i}
              for i, x in enumerate((-20.0, 0.0, 20.0))]
    circle = [[10 * np.cos(a), 10 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 40)]
    lump = {"center_mm": [0, 0], "radius_mm": 10, "center_sd_mm": 0.5, "radius_sd_mm": 0.5, "boundary_mm": circle}
    live = {"session": "20261128-051440", "strategy": "", "palpations": 3, "probes": probes, "lumps": [lump],
            "model": {"chosen": "circles:1", "weight": 1.0}}
    posterior = {"xs_mm": [-30.0, 0.0, 30.0], "ys_mm": [-30.0, 0.0, 30.0], "p_lump": np.eye(3).tolist(),
                 "confidence": 0.9}
    plot.plot_scan(live, (60.0, 60.0), tmp_path / "map.png", posterior)
    fig = kept["fig"]
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    title, bars = ax.title.get_window_extent(renderer), [a.get_window_extent(renderer) for a in fig.axes[1:]]
    assert bars and all(title.x1 < bar.x0 for bar in bars), (title, bars)
    numbers = [t for t in ax.texts if t.get_text() in ("1", "2", "3")]
    lump_z = max(line.get_zorder() for line in ax.lines)
    assert len(numbers) == 3 and all(t.get_fontsize() >= 8 and t.get_zorder() > lump_z for t in numbers)


def test_a_lump_the_tissue_edge_cuts_says_so_in_the_scan_s_lump_line():
    from palpd.commands.scan import _lump_line

    cut = {"center_mm": [-22.75, 0.76], "radius_mm": 20.92, "center_sd_mm": 0.17, "radius_sd_mm": 0.09,
           "axes_mm": [71.81, 22.28], "axes_sd_mm": [4.15, 1.17], "angle_deg": 75.4, "edge_mm": 9.0,
           "boundary_sd_mm": 0.36, "cut_by_edge": True}
    line = _lump_line(cut)
    assert "(its part on the tissue, whose edge cuts it: boundary ± 0.36 mm)" in line
    assert "whole shape's axes 71.81 ± 4.15 / 22.28 ± 1.17 mm at 75.4°" in line
    whole = {k: v for k, v in cut.items() if k not in ("cut_by_edge", "boundary_sd_mm")}
    assert "part on the tissue" not in _lump_line(whole) and ", axes 71.81" in _lump_line(whole)


def test_the_pareto_front_s_labels_never_lie_on_one_another(tmp_path, monkeypatch):
    """Close points of a front had their labels at one fixed offset: printed on top of one another."""
    import matplotlib.pyplot as plt
    from matplotlib.text import Text

    from palpd.tradeoff import pareto

    kept = {}
    monkeypatch.setattr(plt, "close", lambda fig: kept.setdefault("fig", fig))
    rows = [{"scene": "paper", "seed": 0, "strategy": "active", "palpation": "discrete",
             "setting": f"n={n};tolerance_mm=1.0", "palpations": n, "robot_time_s": 50.0 + 2.0 * n,
             "iou": 0.90 + 0.002 * n, "center_error_mm": 1.0 / n,
             "radius_error_mm": 0.1, "lumps_found": 1, "lumps_true": 1} for n in range(10, 18)]
    rows.append({**rows[-1], "strategy": "raster", "setting": "n=81", "robot_time_s": 400.0, "iou": 0.95,
                 "center_error_mm": 0.01})  # far off: the others crowd into the axes' first eighth
    pareto.plot(rows, pareto.settings_summary(rows), tmp_path / "pareto.png")
    fig = kept["fig"]
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        boxes = [Text.get_window_extent(t, renderer) for t in ax.texts]
        assert len(boxes) == 9
        assert not [(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1:] if a.overlaps(b)]
