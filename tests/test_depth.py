"""A lump's depth (issue 49): estimated from how it is felt, by a surrogate of the finite-element tissue."""
import math

import numpy as np
import pytest
from hypothesis import given, settings as hsettings, strategies as st

from conftest import SCENES
from drivers.sim.scene import load_scene
from palpd import metrics
from palpd.learner import depth
from test_active_scan import active_scan


def test_the_issue_sphere_scans_to_one_lump_with_its_depth_within_1_mm_and_its_sd_covering_the_error():
    # a 5 mm sphere, 150 kPa, centred 8 mm deep (its top 3 mm down) in 15 kPa tissue 20 mm thick: its force
    # table ships, so this is a scan of a few seconds
    scene = load_scene(SCENES / "sphere-3d.toml")
    report, m = active_scan(scene)
    assert report["verdict"] == "lumps" and m["lumps_found"] == 1 and m["false_lumps"] == 0
    [lump], [true] = report["lumps"], metrics.scene_truth(scene)
    assert m["max_center_error_mm"] < 1.0
    error = abs(lump["depth_mm"] - true["depth_mm"])
    assert true["depth_mm"] == pytest.approx(3.0) and error < 1.0, lump
    assert error <= 2.0 * lump["depth_sd_mm"] and lump["depth_sd_mm"] < 1.5, lump  # honest, and still telling
    assert m["max_depth_error_mm"] == pytest.approx(error, abs=1e-3)


def test_the_shipped_surrogate_states_its_error_on_bodies_it_was_not_fitted_on():
    s = depth.surrogate()
    assert s.rows >= 40 and 0.0 < s.fit_sd_mm and 0.0 < s.held_out_sd_mm < 1.0
    top, sd = s.estimate(0.47, 5.1, 3.6)
    assert sd >= math.hypot(s.fit_sd_mm, s.held_out_sd_mm) - 1e-12


@hsettings(max_examples=60, deadline=None)
@given(st.floats(0.05, 3.0), st.floats(3.0, 11.0), st.floats(1.5, 6.0))
def test_a_fainter_lump_of_the_same_size_and_edge_lies_deeper(contrast, radius, edge):
    # within the fitted ranges: the tissue above a body lowers the contrast it is felt with
    s = depth.surrogate()
    lo, hi = s.ranges["contrast"]
    contrast = min(max(contrast, lo), hi / 1.5)
    deeper, shallower = s.top_mm(contrast, radius, edge), s.top_mm(1.5 * contrast, radius, edge)
    assert deeper >= shallower - 0.05 and math.isfinite(deeper) and deeper >= 0.0


def test_depth_is_compared_only_with_a_3d_scenes_inclusions():
    lump = {"center_mm": [0.0, 0.0], "radius_mm": 5.0, "boundary_mm": [[5, 0], [0, 5], [-5, 0], [0, -5], [5, 0]],
            "depth_mm": 2.5, "depth_sd_mm": 0.5}
    inclusion = {"center_mm": [0.0, 0.0], "radius_mm": 5.0, "depth_mm": 3.0, "shape": "sphere"}
    drawn = {"center_mm": [0.0, 0.0], "radius_mm": 5.0, "depth_mm": 3.0}  # a 2-D lump: depth widens its edge
    m = metrics.compare([inclusion], [lump])
    assert m["max_depth_error_mm"] == pytest.approx(0.5) and m["per_lump"][0]["depth_error_sd"] == pytest.approx(1.0)
    assert "max_depth_error_mm" not in metrics.compare([drawn], [lump])


def test_a_lump_beyond_what_the_surrogate_was_fitted_on_is_given_a_wider_sd():
    s = depth.surrogate()
    widest = s.ranges["radius_mm"][1]
    (top_in, sd_in), (top_out, sd_out) = s.estimate(0.5, widest, 3.5), s.estimate(0.5, 1.6 * widest, 3.5)
    assert top_out == pytest.approx(top_in)  # held at the fitted range's end...
    assert sd_out > sd_in + 0.5  # ...and the sd says how far the form would have gone beyond it
