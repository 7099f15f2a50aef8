"""scripts/garg_recording.py: a recording of the public Garg et al. repository, in either of its two pickle
layouts, becomes a scene that reads the probe's raw values itself, its stiff region where it was read."""
import csv
import math
import pickle

import numpy as np
import pytest

from conftest import load_script
from drivers.sim.scene import load_scene
from palpd import metrics

TURN = math.radians(30.0)
ROTATION = np.array([[math.cos(TURN), -math.sin(TURN)], [math.sin(TURN), math.cos(TURN)]])


@pytest.fixture(scope="module")
def garg():
    return load_script("garg_recording")


def _raster() -> tuple[np.ndarray, np.ndarray]:
    """A 50 x 20 mm raster (the tissue's frame, centred) with a 5 mm stiff disc 12 mm along its long side, and
    the raw values a probe pressed to one depth would read there (offset 6000, tissue 1000 over it)."""
    xs, ys = np.meshgrid(np.linspace(-25.0, 25.0, 51), np.linspace(-10.0, 10.0, 11))
    xy = np.column_stack([xs.ravel(), ys.ravel()])
    inside = np.hypot(xy[:, 0] - 12.0, xy[:, 1]) < 5.0
    return xy, 6000.0 + np.where(inside, 3000.0, 1000.0)


def _check_scene(garg, tmp_path, recording, tissue_xy, readings, left_out: int, capsys):
    assert garg.main([str(recording), str(tmp_path / "out")]) == 0
    said = capsys.readouterr().out
    scene = load_scene(tmp_path / "out" / f"{recording.stem}.toml")
    with (tmp_path / "out" / f"{recording.stem}.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == len(readings) - left_out, said
    assert (f"{left_out} at or under it left out" in said) == (left_out > 0), said
    frame = np.array([(float(r["x_mm"]), float(r["y_mm"])) for r in rows])
    # centred on the points, x along their long side: the raster's own frame, up to the axes' signs
    assert np.abs(frame).max(axis=0) == pytest.approx([25.0, 10.0], abs=0.01)
    assert scene.tissue.size_mm == pytest.approx((50.0, 20.0), abs=0.11)
    (region,) = metrics.scene_truth(scene)
    assert abs(region["center_mm"][0]) == pytest.approx(12.0, abs=0.5) and abs(region["center_mm"][1]) < 0.5, region
    assert region["radius_mm"] == pytest.approx(5.0, abs=1.0), region


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")  # the recordings' numpy matrices
def test_a_list_of_readings_and_poses_becomes_a_scene_in_the_points_own_frame(garg, tmp_path, capsys):
    """The robot's frame turned 30 deg and shifted; the first press never touched (a value under every other),
    so it is left out and counted, as the dVRK's 20 x 10 grid's first reading is."""
    xy, readings = _raster()
    robot_xy = xy @ ROTATION.T + (120.0, -40.0)
    poses = []
    for (x, y), z in zip(robot_xy, np.linspace(-95.0, -93.0, len(xy))):
        pose = np.eye(4)
        pose[:3, 3] = (x / 1000.0, y / 1000.0, z / 1000.0)
        poses.append(np.asmatrix(pose))  # the recordings' poses are numpy matrices
    readings = np.concatenate([[4000.0], readings])
    poses = [np.asmatrix(np.eye(4))] + poses
    recording = tmp_path / "exp0.p"
    recording.write_bytes(pickle.dumps([[float(r), pose] for r, pose in zip(readings, poses)], protocol=2))
    _check_scene(garg, tmp_path, recording, xy, readings, 1, capsys)


def test_a_dense_grids_rows_become_a_scene(garg, tmp_path, capsys):
    xy, readings = _raster()
    recording = tmp_path / "dense_grid.p"
    data = np.column_stack([(xy[:, 1] + 10.0) / 1000.0, (xy[:, 0] + 25.0) / 1000.0, readings])  # its short side first
    recording.write_bytes(pickle.dumps({"rows": 11, "columns": 51, "data": data}, protocol=2))
    _check_scene(garg, tmp_path, recording, xy, readings, 0, capsys)


@pytest.mark.parametrize("content", [b"x_mm,y_mm,reading\n1,2,3\n", pickle.dumps({"rows": 3})],
                         ids=["not-a-pickle", "another-pickle"])
def test_a_file_that_is_no_recording_is_one_line_and_exit_1(garg, tmp_path, capsys, content):
    recording = tmp_path / "notes.p"
    recording.write_bytes(content)
    assert garg.main([str(recording), str(tmp_path / "out")]) == 1
    said = capsys.readouterr().err
    assert said.startswith(f"garg_recording: {recording}: ") and said.count("\n") == 1, said
    assert not (tmp_path / "out").exists()
