import json

import numpy as np
import pytest

from conftest import SCENES, assert_one_line_error
from palpd.dataset import label_tumor, manual_points, read_dataset
from palpd.study.methods import Options, weighted_centroid
from palpd.study.run import run_study


def synthetic(tmp_path, name, rotation_deg, seed, labelled=True, count=80):
    """Points on the paper's layout with stiffness 0.8 inside a 10 mm lump and 0.12 outside, plus noise."""
    rng = np.random.default_rng(seed)
    xy = np.array(manual_points((60.0, 60.0), count, seed))
    angle = np.radians(rotation_deg)
    centre = np.array([7.5 * np.cos(angle) + 4.0 * np.sin(angle), 7.5 * np.sin(angle) - 4.0 * np.cos(angle)])
    tumor = np.array(label_tumor(xy, [{"center_mm": centre, "radius_mm": 10.0}]))
    k = np.where(tumor == 1, 0.8, 0.12) + rng.normal(0, 0.02, len(xy)).clip(-0.05, 0.05)
    path = tmp_path / name
    header = "x_mm,y_mm,stiffness_n_per_mm" + (",tumor" if labelled else "")
    rows = [f"{x:.3f},{y:.3f},{s:.4f}" + (f",{t}" if labelled else "") for (x, y), s, t in zip(xy, k, tumor)]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


def test_supervised_methods_label_a_clear_lump_within_10_percent(tmp_path):
    train = read_dataset(synthetic(tmp_path, "train.csv", 0, 1))
    tests = [read_dataset(synthetic(tmp_path, f"t{r}.csv", r, r)) for r in (40, 200)]
    results = run_study(train, tests, Options())
    assert {r["method"] for r in results} == {"threshold-radius", "centroid-radius", "centroid-radius-stiffness",
                                              "kmeans", "kmeans-semisupervised"}
    assert len(results) == (4 * 3 + 1) * 2
    for r in results:
        if r["method"] in ("threshold-radius", "centroid-radius-stiffness"):
            assert (r["fp"] + r["fn"]) / r["n"] <= 0.10, r


def test_weighted_centroid_leans_to_the_stiff_points():
    xy = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    assert weighted_centroid(xy, np.array([0.1, 1.0, 0.1]), (10.0, 3.0))[0] == pytest.approx(10.0, abs=0.02)
    assert weighted_centroid(xy, np.ones(3), (10.0, 3.0)) == pytest.approx([10 / 3, 10 / 3])


def test_study_command_writes_the_report_and_plot(tmp_path, run_cli):
    train, test = synthetic(tmp_path, "train.csv", 0, 1), synthetic(tmp_path, "test.csv", 90, 2)
    result = run_cli("study", "--train", train, "--test", test, "--report", "s.json", "--plot", "s.png",
                     "--svm-c", "10", "--centroid-weights", "10,3")
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "s.json").read_text())
    row = report["results"][0]
    assert set(row) == {"method", "algorithm", "test", "n", "fp", "fn", "center_mm", "radius_mm"}
    assert (tmp_path / "s.png").stat().st_size > 10_000


def test_study_refuses_unlabelled_training_one_class_tests_and_too_few_points(tmp_path, run_cli):
    test = synthetic(tmp_path, "test.csv", 90, 2)
    unlabelled = synthetic(tmp_path, "u.csv", 0, 1, labelled=False)
    assert_one_line_error(run_cli("study", "--train", unlabelled, "--test", test), "u.csv", "no tumor column")
    one_class = tmp_path / "one.csv"
    one_class.write_text("x_mm,y_mm,stiffness_n_per_mm,tumor\n" + "".join(f"{i},0,0.1,0\n" for i in range(10)))
    train = synthetic(tmp_path, "train.csv", 0, 1)
    assert_one_line_error(run_cli("study", "--train", train, "--test", one_class), "one.csv", "one class")
    tiny = tmp_path / "tiny.csv"
    tiny.write_text("x_mm,y_mm,stiffness_n_per_mm,tumor\n0,0,0.8,1\n1,0,0.1,0\n")
    assert_one_line_error(run_cli("study", "--train", tiny, "--test", test), "tiny.csv", "at least 4")
    assert_one_line_error(run_cli("study", "--train", train, "--test", tmp_path / "missing.csv"), "missing.csv")


def test_dataset_command_palpates_the_scene_and_labels_the_lump(tmp_path, run_cli):
    result = run_cli("dataset", "--scene", SCENES / "paper.toml", "--palpations", "9", "--pattern", "raster",
                     "--rotation-deg", "30", "--out", "d.csv")
    assert result.returncode == 0, result.stderr
    data = read_dataset(tmp_path / "d.csv")
    assert len(data.stiffness_n_per_mm) == 9 and data.tumor is not None
    # the raster point nearest the rotated lump centre is on the lump and clearly stiffer than the rest
    stiff = np.argmax(data.stiffness_n_per_mm)
    assert data.tumor[stiff] == 1 and data.stiffness_n_per_mm[stiff] > 3 * np.median(data.stiffness_n_per_mm)
    assert_one_line_error(run_cli("dataset", "--scene", SCENES / "paper.toml", "--palpations", "0"), "--palpations")
    (tmp_path / "blocker").write_text("")
    result = run_cli("dataset", "--scene", SCENES / "paper.toml", "--palpations", "100000", "--out", "blocker/d.csv")
    assert_one_line_error(result, "d.csv: cannot write")  # at once: after 100000 palpations, the run times out


def test_manual_coverage_is_uneven_and_inside_the_tissue():
    points = np.array(manual_points((60.0, 60.0), 200, 3))
    assert np.all(np.abs(points) <= 30.0)
    counts, _, _ = np.histogram2d(points[:, 0], points[:, 1], bins=4, range=[[-30, 30], [-30, 30]])
    assert counts.max() >= 3 * max(counts.min(), 1)  # some places far denser than others
