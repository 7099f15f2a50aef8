"""The supervised threshold: τ from a labelled training set (§3.4), used by the learner and `palpd scan --train`."""
import math

import numpy as np
import pytest

from conftest import SCENES, assert_one_line_error
from palpd.config import LearnerSettings, Settings
from palpd.dataset import label_tumor, to_csv
from palpd.errors import ConfigError
from palpd.learner import Learner
from palpd.learner.planner import make_learner
from palpd.learner.training import supervised_tau
from test_learner import TISSUE, field

PAPER_LUMP = ((7.5, -4.0), 10.0, 3.0, 0.8)


def training_csv(path, truth, count=81, noise=0.003, seed=0, labelled=True):
    """A dataset as `palpd dataset` writes it, from the synthetic field (labels: inside a true radius)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-30.0, 30.0, size=(count, 2))
    k_at = field(truth)
    k = [k_at(p) + rng.normal(0.0, noise) for p in xy]
    labels = label_tumor(xy, [{"center_mm": c, "radius_mm": r} for c, r, *_ in truth])
    text = to_csv([(x, y, kk, t) for (x, y), kk, t in zip(xy, k, labels)])
    if not labelled:
        text = "\n".join(",".join(line.split(",")[:3]) for line in text.splitlines()) + "\n"
    path.write_text(text)
    return path


def learn(k_at, tau, noise=0.0, budget=40, seed=0):
    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=61), 0.3, seed, supervised_tau_n_per_mm=tau)
    rng = np.random.default_rng(seed)
    while (xy := learner.next_probe(budget)) is not None:
        learner.observe(xy, k_at(xy) + rng.normal(0.0, noise), max(noise, 1e-3))
    return learner


def test_tau_from_a_training_set_lies_near_the_lump_half_height(tmp_path):
    tau = supervised_tau(str(training_csv(tmp_path / "t.csv", [PAPER_LUMP])))
    half_height = 0.5 * (TISSUE + 0.8)
    assert abs(tau - half_height) < 0.15 * (0.8 - TISSUE), tau


def test_supervised_learner_finds_a_lump_like_the_training_one_and_none_in_plain_tissue(tmp_path):
    tau = supervised_tau(str(training_csv(tmp_path / "t.csv", [PAPER_LUMP], seed=1)))
    test_truth = [((-10.0, 8.0), 9.0, 3.0, 0.8)]  # same kind of lump, elsewhere
    learner = learn(field(test_truth), tau)
    (lump,) = learner.lumps()
    assert math.dist(lump.center_mm, (-10.0, 8.0)) <= 1.5 and abs(lump.radius_mm - 9.0) <= 1.5
    plain = learn(field([]), tau, noise=0.01)
    assert plain.lumps() == [] and np.all(np.isfinite(plain.p_lump()))


def test_a_point_above_tau_by_less_than_its_noise_is_no_lump():
    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=41, initial_points=0), 0.3, 0,
                      supervised_tau_n_per_mm=0.45)
    for x in (-20.0, -10.0, 0.0, 10.0, 20.0):
        learner.observe((x, 0.0), 0.12, 0.01)
    learner.observe((0.0, 15.0), 0.47, 0.05)  # 0.02 above τ with an SE of 0.05
    assert learner.lumps() == []
    for xy in [(0.0, -15.0), (4.0, -15.0), (0.0, -19.0)]:  # a lump read at three spots (one stiff reading
        learner.observe(xy, 0.8, 0.01)                      # among six is as likely an outlier: evidence.py)
    assert len(learner.lumps()) == 1


def test_settings_key_makes_the_planner_supervised(tmp_path):
    path = training_csv(tmp_path / "t.csv", [PAPER_LUMP])
    learner = make_learner(Settings().updated(learner={"training_set": str(path)}), (60.0, 60.0), 0)
    assert learner.supervised_tau_n_per_mm == pytest.approx(supervised_tau(str(path)))
    assert make_learner(Settings(), (60.0, 60.0), 0).supervised_tau_n_per_mm is None


@pytest.mark.parametrize("truth, labelled, message", [
    ([PAPER_LUMP], False, "no tumor column"),
    ([], True, "needs both tumor (1) and tissue (0) rows"),
])
def test_a_training_set_that_cannot_teach_is_refused(tmp_path, truth, labelled, message):
    path = training_csv(tmp_path / "t.csv", truth, labelled=labelled)
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        supervised_tau(str(path))


def test_overlapping_classes_are_refused(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("x_mm,y_mm,stiffness_n_per_mm,tumor\n0,0,0.5,0\n1,0,0.1,1\n2,0,0.5,0\n3,0,0.1,1\n")
    with pytest.raises(ConfigError, match="does not separate"):
        supervised_tau(str(path))


def test_cli_train_errors_are_one_line(tmp_path, run_cli):
    unlabelled = training_csv(tmp_path / "u.csv", [PAPER_LUMP], labelled=False)
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--strategy", "active", "--train", unlabelled)
    assert_one_line_error(result, "u.csv", "no tumor column")
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--strategy", "raster", "--train", unlabelled)
    assert_one_line_error(result, "--train", "--strategy active")
    result = run_cli("scan", "--scene", SCENES / "paper.toml", "--strategy", "active", "--train", tmp_path / "nope.csv")
    assert_one_line_error(result, "nope.csv")
