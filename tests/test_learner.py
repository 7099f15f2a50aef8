"""The online learner on synthetic stiffness fields: lumps found, none invented, extremes survived."""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings as hsettings, strategies as st

from drivers.sim.tissue import lump_profile, lump_sharpness
from palpd.config import LearnerSettings
from palpd.learner import Learner
#from palpd.learner.threshold import levels

TISSUE = 0.12


def field(lumps, tissue=TISSUE):
    """k(x, y) as the simulator feels it: (centre, radius, depth, k_lump) lumps on flat tissue."""
    def k_at(xy):
        best = 0.0
        for (cx, cy), radius, depth, k_lump in lumps:
            c = (k_lump - tissue) * lump_profile(math.hypot(xy[0] - cx, xy[1] - cy), radius, lump_sharpness(radius, depth))
            best = c if abs(c) > abs(best) else best
        return tissue + best
    return k_at


def learn(k_at, budget=40, noise=0.0, seed=0, grid=61, **overrides):
    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=grid, **overrides), 0.3, seed)
    rng = np.random.default_rng(seed)
    while (xy := learner.next_probe(budget)) is not None:
        learner.observe(xy, k_at(xy) + rng.normal(0.0, noise), max(noise, 1e-3))
    return learner


def assert_sane(learner, truth):
    p = learner.p_lump()
    assert p is None or (np.all(np.isfinite(p)) and p.min() >= 0 and p.max() <= 1)
    for lump in learner.lumps():
        d = lump.as_dict()
        assert all(math.isfinite(v) for v in [*d["center_mm"], d["radius_mm"], d["center_sd_mm"], d["radius_sd_mm"]])
        assert d["boundary_mm"][0] == d["boundary_mm"][-1]
        # never invented: every lump lies on a true one
        assert any(math.dist(d["center_mm"], c) <= r + 3.0 for c, r, *_ in truth), (d["center_mm"], truth)


def matched(learner, center, radius):
    return min(learner.lumps(), key=lambda l: math.dist(l.center_mm, center))


@pytest.mark.parametrize("truth, tol_mm", [
    ([((7.5, -4.0), 10.0, 3.0, 0.8)], 1.0),
    ([((-12.0, 10.0), 8.0, 2.0, 0.7), ((14.0, -13.0), 6.0, 4.0, 0.5)], 1.5),
    ([((26.0, 0.0), 8.0, 2.0, 0.8)], 1.5),                    # cut by the edge of the area
    ([((0.0, 0.0), 25.0, 3.0, 0.8)], 1.5),                    # a very large lump
    ([((0.0, 0.0), 8.0, 2.0, 0.12 * 1000)], 1.5),             # 1000x contrast
])
def test_learner_finds_each_lump_with_centre_and_radius(truth, tol_mm):
    learner = learn(field(truth))
    assert_sane(learner, truth)
    assert len(learner.lumps()) == len(truth)
    for center, radius, *_ in truth:
        lump = matched(learner, center, radius)
        assert math.dist(lump.center_mm, center) <= tol_mm and abs(lump.radius_mm - radius) <= tol_mm


def test_three_lumps_are_three():
    truth = [((-15.0, 15.0), 6.0, 2.0, 0.7), ((15.0, 12.0), 7.0, 2.0, 0.6), ((0.0, -15.0), 7.0, 2.0, 0.8)]
    learner = learn(field(truth), budget=60)
    assert_sane(learner, truth)
    assert len(learner.lumps()) == 3


@pytest.mark.parametrize("k", [0.12, 5.0])
def test_all_equal_stiffness_gives_no_lump_and_stops_on_its_own(k):
    learner = learn(field([], tissue=k), budget=200)
    assert learner.lumps() == [] and learner.points < 60
    assert learner.ambiguous_area_mm2() <= 0.01 * learner.grid_area_mm2


def test_tiny_lump_is_never_invented_elsewhere():
    truth = [((5.0, 5.0), 2.0, 1.0, 0.8)]
    assert_sane(learn(field(truth)), truth)


def test_very_noisy_sensor_invents_nothing():
    learner = learn(field([]), noise=0.05, budget=60)
    assert learner.lumps() == []
    truth = [((0.0, 0.0), 10.0, 2.0, 0.8)]
    assert_sane(learn(field(truth), noise=0.05, budget=60), truth)


def test_repeated_probes_at_one_point_stay_finite_and_are_not_asked_for_again():
    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=41, initial_points=0), 0.3, 0)
    for i in range(50):
        learner.observe((3.0, 3.0), 0.12 + 1e-4 * (i % 3), 0.0)
    assert np.all(np.isfinite(learner.p_lump()))
    nxt = learner.next_probe(max_palpations=100)
    assert nxt is not None and math.dist(nxt, (3.0, 3.0)) >= 1.5
    assert learner.lumps() == []


def test_palpations_without_stiffness_count_but_teach_nothing():
    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=41), 0.3, 0)
    learner.observe((0.0, 0.0), None)
    learner.observe((1.0, 1.0), float("nan"))
    assert learner.points == 2 and learner.p_lump() is None and learner.lumps() == []


def test_threshold_needs_a_real_contrast_not_a_fraction_of_the_range():
    rng = np.random.default_rng(1)
    plain = 0.12 + rng.normal(0, 0.003, 40)
    assert not levels(plain, 0.3).contrast  # noise alone has a range, but no lump
    with_lump = np.concatenate([plain, [0.8, 0.79, 0.45]])
    lv = levels(with_lump, 0.3)
    assert lv.contrast and lv.tissue_n_per_mm == pytest.approx(0.12, abs=0.005) and 0.3 < lv.tau_n_per_mm < 0.6


@hsettings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lumps=st.lists(st.tuples(st.tuples(st.floats(-30, 30), st.floats(-30, 30)), st.floats(2.0, 25.0),
                                st.floats(0.5, 6.0), st.floats(0.05, 120.0)), max_size=3),
       noise=st.sampled_from([0.0, 0.002, 0.03]), seed=st.integers(0, 5))
def test_any_field_gives_a_sane_map(lumps, noise, seed):
    truth = [(c, r, d, k) for c, r, d, k in lumps]
    learner = learn(field(truth), budget=20, noise=noise, seed=seed, grid=41)
    p = learner.p_lump()
    assert p is None or (np.all(np.isfinite(p)) and p.min() >= 0 and p.max() <= 1)
    for lump in learner.lumps():
        assert math.isfinite(lump.radius_mm) and lump.boundary_mm[0] == lump.boundary_mm[-1]
        softer = all(k < TISSUE * 1.3 for *_, k in truth)
        assert not softer, "a lump in tissue with no stiffer spot"


def test_active_planner_uses_each_probes_fit_uncertainty_as_observation_noise():
    from types import SimpleNamespace

    from palpd.config import Settings
    from palpd.learner import ActivePlanner

    planner = ActivePlanner((60.0, 60.0), Settings().updated(learner={"grid_points": 21}), 40)
    for x, se in [(0.0, 0.002), (10.0, 0.03)]:
        fit = SimpleNamespace(stiffness_n_per_mm=0.12, stiffness_se_n_per_mm=se)
        planner.observe(SimpleNamespace(record=SimpleNamespace(xy_mm=(x, 0.0)), fit=fit))
    planner.observe(SimpleNamespace(record=SimpleNamespace(xy_mm=(20.0, 0.0)), fit=None))  # rejected fit
    gp = planner.learner.gp
    assert gp.noise_var.tolist() == pytest.approx([0.002**2, 0.03**2]) and planner.learner.points == 3
