import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from palpd.estimate import estimate_lumps, stiffness_threshold, unfelt_radius_mm
from palpd.stiffness import FitRejected, fit_linear


def grid(spacing=5.0):
    axis = np.arange(-30, 30.1, spacing)
    return np.array([(x, y) for x in axis for y in axis])


def disc_field(xy, centre, radius, k_in=0.8, k_out=0.12, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    inside = np.hypot(*(xy - centre).T) < radius
    return np.where(inside, k_in, k_out) + rng.normal(0, noise, len(xy))


def test_one_lump_centre_and_radius():
    xy = grid()
    (lump,) = estimate_lumps(xy, disc_field(xy, (2.0, -3.0), 9.0, noise=0.005))
    assert np.hypot(*(np.array(lump.center_mm) - (2, -3))) < 1.5
    assert lump.radius_mm == pytest.approx(9.0, abs=2.5)
    assert lump.center_sd_mm > 0 and lump.radius_sd_mm > 0


def test_two_separate_lumps_are_two():
    xy = grid()
    k = np.maximum(disc_field(xy, (-15, -15), 7), disc_field(xy, (15, 15), 7, k_in=0.5))
    lumps = estimate_lumps(xy, k)
    assert sorted(round(l.center_mm[0]) for l in lumps) == [-15, 15]


@settings(max_examples=60, deadline=None)
@given(st.floats(0.01, 2.0), st.floats(0.0, 0.05), st.integers(0, 10_000))
def test_plain_tissue_never_invents_a_lump(k, relative_noise, seed):
    xy = grid()
    stiffness = k * (1 + np.random.default_rng(seed).normal(0, relative_noise, len(xy)))
    assert estimate_lumps(xy, stiffness) == []


def test_threshold_needs_real_contrast():
    assert stiffness_threshold(np.array([0.1, 0.1, 0.1, 0.1]), 0.3) is None
    assert stiffness_threshold(np.array([0.1, 0.1, 0.1, 0.11]), 0.3) is None
    assert stiffness_threshold(np.array([0.1, 0.1, 0.1, 0.5, 0.5]), 0.3) == pytest.approx(0.3)


def test_linear_fit_recovers_slope_and_rejects_what_it_cannot_fit():
    d = np.linspace(0, 4, 200)
    fit = fit_linear(d, 0.3 * d + 0.05)
    assert fit.stiffness_n_per_mm == pytest.approx(0.3) and fit.samples == 200
    with pytest.raises(FitRejected, match="too few samples"):
        fit_linear([1.0, 2.0], [0.1, 0.2])
    with pytest.raises(FitRejected, match="range"):
        fit_linear([1.0] * 10, np.linspace(0, 1, 10))
    with pytest.raises(FitRejected, match="does not rise"):
        fit_linear(d, -0.3 * d)
    assert fit_linear([0, 1, np.nan, 2, 3], [0, 1, 5, 2, np.inf]).samples == 3


def test_stiff_points_linked_around_a_soft_one_are_one_bounded_disc_not_an_svm_s_stray_boundary():
    """A coarse raster (20 mm) over three lumps: four stiff points, linked into one group around soft points
    nearer its centre. No distance separates them from the rest; the SVM's boundary had put the radius at -17 km."""
    axis = np.arange(-40.0, 41.0, 20.0)
    xy = np.array([(x, y) for x in axis for y in axis])
    stiff = {(20.0, -20.0), (20.0, 0.0), (0.0, 20.0), (-20.0, 20.0)}  # 5 x 5 over 80 mm tissue, random-2-3
    k = np.array([0.9 if (x, y) in stiff else 0.2 for x, y in xy])
    (lump,) = estimate_lumps(xy, k)
    distances = np.hypot(*(xy[k > 0.5] - lump.center_mm).T)
    assert distances.max() < lump.radius_mm <= np.hypot(*(xy - lump.center_mm).T).max()  # holds them, bounded
    assert np.all(np.isfinite(lump.boundary_mm))


def test_iou_of_a_boundary_gone_astray_is_zero_without_gigabytes():
    from palpd.estimate import circle_polygon
    from palpd.metrics import iou

    astray = circle_polygon((5.0, 5.0), 17462.0)
    assert iou(astray, {"center_mm": [0.0, 0.0], "radius_mm": 5.0}) < 1e-3
    assert iou(circle_polygon((0.0, 0.0), 5.0), {"center_mm": [0.0, 0.0], "radius_mm": 5.0}) > 0.97


def test_what_a_fixed_plan_rules_out_is_the_farthest_spot_from_its_readings():
    """A raster of 2 x 2 at the corners of a 60 mm tissue leaves its centre 42.4 mm from every reading: its
    "no lump" rules out nothing smaller (before, `palpd scan --max-palpations 4` said "no lump" beside a
    10 mm lump in the middle, and no more)."""
    corners = [(-30.0, -30.0), (30.0, -30.0), (-30.0, 30.0), (30.0, 30.0)]
    assert unfelt_radius_mm(corners, (60.0, 60.0)) == pytest.approx(30.0 * np.sqrt(2.0), abs=0.01)
    assert unfelt_radius_mm([(0.0, 0.0)], (80.0, 40.0)) == pytest.approx(np.hypot(40.0, 20.0), abs=0.01)
    assert unfelt_radius_mm([], (60.0, 60.0)) == np.inf


SPOT = st.tuples(st.floats(-30, 30), st.floats(-20, 20))


@given(st.lists(SPOT, min_size=1, max_size=20), SPOT)
@settings(max_examples=40, deadline=None)
def test_a_reading_more_never_widens_what_could_lie_unfelt(readings, more):
    size = (60.0, 40.0)
    before = unfelt_radius_mm(readings, size)
    assert unfelt_radius_mm(readings + [more], size) <= before + 1e-9
    # the tissue's corners are spots too: none lies farther from every reading than the claim says
    corners = [(-30, -20), (30, 20), (30, -20), (-30, 20)]
    assert before >= max(min(np.hypot(x - rx, y - ry) for rx, ry in readings) for x, y in corners) - 1e-9
