"""scripts/levelset_evidence.py (docs/learner-history.md, "A level-set free-form model, prototyped"): the level set
it measures draws a step where the readings step, and no region on plain tissue."""
import math

import numpy as np
import pytest

from conftest import load_script
from palpd.learner.observations import Observations
from palpd.learner.priors import Priors

GRID = np.linspace(-27.0, 27.0, 7)  # 49 readings over a 60 mm square, 9 mm apart


def readings(stiffness) -> Observations:
    obs = Observations()
    rng = np.random.default_rng(0)
    for x in GRID:
        for y in GRID:
            k = stiffness(x, y) * math.exp(0.01 * rng.standard_normal())
            obs.add((x, y), "fit", k, 0.005 * k)
    return obs


@pytest.fixture(scope="module")
def levelset():
    return load_script("levelset_evidence")


def test_a_step_is_drawn_where_the_readings_step(levelset):
    """Half the tissue 4x stiffer (x > 3 mm): the most evident point of the hyperparameter grid draws it, P(lump)
    near 1 inside and near 0 outside, ½ between the last soft column of readings (x = 0) and the first stiff one
    (x = 9). (Many grid points end in a poorer mode, a graded field with the contrast at its bound: the fit is
    multimodal, docs/learner-history.md; the mean evidence over the grid is at most the best point's.)"""
    obs = readings(lambda x, y: 0.48 if x > 3.0 else 0.12)
    priors = Priors((60.0, 60.0), 0.3, float(np.median(obs.y)))
    top, mean_log_z = levelset.best(obs, priors, 0.01)
    assert math.isfinite(mean_log_z) and mean_log_z <= top["log_z"]
    assert top["noise"] < 0.02  # the step explained to the readings' own noise
    assert math.exp(top["theta"][3]) == pytest.approx(3.0, rel=0.1)  # the contrast: 0.48 / 0.12 − 1
    xs = np.linspace(-25.0, 25.0, 51)
    p = levelset.p_lump(top, obs, np.column_stack([xs, np.zeros_like(xs)]))
    assert p[xs <= -5.0].max() < 0.1 and p[xs >= 14.0].min() > 0.9
    assert 0.0 <= xs[np.argmax(p > 0.5)] <= 9.0


@pytest.mark.parametrize("far_mean", [-0.5, -2.0])
def test_plain_tissue_draws_no_region(levelset, far_mean):
    """On plain tissue no spot is more likely lump than not, whatever the prior far from the readings."""
    obs = readings(lambda x, y: 0.12)
    priors = Priors((60.0, 60.0), 0.3, float(np.median(obs.y)))
    fit = levelset.fit(obs, priors, 0.01, 10.0, 4.0, far_mean)
    xy = np.array([(x, y) for x in np.linspace(-28.0, 28.0, 15) for y in np.linspace(-28.0, 28.0, 15)])
    assert levelset.p_lump(fit, obs, xy).max() < 0.5
