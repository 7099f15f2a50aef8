"""The learner's one stop rule (decision.py `Decision.decided`): the count decided, the boundary known to the user's
tolerance, the readings explained; P(lump) averaged over the hypotheses; the true boundary error it is judged by."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings as hsettings, strategies as st
from test_learner import field, learn

from palpd import metrics
from palpd.learner import maps
from palpd.learner.decision import Decision


def test_the_stop_rule_is_one_function_whose_docstring_states_it():
    rule = Decision.decided.__doc__
    for term in ("(a) The count is decided", "confidence", "(b) The boundary is known to the tolerance",
                 "∫ min(P, 1 − P) dA", "averaged over the hypotheses", "tolerance_mm",
                 "(c) The readings are explained", "undetermined"):
        assert term in rule, term


def _disc(centre, radius, n=360):
    t = np.linspace(0.0, 2.0 * math.pi, n)
    return {"boundary_mm": np.column_stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)]).tolist()}


@hsettings(max_examples=25, deadline=None)
@given(shift=st.floats(0.0, 3.0), grow=st.floats(-2.0, 2.0), radius=st.floats(4.0, 12.0))
def test_the_true_boundary_error_is_the_misread_area_over_the_boundary_length(shift, grow, radius):
    """A disc reported `shift` mm off and `grow` mm wider: misread area over 2πr. For a small shift d the two
    crescents hold ~4rd; for a radius off by g, the ring holds ~2πr|g|."""
    truth = [{"center_mm": [0.0, 0.0], "radius_mm": radius}]
    error = metrics.boundary_error_mm(truth, [_disc((shift, 0.0), radius + grow)], (60.0, 60.0))
    if shift == 0.0:
        expected = abs(grow) * (1.0 + grow / (2.0 * radius)) if grow > 0 else abs(grow) * (1.0 - abs(grow) / (2 * radius))
        assert error == pytest.approx(expected, abs=0.08)
    # never below either part alone, never above their sum (area adds at most)
    assert error >= 2.0 * shift / math.pi * 0.9 - 0.08 and error <= 2 * shift / math.pi * 1.1 + abs(grow) * 1.2 + 0.08


def test_a_missed_lump_and_a_false_one_both_count_and_no_truth_has_no_boundary():
    truth = [{"center_mm": [0.0, 0.0], "radius_mm": 10.0}]
    assert metrics.boundary_error_mm(truth, [], (60.0, 60.0)) == pytest.approx(5.0, abs=0.1)  # πr² / 2πr
    assert metrics.boundary_error_mm(truth, [_disc((0, 0), 10), _disc((20, 20), 5)], (60, 60)) == pytest.approx(
        2.5 * 0.5, abs=0.1)  # the false lump's 25π over the true boundary's 20π
    assert metrics.boundary_error_mm([], [_disc((0, 0), 5)], (60.0, 60.0)) is None


def test_p_lump_is_the_posterior_weighted_average_over_the_hypotheses():
    """Bayesian model averaging: with the weight split between two hypotheses, P(lump) is their mixture, each
    hypothesis's own P (a parametric fit's from its posterior, `none`'s 0)."""
    learner = learn(field([((7.5, -4.0), 10.0, 3.0, 0.8)]), budget=14, grid=31)
    assert learner.choice.chosen == "circles:1"
    fit = learner.chosen_fit()
    own = maps.inside_probability(fit, learner.xs, learner.ys)
    learner.choice.shares.clear()
    learner.choice.shares.update({"circles:1": 0.6, "none": 0.4})
    learner._cache.clear()
    assert np.allclose(learner.p_lump().ravel(), 0.6 * own, atol=1e-9)
    learner.choice.shares.update({"circles:1": 0.995, "none": 0.005})  # under MIN_WEIGHT: left out, renormalised
    learner._cache.clear()
    assert np.allclose(learner.p_lump().ravel(), own, atol=1e-9)


def test_the_tolerance_trades_palpations_for_boundary_error():
    """A deep lump (a wide, gradual edge) read with 5 % noise: at `tolerance_mm` 2 the scan stops early (13
    readings; 25 at 0.25), its stated boundary error within 2 mm and so is its true one; the same posterior does
    not satisfy a tolerance of 0.25 mm, which reads on."""
    truth = [((-4.0, 6.0), 9.0, 25.0, 0.5)]
    learner = learn(field(truth), budget=30, noise=0.05, grid=31, tolerance_mm=2.0)
    assert learner.points < 20 and learner.verdict() == "lumps"
    stated = learner.expected_boundary_error_mm()
    assert stated is not None and stated <= 2.0
    true_lumps = [{"center_mm": list(c), "radius_mm": r} for c, r, *_ in truth]
    assert metrics.boundary_error_mm(true_lumps, [lump.as_dict() for lump in learner.lumps()], (60, 60)) <= 2.0
    learner.settings = learner.settings.model_copy(update={"tolerance_mm": 0.25})
    learner._cache.clear()
    assert stated > 0.25 and not learner.decided() and learner.next_probe(30) is not None


def _readings_on(size_mm=60.0, step_mm=2.0):
    from palpd.learner.coverage import Readings

    axis = np.arange(-size_mm / 2, size_mm / 2 + 1e-9, step_mm)
    gx, gy = np.meshgrid(axis, axis)
    return Readings(np.column_stack([gx.ravel(), gy.ravel()]), 1.5)


RADII = (0.5, 30.0)


@hsettings(max_examples=25, deadline=None)
@given(points=st.lists(st.tuples(st.floats(-30, 30), st.floats(-30, 30)), min_size=1, max_size=30),
       expected=st.floats(0.0, 5.0))
def test_the_unfelt_area_is_the_prior_s_before_any_reading_and_no_reading_adds_to_it(points, expected):
    """Lumps no reading felt keep their prior: before any reading the expected area of `expected` lumps with
    radii log-uniform over RADII (the mean of π r² over them); each reading can only take some off, and what
    is left is at most the area of lumps of a radius up to the farthest spot's distance."""
    readings = _readings_on()
    radii = np.exp(np.linspace(math.log(RADII[0]), math.log(RADII[1]), 48))
    before = readings.unfelt_area_mm2(expected, RADII)
    assert before == pytest.approx(expected * float(np.mean(math.pi * radii**2)), rel=1e-9)
    for p in points:
        readings.add(p)
        after = readings.unfelt_area_mm2(expected, RADII)
        assert after <= before + 1e-9
        before = after
    reach = readings.distance_mm.max()
    assert before <= expected * float(np.mean(np.where(radii < reach, math.pi * radii**2, 0.0))) + 1e-9


@hsettings(max_examples=15, deadline=None)
@given(points=st.lists(st.tuples(st.floats(-30, 30), st.floats(-30, 30)), min_size=1, max_size=20))
def test_a_reading_at_the_best_unfelt_spot_takes_off_at_least_what_one_at_the_farthest_spot_does(points):
    """best_unfelt_spot weighs each hole by what it could hide: never worse than the farthest spot, which is
    on the tissue's edge or in a corner more often than not."""
    import copy

    readings = _readings_on()
    for p in points:
        readings.add(p)
    far = readings.cells_xy[int(np.argmax(readings.distance_mm))]
    best = readings.best_unfelt_spot(1.0, RADII)
    at_far, at_best = copy.deepcopy(readings), copy.deepcopy(readings)
    at_far.add(far)
    at_best.add(best)
    assert at_best.unfelt_area_mm2(1.0, RADII) <= at_far.unfelt_area_mm2(1.0, RADII) + 1e-9


def test_the_stated_boundary_error_holds_the_unfelt_lumps_area_and_a_tight_tolerance_reads_the_holes():
    """(b) of the stop rule: the expected misread area is the hypotheses' doubt about the boundary drawn plus
    the area lumps no reading felt could take. With the drawn boundary known to the tolerance and the unfelt
    area what keeps the error above it, the next probe goes where one reading takes most of that area off."""
    learner = learn(field([((7.5, -4.0), 10.0, 3.0, 0.8)]), budget=20, grid=31)
    drawn, unfelt, length = learner._boundary_error_parts()
    assert unfelt == pytest.approx(learner.unfelt_area_mm2()) and unfelt > 0.0
    assert learner.expected_boundary_error_mm() == pytest.approx((drawn + unfelt) / length)
    tolerance = 0.5 * (drawn + (drawn + unfelt)) / length  # between the drawn error and the whole one
    learner.settings = learner.settings.model_copy(update={"tolerance_mm": tolerance})
    learner._cache.clear()
    assert not learner._boundary_known()
    hole = learner._unfelt_hole()
    assert hole == learner.coverage.best_unfelt_spot(learner.settings.expected_lumps, learner._unfelt_radii())
    learner.settings = learner.settings.model_copy(update={"expected_lumps": 0.0})
    learner._cache.clear()
    assert learner._unfelt_hole() is None and learner.unfelt_area_mm2() == 0.0


def test_texture_that_would_hide_the_smallest_contrast_asked_for_explains_no_misfit():
    """13 readings 10 mm apart of a phantom whose middle block is 2.5x stiffer, its soft third scattering widely
    (as a dVRK's dense grid read them): neighbours differ by 60x the noise floor, and `none`, missing them by 53x,
    had that taken for texture and claimed no lump at weight 0.999. Texture so large would hide a lump of
    `min_contrast` at every reading, so it accounts for no more than that lump stands out by (3 sd)."""
    from palpd.config import Settings
    from palpd.learner import Learner, shapes
    from palpd.learner.evidence import SUPPORT_SIGMA
    from palpd.learner.likelihood import texture_sd

    # (x, y) mm, stiffness N/mm, its fit's se: the readings a seed-1 active scan took, in its order
    readings = [((0.0, -8.049), 0.18728, 0.000436), ((9.633, 8.051), 0.0822, 0.000401),
                ((-28.899, 8.051), 0.0374, 0.000397), ((-19.267, -8.05), 0.32429, 0.000481),
                ((-9.633, 8.051), 0.15419, 0.00048), ((19.267, -8.049), 0.1391, 0.000428),
                ((28.899, 8.051), 0.08825, 0.000451), ((-19.999, 3.995), 0.05367, 0.000347),
                ((-18.304, -9.2), 0.08101, 0.000414), ((0.0, 0.001), 0.18086, 0.000393),
                ((-21.194, -5.749), 0.06495, 0.000375), ((28.9, -11.5), 0.14009, 0.000365),
                ((26.973, -11.499), 0.14154, 0.000375)]
    learner = Learner((57.8, 23.0), Settings().learner, 0.3, seed=1)
    for xy, k, se in readings:
        learner.observe(xy, k, se)
    assert learner.choice.chosen == "none" and learner.choice.weight > 0.9, learner.choice
    fit, exact = learner.chosen_fit(), learner.obs.exact
    f, _ = shapes.evaluate(fit.family, fit.theta, learner.obs.xy[exact], jacobian=False)
    raw = texture_sd(learner.obs.xy[exact], learner.obs.y[exact] - f, learner.obs.sd[exact], 6)
    cap = math.log1p(0.3) / SUPPORT_SIGMA
    assert raw >= fit.noise_sd > 5.0 * cap  # what the neighbours alone would have excused
    assert learner._texture_sd() <= cap + 1e-12
    assert not learner._adequate() and not learner.decided() and learner.undecided().startswith("none, the likeliest")
    assert learner.next_probe() is not None  # the scan reads on


def test_no_lump_is_claimed_only_as_far_as_the_readings_reach():
    """Plain tissue read over its left half only (a sliding scan whose paths kept losing contact, a fixed plan
    cut short): `none` is the likeliest, but "no lump" claims the whole tissue, and a spot 30 mm from every
    reading rules nothing out there. The verdict waits, saying why; the same tissue read all over is `none`."""
    from palpd.config import Settings
    from palpd.learner import Learner

    rng = np.random.default_rng(0)
    def read(points):
        learner = Learner((60.0, 60.0), Settings().learner, 0.3, seed=0)
        for xy in points:
            learner.observe(xy, 0.12 * (1.0 + rng.normal(0.0, 0.005)), 0.0005)
        return learner

    grid = [(x, y) for x in np.arange(-27.0, 28.0, 6.0) for y in np.arange(-27.0, 28.0, 6.0)]
    half = read([p for p in grid if p[0] < 0.0])
    assert half.choice.chosen == "none" and half.choice.count_weight >= 0.9
    assert half.verdict() == "undetermined" and half.undecided().startswith("no lump among the readings")
    assert half.unfelt_radius_mm() > 25.0
    assert read(grid).verdict() == "none"
