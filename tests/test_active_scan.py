"""--strategy active end to end on the shipped scenes (simulated time, the real control and fit code)."""
import pytest

from conftest import SCENES
from drivers.sim.scene import load_scene, truth_lumps
from palpd import metrics
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.scan import plan, run_scan


@pytest.mark.parametrize("scene_name", ["two-lumps", "no-lump", "paper-edge"])
def test_active_scan_with_defaults_finds_every_lump_and_no_false_one(scene_name):
    scene = load_scene(SCENES / f"{scene_name}.toml")
    settings = Settings().updated(scan={"strategy": "active"})
    planner = plan("active", scene.tissue.size_mm, settings.learner.max_palpations, 0, settings)
    report = run_scan(open_simulated_bench(settings, scene), settings, planner)
    m = metrics.compare(truth_lumps(scene), report["lumps"])
    assert report["faults"] == [] and report["palpations"] <= 40
    assert m["lumps_found"] == len(scene.lump) and m["false_lumps"] == 0
    if scene.lump:
        assert m["max_center_error_mm"] <= 1.5 and m["max_radius_error_mm"] <= 1.5 and m["min_iou"] >= 0.8
    else:
        assert report["lumps"] == []
