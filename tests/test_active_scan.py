"""--strategy active end to end (simulated time, the real control and fit code): one set of scans, made once.

The scenes: plain tissue (`none`, quickly), the same with 5 % texture and with a soft inclusion, a small lump at the tissue's centre, an elongated lump from a measured map (an ellipse, not a
circle), a deep lump with a wide edge (one circle, not two), a textured measured map whose stiff region
runs past the tissue's edges (decided, and reported by its part on the tissue); and, at seeds of their
own, a measured map of a lump that rises to a point (its half-height pinned) and three lumps that nearly touch.
"""
import math

import numpy as np
import pytest

from conftest import SCENES
from drivers.sim.scene import Scene, load_scene
from palpd import metrics
from palpd.bench import open_simulated_bench
from palpd.bus.messages import ModelChoice
from palpd.commands.scan import _verdict_line
from palpd.config import Settings
from palpd.plot import plot_scan
from palpd.scan import plan, run_scan

SCENE_NAMES = ("no-lump", "textured-no-lump", "elongated-lump", "deep-lump", "textured-half-map", "soft-cyst")


# Not shipped: the covering lattice of a 60 mm square has its widest hole at the centre, where a user puts a lump.
CENTRED_SMALL_LUMP = Scene(name="centred-small-lump", tissue={"size_mm": [60.0, 60.0], "stiffness_n_per_mm": 0.12},
                           lump=[{"center_mm": [0.0, 0.0], "radius_mm": 5.0, "depth_mm": 2.0, "stiffness_n_per_mm": 0.5}],
                           sensor={"noise_n": 0.01, "tilt": True})

# Not shipped: at 11 mm the covering lattice of 80 x 80 mm is 27 points, and `none` had taken 28 palpations.
PLAIN_80 = Scene(name="plain-80", tissue={"size_mm": [80.0, 80.0], "stiffness_n_per_mm": 0.12},
                 sensor={"noise_n": 0.01, "tilt": True})
UNSHIPPED = {scene.name: scene for scene in (CENTRED_SMALL_LUMP, PLAIN_80)}


def active_scan(scene: Scene, seed: int = 0) -> tuple[dict, dict]:
    """`palpd scan --strategy active --seed SEED` on the scene with default settings: its report, and how it
    compares with the scene's truth."""
    settings = Settings().updated(scan={"strategy": "active"})
    planner = plan("active", scene.tissue.size_mm, settings.learner.max_palpations, seed, settings)
    report = run_scan(open_simulated_bench(settings, scene, seed=seed), settings, planner)
    return report, metrics.compare(metrics.scene_truth(scene), report["lumps"], scene.tissue.size_mm)


@pytest.fixture(scope="module")
def scans() -> dict:
    return {name: active_scan(UNSHIPPED[name] if name in UNSHIPPED else load_scene(SCENES / f"{name}.toml"))
            for name in SCENE_NAMES + tuple(UNSHIPPED)}


@pytest.mark.parametrize("name", ["no-lump", "textured-no-lump"])
def test_plain_tissue_is_none_within_20_palpations_once_every_spot_is_within_11_mm_of_a_reading(scans, name):
    """Textured too: `none` leaves 5x the readings' noise there, what neighbouring readings differ by (before,
    no hypothesis was adequate, and the scan ended `undetermined` at the budget)."""
    report, m = scans[name]
    assert report["faults"] == [] and report["verdict"] == "none" and report["lumps"] == []
    assert report["model"]["chosen"] == "none" and report["model"]["weight"] >= 0.9
    assert report["palpations"] <= 20 and m["false_lumps"] == 0  # 18: the covering lattice's 16, the centre, one more


def test_plain_tissue_wider_than_60_mm_is_none_within_20_palpations_and_says_what_it_rules_out(scans):
    """The `none` reach widens with the tissue (design.none_reach), so the claim costs what it does on 60 mm,
    and the report says how large a lump it leaves open (more than 11 mm; at most `coverage_mm`)."""
    report, m = scans["plain-80"]
    assert report["faults"] == [] and report["verdict"] == "none" and m["false_lumps"] == 0
    assert report["palpations"] <= 20, report["palpations"]
    assert 11.0 < report["model"]["unfelt_radius_mm"] <= Settings().learner.coverage_mm, report["model"]


def test_tissue_with_a_soft_inclusion_is_none_within_20_palpations_and_the_model_draws_where_it_is_soft(scans, tmp_path):
    """A cyst 3x softer than the tissue: before `none+soft:1`, no model had room for it and the scan ended
    `undetermined` at the budget, a stiff half-disc beside the cyst its likeliest answer."""
    report, m = scans["soft-cyst"]
    assert report["faults"] == [] and report["verdict"] == "none" and report["lumps"] == [], report["model"]
    assert report["model"]["chosen"] == "none+soft:1" and report["model"]["weight"] >= 0.9, report["model"]
    assert report["palpations"] <= 20 and m["false_lumps"] == 0 and m["lumps_true"] == 0
    (soft,) = report["model"]["soft_regions"]
    assert math.dist(soft["center_mm"], (-6.0, 8.0)) < soft["radius_mm"] and soft["softer"] > 2.0, soft
    ModelChoice.model_validate(report["model"])  # the estimate event's schema holds it
    assert "no lump (tissue " in _verdict_line(report) and "x softer around (" in _verdict_line(report)
    plot_scan(report, (60.0, 60.0), tmp_path / "soft.png")  # the picture draws it dashed
    assert (tmp_path / "soft.png").stat().st_size > 10_000


def test_a_small_lump_at_the_tissue_centre_is_found_not_called_none(scans):
    """None of the covering lattice's 16 points felt it: `none` at 17 palpations, before `none` waited for the centre."""
    report, m = scans["centred-small-lump"]
    assert report["faults"] == [] and report["verdict"] == "lumps" and report["model"]["chosen"] == "circles:1"
    assert m["lumps_found"] == 1 and m["false_lumps"] == 0 and report["palpations"] <= 25
    assert m["max_center_error_mm"] <= 0.5 and m["max_radius_error_mm"] <= 0.5 and m["min_iou"] >= 0.9, m


@pytest.mark.parametrize("name, chosen", [("elongated-lump", "ellipse:1"), ("deep-lump", "circles:1")])
def test_the_simplest_adequate_model_is_chosen_and_the_lump_pinned_within_half_a_millimetre(scans, name, chosen):
    report, m = scans[name]
    assert report["faults"] == [] and report["verdict"] == "lumps"
    assert report["model"]["chosen"] == chosen and report["model"]["weight"] >= 0.9, report["model"]
    assert report["palpations"] <= 25
    assert m["lumps_found"] == 1 and m["false_lumps"] == 0
    assert m["max_center_error_mm"] <= 0.5 and m["max_radius_error_mm"] <= 0.5 and m["min_iou"] >= 0.9, m
    (lump,) = report["lumps"]
    assert lump["center_sd_mm"] <= 0.5 and lump["radius_sd_mm"] <= 0.5 and lump["edge_mm"] > 0
    assert ("axes_mm" in lump) == (chosen.startswith("ellipse"))


def test_the_elongated_lump_has_its_axes_and_angle(scans):
    (lump,) = scans["elongated-lump"][0]["lumps"]
    assert lump["axes_mm"] == pytest.approx([12.0, 5.0], abs=0.5)
    assert lump["angle_deg"] == pytest.approx(30.0, abs=3.0) and max(lump["axes_sd_mm"]) <= 0.5
    assert lump["radius_mm"] == pytest.approx(math.sqrt(12.0 * 5.0), abs=0.5)


def test_a_textured_stiff_region_past_the_tissue_edge_is_decided_and_reported_by_its_part_on_the_tissue(scans):
    """5 % texture: every hypothesis leaves ~4x the readings' noise, which neighbouring readings differ by
    too (the tissue, not a lump missed); before, the scan ended `undetermined` at the budget with an
    ellipse centred 6 mm off and 40 mm in radius, its boundary mostly where no tissue is (IoU 0.27)."""
    report, m = scans["textured-half-map"]
    assert report["faults"] == [] and report["verdict"] == "lumps", report["model"]
    # it may read to the budget: the texture keeps the stated boundary error near 0.6 mm once the area of lumps
    # no reading has felt is in it, over the default tolerance of 0.5 (it stopped at 25 before that was)
    assert report["palpations"] <= 40 and m["lumps_found"] == 1 and m["false_lumps"] == 0
    assert m["max_center_error_mm"] <= 0.5 and m["max_radius_error_mm"] <= 0.5 and m["min_iou"] >= 0.9, m
    (lump,) = report["lumps"]
    assert lump["cut_by_edge"] is True and lump["boundary_sd_mm"] <= 0.5
    assert "axes_mm" in lump and "angle_deg" in lump  # ellipse:1 (DESIGN.md), the whole shape's axes
    assert all(abs(x) <= 40.0 and abs(y) <= 20.0 for x, y in lump["boundary_mm"])
    scene = load_scene(SCENES / "textured-half-map.toml")
    truth = metrics.scene_truth(scene)
    active_iou = metrics.region_iou(truth, report["lumps"], (80.0, 40.0))
    # issue 11: on a map with a large stiff region, at least a raster scan's boundary IoU at the same count
    settings = Settings()
    raster = run_scan(open_simulated_bench(settings, scene), settings, plan("raster", (80.0, 40.0), report["palpations"], 0))
    assert active_iou >= max(0.9, metrics.region_iou(truth, raster["lumps"], (80.0, 40.0))), raster["lumps"]


def test_every_probe_is_reported_where_it_was_aimed_with_its_outcome(scans):
    for report, _ in scans.values():
        for probe in report["probes"]:
            assert probe["outcome"] in ("fit", "no_contact", "too_stiff", "too_soft", "rejected")
            assert math.dist(probe["xy_mm"], probe["target_xy_mm"]) < 1.0


def test_no_stop_on_a_reading_that_just_moved_the_radius_further_than_the_tolerance(tmp_path):
    """A broad Gaussian rise (sd 9 mm, 5x, 2 % texture) had its radius go 8.5 -> 11.3 mm on its 13th reading,
    within 1 sd before, and the scan stopped there 0.71 mm off claiming 0.30 mm; it reads on now."""
    rng = np.random.default_rng(21)
    axis = np.arange(-30.0, 30.001, 1.0)
    gx, gy = np.meshgrid(axis, axis)
    k = 0.12 + 0.48 * np.exp(-((gx + 8.0) ** 2 + (gy - 3.0) ** 2) / (2 * 9.0**2))
    rng.normal(0.0, 0.02, k.size)  # the texture of the map this was found on, made second
    k = k * (1.0 + rng.normal(0.0, 0.02, k.size).reshape(k.shape))
    rows = [f"{x:.2f},{y:.2f},{v:.5f}" for x, y, v in zip(gx.ravel(), gy.ravel(), k.ravel())]
    (tmp_path / "rise.csv").write_text("x_mm,y_mm,stiffness_n_per_mm\n" + "\n".join(rows) + "\n")
    (tmp_path / "rise.toml").write_text('name = "rise"\nseed = 2\n[tissue]\nsize_mm = [60.0, 60.0]\n'
                                        'stiffness_n_per_mm = 0.12\nmap = "rise.csv"\n[sensor]\nnoise_n = 0.01\n'
                                        'tilt = true\n')
    report, m = active_scan(load_scene(tmp_path / "rise.toml"))
    assert report["verdict"] == "lumps" and m["lumps_found"] == 1 and m["false_lumps"] == 0
    assert m["max_center_error_mm"] <= 0.5 and m["max_radius_error_mm"] <= 0.5, (report["palpations"], m)


def test_a_lump_that_rises_to_a_point_is_pinned_at_its_half_height():
    """cone-lump, seed 0: a measured map whose lump rises linearly to a point and ends 16 mm out. The family's
    tails never ended, and its best fit drew a plateau under the top and the half-height 0.5-2.3 mm too far
    out on such maps (this one 1.4 mm), the map's texture hiding the misfit (test_learner: a cone's readings).
    With tails that end on offer this seed still stopped at 15 palpations 1.4 mm wide, one reading after its
    centre had moved 4.5 sd: a posterior one reading showed too narrow is now believed only once two readings
    in a row bear it out."""
    report, m = active_scan(load_scene(SCENES / "cone-lump.toml"))
    assert report["verdict"] == "lumps" and report["model"]["chosen"] == "circles:1", report["model"]
    assert m["lumps_found"] == 1 and m["false_lumps"] == 0, m
    assert m["max_center_error_mm"] <= 0.5 and m["max_radius_error_mm"] <= 0.5 and m["min_iou"] >= 0.9, m
    assert report["palpations"] <= 25, report["palpations"]


def test_three_lumps_that_nearly_touch_on_a_measured_map_are_three_circles():
    """touching-lumps-map, seed 2: counts are built up one lump at a time, and one circle grown over two of the
    lumps stayed in every count built on it; the scan stopped at 27 palpations on that one circle (its σ_w 8.6x
    the floor, taken for the map's texture) while four circles, one a sliver, fitted the readings to the floor.
    A count is now also started from the next one's fit without each of its lumps (hypotheses._dropped)."""
    report, m = active_scan(load_scene(SCENES / "touching-lumps-map.toml"), seed=2)
    assert report["verdict"] == "lumps" and report["model"]["chosen"] == "circles:3", report["model"]
    assert m["lumps_found"] == 3 and m["false_lumps"] == 0, m
    assert m["max_center_error_mm"] <= 0.5 and m["max_radius_error_mm"] <= 0.5, m
