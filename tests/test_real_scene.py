"""The real phantom scene (config/scenes/garg-phantom.toml): dVRK readings kept as they were read; and a scene
that reads a probe's raw readings itself (tissue.map_baseline), as a user's own real data would be replayed.

tests/data/garg-point-probe-40x20.csv is the raw data the shipped map was made from: 760 readings of a silicone
phantom by a dVRK arm (Garg et al., IEEE CASE 2016, the public repository yjen/palpation_strategy)."""
from pathlib import Path

import numpy as np
import pytest

from conftest import SCENES
from drivers.sim.scene import SceneError, load_scene, load_stiffness_map, map_rows, stiffness_from_readings
from drivers.sim.tissue import StiffnessField
from palpd import metrics

RAW = Path(__file__).parent / "data" / "garg-point-probe-40x20.csv"


def test_readings_become_stiffness_in_proportion_past_the_offset():
    k = np.array(stiffness_from_readings([9000.0, 10000.0, 12000.0], 8000.0, 0.12))
    assert np.median(k) == pytest.approx(0.12)
    assert k / k[0] == pytest.approx([1.0, 2.0, 4.0])  # force past the offset, proportional to stiffness
    with pytest.raises(ValueError, match="not below the smallest reading"):
        stiffness_from_readings([9000.0, 10000.0], 9000.0, 0.12)


def _raw_scene(tmp_path, baseline: str = "map_baseline = 8000\n", extra: str = "") -> Path:
    (tmp_path / "readings.csv").write_bytes(RAW.read_bytes())
    path = tmp_path / "raw.toml"
    path.write_text(f'name = "raw"\n[tissue]\nsize_mm = [58.0, 20.0]\nmap = "readings.csv"\n{baseline}{extra}')
    return path


def test_a_scene_reads_a_probes_raw_readings_as_the_shipped_real_map_felt_them(tmp_path):
    """Other real data needs no conversion step: the scene points at the readings and states the probe's value
    at no force; what it feels, and its truth, are the shipped map's (written from the same readings)."""
    raw = load_scene(_raw_scene(tmp_path))
    shipped = load_scene(SCENES / "garg-phantom.toml")
    felt, kept = np.array(map_rows(raw.tissue)), np.array(map_rows(shipped.tissue))
    assert felt[:, :2] == pytest.approx(kept[:, :2]) and felt[:, 2] == pytest.approx(kept[:, 2], abs=6e-6)
    assert StiffnessField(raw).k_at(5.0, 0.0) == pytest.approx(StiffnessField(shipped).k_at(5.0, 0.0), rel=1e-4)
    (region,) = metrics.scene_truth(raw)
    (expected,) = metrics.scene_truth(shipped)
    assert region["center_mm"] == pytest.approx(expected["center_mm"], abs=0.01)
    assert region["radius_mm"] == pytest.approx(expected["radius_mm"], abs=0.01)


@pytest.mark.parametrize("baseline, extra, message", [
    ("", "", r"readings\.csv: missing column\(s\) stiffness_n_per_mm \(it holds raw readings: set tissue\.map_baseline"),
    ("map_baseline = 9000\n", "", r"readings\.csv: tissue\.map_baseline: the baseline 9000 is not below the smallest "
                                  r"reading 8711\.41 \(34 of 760 readings at or under it;.*a press that never touched\); the lowest is on line 648 \(x 20\.077, y 7\.576 mm\)"),
    ("map_baseline = nan\n", "", r"map_baseline"),
    ("map_baseline = 8000\n", "thickness_mm = 20\nmodulus_kpa = 15\n", r"tissue\.map.* belong to a 2-D scene"),
], ids=["no-baseline", "baseline-too-high", "nan", "in-3-d"])
def test_a_raw_readings_map_given_wrongly_is_one_clear_line(tmp_path, baseline, extra, message):
    with pytest.raises(SceneError, match=message) as caught:
        load_scene(_raw_scene(tmp_path, baseline, extra))
    assert "\n" not in str(caught.value)


def test_a_baseline_without_a_map_or_over_a_stiffness_map_is_refused(tmp_path):
    (tmp_path / "s.toml").write_text('name = "s"\n[tissue]\nmap_baseline = 8000\n')
    with pytest.raises(SceneError, match="tissue.map_baseline reads a map of raw readings: give tissue.map too"):
        load_scene(tmp_path / "s.toml")
    with pytest.raises(SceneError, match=r"it holds stiffness already: leave tissue\.map_baseline out"):
        load_stiffness_map(SCENES / "maps" / "garg-phantom.csv", 8000.0)


def test_the_simulator_feels_every_real_reading_unsmoothed():
    scene = load_scene(SCENES / "garg-phantom.toml")
    field = StiffnessField(scene)
    rows = load_stiffness_map(scene.tissue.map)
    assert len(rows) == 760
    felt = np.array([field.k_at(x, y) for x, y, _ in rows[::7]])
    read = np.array([k for _, _, k in rows[::7]])
    # Clough-Tocher passes through each sample; the 0.5 mm resampling grid moves a value by well under the
    # point-to-point scatter (neighbouring readings differ by ~5 %)
    assert np.median(np.abs(felt / read - 1.0)) < 0.02


def test_its_truth_is_the_rod_and_the_stiffer_strip_not_the_soft_corner():
    from matplotlib.path import Path as Polygon

    scene = load_scene(SCENES / "garg-phantom.toml")
    (region,) = metrics.map_regions(scene.tissue.map, scene.tissue.size_mm, 0.3)
    inside = Polygon(region["boundary_mm"]).contains_points([(5.0, 0.0), (-20.0, -7.0), (25.0, 7.0), (-20.0, 7.0)])
    assert inside.tolist() == [True, True, False, False]  # rod, stiff strip; soft corner, plain tissue
