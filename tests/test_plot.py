"""The scan picture's and the scan command's words: what they say of the model chosen and of each lump."""
from palpd.plot import _title

MODEL = {"chosen": "ellipse:1", "weight": 0.994}


def test_a_finished_scan_says_its_verdict_and_a_live_estimate_its_model():
    finished = _title({"scene": "paper", "strategy": "active", "palpations": 21, "verdict": "lumps", "model": MODEL})
    assert finished == "paper — active, 21 palpations, lumps: ellipse:1 (weight 0.99)"
    live = _title({"session": "20261126-204938", "palpations": 19, "model": MODEL})  # palpctl plot: no verdict yet
    assert live == "session 20261126-204938 — scan, 19 palpations, model ellipse:1 (weight 0.99)"
    assert _title({"session": "s", "palpations": 2, "model": None}) == "session s — scan, 2 palpations"


def test_an_undetermined_scan_s_picture_says_why():
    why = ("circles:1, the likeliest, misses its readings by 9.0x their noise floor, more than the tissue's texture "
           "accounts for: no hypothesis on offer explains them")
    title = _title({"scene": "blotches", "strategy": "active", "palpations": 40, "verdict": "undetermined",
                    "model": {**MODEL, "undecided": why}})
    first, *why_lines = title.split("\n")
    assert first == "blotches — active, 40 palpations, undetermined: ellipse:1 (weight 0.99)"
    assert " ".join(why_lines) == f"why: {why}" and all(len(line) <= 90 for line in why_lines)
    assert "\n" not in _title({"scene": "p", "palpations": 9, "verdict": "lumps", "model": {**MODEL, "undecided": None}})


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
