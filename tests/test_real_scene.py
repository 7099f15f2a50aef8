"""The real phantom scene (config/scenes/garg-phantom.toml): dVRK readings kept as they were read."""
import numpy as np
import pytest

from conftest import SCENES, load_script
from drivers.sim.scene import load_scene, load_stiffness_map
from drivers.sim.tissue import StiffnessField
from palpd import metrics


def _script():
    return load_script("make_real_map")


def test_readings_become_stiffness_in_proportion_past_the_offset():
    convert = _script().stiffness_from_readings
    readings = np.array([9000.0, 10000.0, 12000.0])
    k = convert(readings, 8000.0)
    assert np.median(k) == pytest.approx(0.12)
    assert k / k[0] == pytest.approx([1.0, 2.0, 4.0])  # force past the offset, proportional to stiffness
    with pytest.raises(SystemExit, match="not below the smallest reading"):
        convert(readings, 9000.0)


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
