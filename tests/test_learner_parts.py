"""The learner's parts: the GP's one-block refit, the evidence's choice on fixed readings, the layering."""
import math
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings as hsettings, strategies as st

from palpd import metrics
from palpd.learner import shapes
from palpd.learner.gp import JITTER, PENDING_ROWS, Hyper, IncrementalGP, fit_hyper, lattice_steps
from palpd.learner.hypotheses import Hypotheses
from palpd.learner.observations import Observations


def grid(side=21):
    axis = np.linspace(-30.0, 30.0, side)
    gx, gy = np.meshgrid(axis, axis)
    return np.column_stack([gx.ravel(), gy.ravel()])


def test_a_one_block_refit_equals_the_row_by_row_posterior_and_survives_duplicate_points():
    rng = np.random.default_rng(0)
    xy = rng.uniform(-30, 30, (40, 2))
    y = np.log(0.12 + 0.5 * (np.hypot(*(xy - 5.0).T) < 8))
    hyper = Hyper(np.log(0.12), 0.5, 4.0, 1e-4)
    rows, read_each_time = IncrementalGP(grid(), hyper), IncrementalGP(grid(), hyper)
    for p, v in zip(xy, y):
        rows.add(p, v, 1e-4)
        assert rows._pending <= PENDING_ROWS  # never left to one flush of every row, however long unread
        read_each_time.add(p, v, 1e-4)
        read_each_time.var  # the grid's rows one at a time, where `rows` makes them in one block when asked
    assert read_each_time.mean == pytest.approx(rows.mean, abs=1e-5)
    block = IncrementalGP(grid(), hyper)
    block.xy, block.y, block.noise_var = rows.xy, rows.y, rows.noise_var
    block.refit(hyper)
    assert block.mean == pytest.approx(rows.mean, abs=1e-5) and block.var == pytest.approx(rows.var, abs=1e-5)
    assert block.log_marginal_likelihood() == pytest.approx(rows.log_marginal_likelihood(), rel=1e-6)
    same = IncrementalGP(grid(), Hyper(0.0, 1.0, 4.0, 0.0))  # the same spot, no noise: a singular block
    for _ in range(5):
        same.add((1.0, 1.0), 0.3, 0.0)
    same.refit(Hyper(0.0, 1.0, 5.0, 0.0))
    assert np.all(np.isfinite(same.mean)) and np.all(np.isfinite(same.std()))


def test_the_posterior_covariance_between_cells_is_what_a_reading_at_one_takes_off_the_others_variance():
    """The free-form map's next probe is scored by what it takes off its boundary's variance: Var_b less
    cov(b, c)² / (Var_c + noise) after a reading at c. Held against the GP's own update at the new point,
    with the rows both pending and flushed (V kept in float32)."""
    rng = np.random.default_rng(1)
    hyper = Hyper(np.log(0.12), 0.5, 6.0, 1e-4)
    cells = grid()
    for n in (0, 5, 12):
        gp = IncrementalGP(cells, hyper)
        for p in rng.uniform(-30, 30, (n, 2)):
            gp.add(p, np.log(0.12) + rng.normal(0.0, 0.3), 1e-4)
        c = int(rng.integers(len(cells)))
        others = np.arange(len(cells))
        cov = gp.covariance(others, np.array([c]))[:, 0]
        assert cov[c] == pytest.approx(gp.var[c], rel=1e-4)  # a cell's covariance with itself is its variance
        predicted = gp.var - cov**2 / (gp.var[c] + hyper.white_var + 1e-4)
        gp.add(cells[c], 0.0, 1e-4)
        assert gp.var == pytest.approx(predicted, abs=1e-5 * hyper.signal_var), n


def test_the_lattice_covariance_is_the_covariance_of_its_cells_under_whatever_kernel_the_map_has_now():
    """The free-form map's probe score asks the covariance of a fixed lattice's cells at every update, its
    prior kernel kept while the kernel holds: the same as asking for those cells afresh, before and after
    readings and a new kernel (a kept kernel that outlived a relearn would score the probes by the old one). On
    a grid's cells the kernel is read off a table of their offsets (gp.lattice_kernel); off a grid, pair by pair."""
    rng = np.random.default_rng(2)
    for on_grid, cells in ((True, grid()), (False, rng.uniform(-30.0, 30.0, (441, 2)))):
        lattice = np.arange(0, len(cells), 7)  # scattered over the grid's rows and columns
        assert (lattice_steps(cells[lattice]) is not None) == on_grid
        a, b = np.sort(rng.choice(len(lattice), 20, replace=False)), np.sort(rng.choice(len(lattice), 30, replace=False))
        gp = IncrementalGP(cells, Hyper(np.log(0.12), 0.5, 6.0, 1e-4))
        for step in range(3):
            assert gp.lattice_covariance(lattice, a, b) == pytest.approx(gp.covariance(lattice[a], lattice[b]), abs=1e-9)
            for p in rng.uniform(-30, 30, (4, 2)):
                gp.add(p, np.log(0.12) + rng.normal(0.0, 0.3), 1e-4)
            assert gp.lattice_covariance(lattice, a, b) == pytest.approx(gp.covariance(lattice[a], lattice[b]), abs=1e-9)
            gp.refit(Hyper(np.log(0.12), 0.5 + step, 3.0 + 2.0 * step, 1e-4))


def test_the_learner_holds_its_score_lattice_s_kernel_from_the_start_and_makes_it_again_only_on_a_new_kernel():
    """The free-form map's probe score reads a prior kernel over its lattice (7 ms to make on a 60 mm tissue):
    the learner makes it as it is made, so its first update reads the one held (that update had been the
    learner's slowest, 50-120 ms), and a relearnt kernel makes it anew, never an old one read on."""
    from palpd.config import LearnerSettings
    from palpd.learner import Learner

    learner = Learner((60.0, 60.0), LearnerSettings(initial_points=0, tolerance_mm=1e-6), 0.3)
    held = learner.gp._lattice_prior
    assert held is not None and held[0] is learner._area_lattice[0] and held[1] == learner.gp.hyper
    learner.observe((7.5, -4.0), 0.6, 0.003)
    learner.next_probe()  # scored by the free-form map's misclassified area: the lattice's covariance read
    assert learner.gp._lattice_prior is held  # the first update made no kernel
    for xy in ((-20.0, 15.0), (20.0, 20.0)):
        learner.observe(xy, 0.12, 0.003)  # the third reading relearns the kernel (model._refit_pays)
        learner.next_probe()
    assert learner.gp.hyper != held[1] and learner.gp._lattice_prior[1] == learner.gp.hyper


def readings(k_at, points):
    obs = Observations()
    for p in points:
        obs.add(p, "fit", k_at(p), 0.0004)
    return obs


def lattice(step=6.0):
    axis = np.arange(-27.0, 27.1, step)
    return [(x, y) for x in axis for y in axis]


def sklearn_fit_hyper(xy, y, noise_var, start: Hyper, length_bounds_mm, white_floor_var) -> Hyper:
    """The same fit by scikit-learn's GaussianProcessRegressor (what the learner used before fit_hyper)."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, DotProduct, Matern, WhiteKernel

    scale = start.scale_mm
    bounds = (length_bounds_mm[0] / scale, length_bounds_mm[1] / scale)
    white_bounds = (white_floor_var, max(1.0, 2.0 * white_floor_var))
    kernel = (ConstantKernel(float(np.clip(start.signal_var, 1e-6, 1e2)), (1e-6, 1e2))
              * Matern(float(np.clip(start.length_mm / scale, *bounds)), bounds, nu=2.5)
              + ConstantKernel(start.slope_var, "fixed") * DotProduct(math.sqrt(start.level_var / start.slope_var),
                                                                       "fixed")
              + WhiteKernel(float(np.clip(start.white_var, *white_bounds)), white_bounds))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a bound reached (ConvergenceWarning) is an answer
        fitted = GaussianProcessRegressor(kernel, alpha=noise_var + JITTER).fit(xy / scale, y - start.mean).kernel_
    return Hyper(start.mean, fitted.k1.k1.k1.constant_value, fitted.k1.k1.k2.length_scale * scale,
                 fitted.k2.noise_level, start.level_var, start.slope_var, start.scale_mm)


def log_evidence(hyper: Hyper, xy, y, noise_var) -> float:
    gp = IncrementalGP(grid(3), hyper)
    for p, v, var in zip(xy, y, noise_var):
        gp.add(p, v, var)
    return gp.log_marginal_likelihood()


SAME_NATS = 1e-3  # log evidence two optimisers' stopping points may differ by and still be one optimum


@hsettings(max_examples=20, deadline=None)
@given(n=st.integers(3, 50), contrast=st.floats(0.0, 3.0), noise_sd=st.floats(1e-4, 0.5), seed=st.integers(0, 999),
       start_var=st.floats(1e-3, 10.0), start_length_mm=st.floats(1.0, 40.0))
@example(n=12, contrast=0.386, noise_sd=0.00247, seed=697, start_var=0.5, start_length_mm=8.0)
@example(n=11, contrast=1.75, noise_sd=0.4375, seed=745, start_var=3.75, start_length_mm=7.09375)  # a σ² ridge
@example(n=33, contrast=0.0, noise_sd=0.0719742988241281, seed=589, start_var=7.082271299899137,
         start_length_mm=17.30322832335969)  # L-BFGS-B stopped 0.05 nat short (fit_hyper now restarts)
def test_the_kernel_relearn_finds_scikit_learns_optimum(n, contrast, noise_sd, seed, start_var, start_length_mm):
    """fit_hyper is scikit-learn's fit written over the learner's own kernel (so no learner imports
    scikit-learn): from flat tissue to a 20x lump, from clean readings to very noisy ones, from starts
    inside and outside the bounds, the same optimum.

    Both optimisers stop on their own tolerances, so "the same" is a thousandth of a nat of evidence, and a
    parameter may differ only where the evidence cannot tell the two values apart (a ridge: no field at all,
    or white noise far below the readings' own), or where scikit-learn stopped short of this optimum. A
    1e-6-nat, parameter-for-parameter version failed about one hypothesis run in twenty on such ridges."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-30.0, 30.0, (n, 2))
    y = np.log(0.12) + contrast * (np.hypot(*(xy - 4.0).T) < 9.0) + rng.normal(0.0, noise_sd, n)
    noise_var = np.full(n, noise_sd**2)
    start = Hyper(float(np.median(y)), start_var, start_length_mm, 1e-3)
    mine = fit_hyper(xy, y, noise_var, start, (1.5, 30.0), 1e-4)
    theirs = sklearn_fit_hyper(xy, y, noise_var, start, (1.5, 30.0), 1e-4)
    mine_lml, theirs_lml = log_evidence(mine, xy, y, noise_var), log_evidence(theirs, xy, y, noise_var)
    assert mine_lml >= theirs_lml - SAME_NATS
    if mine_lml > theirs_lml + SAME_NATS:
        return  # scikit-learn stopped short: its parameters are not the optimum
    for name in ("signal_var", "length_mm", "white_var"):
        if getattr(mine, name) != pytest.approx(getattr(theirs, name), rel=1e-2):
            swapped = log_evidence(replace(mine, **{name: getattr(theirs, name)}), xy, y, noise_var)
            assert abs(swapped - mine_lml) <= 10 * SAME_NATS, (name, mine, theirs, mine_lml, swapped)


@hsettings(max_examples=40, deadline=None)
@given(ellipse=st.booleans(), tail=st.floats(*shapes.TAIL_RANGE).filter(lambda t: abs(t) > 1e-5),
       sharpness=st.floats(1.0, 60.0), radius=st.floats(0.5, 30.0), stretch=st.floats(-2.0, 2.0),
       seed=st.integers(0, 999), soft=st.booleans())
def test_every_lump_profile_is_half_high_on_its_boundary_and_its_jacobian_is_its_derivative(
        ellipse, tail, sharpness, radius, stretch, seed, soft):
    """Both tail branches (shapes.py): p = ½ on the 50 % boundary whatever the tails; tails that end are
    zero from ρ^s = 1/c on, where the others never are; and the Jacobian the solver steps by is the
    derivative of the values, out to and past the end of tails that end, with a soft region beside the
    lump or not (its profile the same, drawn the other way)."""
    family = shapes.Family("ellipses" if ellipse else "circles", 1, 30.0, soft=int(soft))
    lump = shapes.make_lump((2.0, -3.0), radius, sharpness, 2.0, (stretch, 0.5 * stretch) if ellipse else None, tail)
    dip = shapes.make_lump((-9.0, 6.0), 0.7 * radius, 0.5 * sharpness + 1.0, 0.9, None, -tail) if soft else []
    theta = np.concatenate([[math.log(0.12), 0.01, -0.02], lump, dip])
    boundary = shapes.boundary_polygon(lump, ellipse)[:-1]
    assert np.allclose(shapes.heights_of(family, theta, boundary)[:, 0], 1.0, rtol=1e-6)  # a·p = 2 · ½
    far = shapes.boundary_polygon(np.concatenate([lump[:2], [lump[2] + math.log(3.0) / sharpness], lump[3:]]),
                                  ellipse)[:-1]  # where ρ^s = 3, past the end of tails with c > 1/3
    far_heights = shapes.heights_of(family, theta, far)[:, 0]
    assert np.all(far_heights < 1e-12) if -0.5 * tail > 1.0 / 3.0 else np.all(far_heights > 1e-3), far_heights
    xy = np.random.default_rng(seed).uniform(-40.0, 40.0, (60, 2))
    _, jac = shapes.evaluate(family, theta, xy)
    step = 1e-6
    for i in range(len(theta)):
        up, down = theta.copy(), theta.copy()
        up[i] += step
        down[i] -= step
        numeric = (shapes.evaluate(family, up, xy, False)[0] - shapes.evaluate(family, down, xy, False)[0]) / (2 * step)
        assert np.allclose(jac[:, i], numeric, rtol=1e-4, atol=1e-5), (i, np.abs(jac[:, i] - numeric).max())


def test_a_soft_disc_is_no_lump_on_tissue_softer_there_not_a_lump_around_it():
    """Tissue 3x softer over a disc (a cyst, fat) is `none+soft:1`: no lump, the disc where the readings dip.
    Before, the only models with room for it were lumps, and one stood for the tissue around the disc (a stiff
    half-disc beside it, 38 times the noise floor: undetermined at the budget)."""
    centre, radius = np.array([4.0, 7.0]), 10.0
    soft = lambda p: 0.12 * (1.0 - (2.0 / 3.0) / (1.0 + (math.dist(p, centre) / radius) ** 8))  # noqa: E731
    inside = [tuple(centre + r * np.array([math.cos(t), math.sin(t)])) for r in (0.0, 5.0) for t in (0.0, 2.1, 4.2)]
    obs = readings(soft, lattice() + inside)
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    hypotheses.update(obs, [], math.log(0.12))
    choice = hypotheses.choice(None, obs)
    assert choice.chosen == "none+soft:1" and choice.weight > 0.99, choice
    dip = hypotheses.fits["none+soft:1"].theta[3:]
    assert math.dist(dip[:2], centre) < 1.0 and abs(math.exp(dip[2]) - radius) < 1.0, dip
    assert 1.0 + math.exp(dip[-1]) == pytest.approx(3.0, rel=0.1)  # 3x softer at its core
    flat = readings(lambda p: 0.12, lattice())
    plain = Hypotheses((60.0, 60.0), 0.3, 0.01)
    plain.update(flat, [], math.log(0.12))
    assert plain.choice(None, flat).chosen == "none" and "none+soft:1" not in plain.fits  # nothing below to try


def test_a_soft_region_has_tissue_around_it_a_disc_past_the_tissue_edge_is_not_one():
    """Softer past the tissue's edge is as much the soft side of a stiff region as a soft region: the
    half-stiff map (a smooth stiff region over half the tissue) was read as a soft disc over its soft half,
    `none`. The prior holds a soft region's 50 % boundary on the tissue, as a residual whose Jacobian the
    solver steps by."""
    from palpd.learner import evidence
    from palpd.learner.priors import Priors

    priors, family = Priors((60.0, 40.0), 0.3, 0.0), shapes.Family("circles", 1, 30.0, soft=1)
    lump = shapes.make_lump((5.0, 0.0), 4.0, 6.0, 2.0)
    def residuals(centre, radius):
        theta = np.concatenate([[0.0, 0.0, 0.0], lump, shapes.make_lump(centre, radius, 4.0, 1.0)])
        return theta, evidence.prior_residuals(family, theta, priors)
    _, (inside, _) = residuals((-10.0, 5.0), 12.0)  # reaches x = -22, y = 17: on the 60 x 40 mm tissue
    assert np.all(inside[3:] == 0.0)
    theta, (past, jac) = residuals((-20.0, 5.0), 16.0)  # to x = -36 and y = 21: 6 and 1 mm past the edges
    assert past[3:] == pytest.approx([6.0 / evidence.OVERLAP_MM, 1.0 / evidence.OVERLAP_MM, 0.0])  # (then: the lump)
    for i in range(family.size):
        step = np.zeros(family.size)
        step[i] = 1e-6
        numeric = (evidence.prior_residuals(family, theta + step, priors)[0]
                   - evidence.prior_residuals(family, theta - step, priors)[0]) / 2e-6
        assert np.allclose(jac[:, i], numeric, atol=1e-5), i


def test_a_lump_beside_a_soft_disc_is_one_lump_on_tissue_softer_there():
    """The soft region goes with the likeliest count of lumps too: a lump 6x stiffer beside a soft disc is
    `circles:1+soft:1`, the lump where it is (circles:1 alone missed the disc's readings, undetermined)."""
    centre, lump = np.array([-10.0, 10.0]), np.array([12.0, -10.0])
    def k_at(p):
        soft = 1.0 - (2.0 / 3.0) / (1.0 + (math.dist(p, centre) / 12.0) ** 8)
        return 0.12 * soft * (1.0 + 5.0 / (1.0 + (math.dist(p, lump) / 7.0) ** 8))
    inside = [tuple(c + r * np.array([math.cos(t), math.sin(t)])) for c in (centre, lump) for r in (0.0, 5.0, 8.0)
              for t in (0.0, 2.1, 4.2)]
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    for points in (lattice(9.0), lattice(9.0) + inside):  # as a scan reads: a covering first, then closer
        obs = readings(k_at, points)
        hypotheses.update(obs, [], math.log(0.12))
        choice = hypotheses.choice(None, obs)
        assert choice.chosen == "circles:1+soft:1" and choice.weight > 0.99, choice
    theta = hypotheses.fits[choice.chosen].theta
    assert math.dist(theta[3:5], lump) < 0.5 and abs(math.exp(theta[5]) - 7.0) < 0.5, theta
    assert math.dist(theta[9:11], centre) < 1.0, theta


def test_the_evidence_picks_one_lump_not_two_two_not_one_and_none_on_flat_tissue():
    def lumps_at(*centres):
        return lambda p: 0.12 + max([0.68 / (1 + (math.dist(p, c) / 7.0) ** 8) for c in centres] + [0.0])

    for k_at, chosen in [(lumps_at((5.0, 5.0)), "circles:1"), (lumps_at((-12.0, -10.0), (12.0, 12.0)), "circles:2"),
                         (lambda p: 0.12, "none")]:
        obs = readings(k_at, lattice())
        hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
        hypotheses.update(obs, [], math.log(0.12))
        assert hypotheses.choice(None, obs).chosen == chosen, (chosen, hypotheses.choice(None, obs))


@pytest.mark.parametrize("kind, second, is_apart", [
    ("circles", (12.0, 0.0, 5.0), True),    # two 5 mm discs 2 mm apart edge to edge
    ("circles", (10.0, 0.0, 5.0), True),    # touching
    ("circles", (7.0, 0.0, 5.0), True),     # sharing 19 % of each one's area: blurred edges, still two lumps
    ("circles", (5.0, 0.0, 5.0), False),    # sharing 39 %
    ("circles", (1.0, 1.0, 2.0), False),    # a small disc inside a large one
    ("ellipses", (6.0, 0.0, 5.0), False),   # two 16 x 1.6 mm ellipses, one 6 mm along the other's axis
    ("ellipses", (0.0, 4.0, 5.0), True),    # side by side 4 mm apart: the centres closer than the first's length
])
def test_lumps_laid_over_one_another_are_not_separate_lumps(kind, second, is_apart):
    """`evidence.apart`: two lumps sharing more than a fifth of the smaller one's area (inside their 50 %
    boundaries) are not separate lumps, and such a fit is never the one chosen; two lumps merely touching
    are."""
    from palpd.learner import evidence, shapes

    family = shapes.Family(kind, 2, 30.0)
    stretch = (math.log(10.0), 0.0) if kind == "ellipses" else ()  # axes R·e^{±ε/2}: 16 x 1.6 mm at R = 5

    def lump(x, y, radius):
        return [x, y, math.log(radius), *stretch, 0.0, math.log(4.0), 0.0]

    theta = np.array([0.0, 0.0, 0.0, *lump(0.0, 0.0, 5.0), *lump(*second)])
    assert evidence.apart(family, theta) is is_apart
    assert evidence.apart(shapes.Family(kind, 1, 30.0), theta[:3 + family.per_lump])


def test_a_missed_small_lump_is_scored_as_missed_not_as_the_found_one_far_off():
    """True lumps are matched to estimates by the least total distance: matched in list order, the 1.5 mm lump
    took the only estimate (over the 6 mm lump, 22 mm away) and the 6 mm lump was scored missed."""
    def disc(x, y, r):
        return {"center_mm": [x, y], "radius_mm": r,
                "boundary_mm": [[x + r * math.cos(a), y + r * math.sin(a)] for a in np.linspace(0, 2 * math.pi, 73)]}

    truth = [{"center_mm": [-15.0, 10.0], "radius_mm": 1.5}, {"center_mm": [5.0, -3.0], "radius_mm": 6.0}]
    m = metrics.compare(truth, [disc(5.1, -3.0, 6.0)], (40.0, 40.0))
    assert m["lumps_found"] == 1 and m["lumps_missed"] == 1 and m["false_lumps"] == 0
    assert m["per_lump"][0] == {"found": False, "radius_mm": 1.5} and m["per_lump"][1]["found"]
    assert m["max_center_error_mm"] == pytest.approx(0.1) and m["min_iou"] > 0.95
    swapped = metrics.compare(truth, [disc(-14.0, 10.0, 1.5), disc(5.0, -2.0, 6.0), disc(20.0, 20.0, 1.0)], (40.0, 40.0))
    assert swapped["lumps_found"] == 2 and swapped["false_lumps"] == 1 and swapped["max_center_error_mm"] == pytest.approx(1.0)
    assert metrics.compare([], [disc(0.0, 0.0, 2.0)])["false_lumps"] == 1 and metrics.compare(truth, [])["lumps_missed"] == 2
    # what the verdict had not allowed for: "no other lump larger than the unfelt radius"
    assert metrics.wrong_beyond_claim(m, 4.0) == 0  # the 1.5 mm lump missed lay under a stated 4 mm
    assert metrics.wrong_beyond_claim(m, 1.5) == 1 and metrics.wrong_beyond_claim(m, None) == 1
    assert metrics.wrong_beyond_claim(swapped, 10.0) == 1  # a false lump is never within a claim
    assert metrics.wrong_beyond_claim(metrics.compare(truth, []), 5.0) == 1  # the 6 mm lump was larger


def test_map_truth_is_the_half_height_region_and_iou_compares_polygons(tmp_path):
    axis = np.arange(-30.0, 30.1, 1.0)
    rows = ["x_mm,y_mm,stiffness_n_per_mm"]
    for x in axis:
        for y in axis:
            rows.append(f"{x},{y},{0.12 + 0.5 * math.exp(-((x - 2) ** 2 + y**2) / (2 * 6.0**2)):.5f}")
    path = tmp_path / "bump.csv"
    path.write_text("\n".join(rows) + "\n")
    (region,) = metrics.map_regions(path, (60.0, 60.0), 0.3)
    assert region["center_mm"] == pytest.approx([2.0, 0.0], abs=0.1)
    assert region["radius_mm"] == pytest.approx(6.0 * math.sqrt(2 * math.log(2)), abs=0.2)
    disc = [[2 + region["radius_mm"] * math.cos(t), region["radius_mm"] * math.sin(t)]
            for t in np.linspace(0, 2 * math.pi, 73)]
    assert metrics.iou(disc, region) > 0.97
    assert metrics.iou(disc, {"center_mm": [12.0, 0.0], "radius_mm": region["radius_mm"]}) < 0.3


def _write_map(path, step_mm, k_at):
    axis = np.arange(-30.0, 30.0 + 1e-9, step_mm)
    rows = ["x_mm,y_mm,stiffness_n_per_mm"] + [f"{x:.2f},{y:.2f},{k_at(x, y):.5f}" for x in axis for y in axis]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_map_truth_keeps_lumps_that_nearly_touch_apart_and_a_1_mm_lump_at_1_mm(tmp_path):
    """touching-lumps' three lumps as a measured map: their tails join above the tissue level, so they had been
    one region, centred between them; and a 1 mm lump's half-height area, taken on the map smoothed by 0.5 mm,
    had a radius of 1.39 mm."""
    from drivers.sim.tissue import lump_profile, lump_sharpness

    centres = [(-8.0, 0.0), (4.0, 0.0), (-1.0, 13.5)]
    sharp = lump_sharpness(5.0, 2.0)
    touching = _write_map(tmp_path / "touching.csv", 1.0, lambda x, y: 0.12 + 0.68 * max(
        lump_profile(math.dist((x, y), c), 5.0, sharp) for c in centres))
    truth = metrics.map_regions(touching, (60.0, 60.0), 0.3)
    assert len(truth) == 3
    for c in centres:
        (near,) = [t for t in truth if math.dist(t["center_mm"], c) < 0.2]
        assert near["radius_mm"] == pytest.approx(5.0, abs=0.15)
    tiny = _write_map(tmp_path / "tiny.csv", 0.5, lambda x, y: 0.12 + 0.68 * lump_profile(
        math.dist((x, y), (5.0, 5.0)), 1.0, lump_sharpness(1.0, 3.0)))
    (region,) = metrics.map_regions(tiny, (60.0, 60.0), 0.3)
    assert region["center_mm"] == pytest.approx([5.0, 5.0], abs=0.1) and region["radius_mm"] == pytest.approx(1.0, abs=0.1)


@hsettings(max_examples=8, deadline=None)
@given(noise=st.floats(0.0, 0.15), seed=st.integers(0, 2**16), spacing=st.sampled_from([0.5, 1.0, 2.0]))
@example(noise=0.08, seed=5, spacing=1.0)
@example(noise=0.12, seed=5, spacing=1.0)
def test_a_noisy_measured_map_s_truth_is_its_lump_not_its_noise(tmp_path_factory, noise, seed, spacing):
    """A measured map with up to 15 % noise per sample (a real robot's grid can be that rough), sampled every
    0.5-2 mm: smoothed only by a quarter of its spacing, the noise itself made regions (12 % on a 1 mm grid:
    39 with the lump among them, 75 without one), the truth every scan was scored against. The map is
    smoothed as far as its own noise asks, and a lump's region stays where it was drawn."""
    tmp_path = tmp_path_factory.mktemp("map")
    rng = np.random.default_rng(seed)

    def k_at(x, y, lump=True):
        return (0.12 + (0.3 / (1.0 + (math.hypot(x - 6.0, y + 4.0) / 8.0) ** 6) if lump else 0.0)) * (
            1.0 + rng.normal(0.0, noise))

    assert metrics.map_regions(_write_map(tmp_path / "none.csv", spacing, lambda x, y: k_at(x, y, False)),
                               (60.0, 60.0), 0.3) == []
    (region,) = metrics.map_regions(_write_map(tmp_path / "lump.csv", spacing, k_at), (60.0, 60.0), 0.3)
    assert region["center_mm"] == pytest.approx([6.0, -4.0], abs=0.5)  # 15 % on a 2 mm grid: up to 0.4 mm
    assert region["radius_mm"] == pytest.approx(8.0, abs=0.5)  # the top is still the (smoothed) map's highest


def test_the_learner_imports_nothing_above_it():
    code = ("import sys, palpd.learner, palpd.learner.service; "
            "print(sorted(m for m in sys.modules if m.startswith('palpd.') and not m.startswith('palpd.learner')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = set(eval(out))  # noqa: S307 (our own print of a list of names)
    assert not loaded & {"palpd.scan", "palpd.dataset", "palpd.bench", "palpd.daemon", "palpd.commands"}, loaded


@hsettings(max_examples=25, deadline=None)
@given(width_mm=st.floats(5.0, 150.0), height_mm=st.floats(5.0, 150.0), share=st.floats(0.08, 1.0),
       seed=st.integers(0, 7))
@example(width_mm=6.6796875, height_mm=7.0, share=0.10546875, seed=0)  # a rounded size once put points 2.5e-7 mm outside
def test_the_covering_lattice_leaves_no_spot_beyond_its_reach(width_mm, height_mm, share, seed):
    from palpd.learner.design import CHECK_STEP_MM, covering_lattice, lattice_order

    reach_mm = share * max(width_mm, height_mm)
    lattice = covering_lattice((width_mm, height_mm), reach_mm)
    half = np.array([width_mm, height_mm]) / 2.0
    spots = np.vstack([np.random.default_rng(seed).uniform(-half, half, (3000, 2)), half * [[1, 1], [1, -1], [-1, 1], [-1, -1]]])
    nearest = np.min(np.hypot(spots[:, None, 0] - lattice[None, :, 0], spots[:, None, 1] - lattice[None, :, 1]), 1)
    assert nearest.max() <= reach_mm + CHECK_STEP_MM / math.sqrt(2.0)  # checked on a grid that fine
    assert np.all(np.abs(lattice) <= half + 1e-9)
    # never much more than the hexagonal lattice's density (the densest covering: 2.6 r² per point)
    assert len(lattice) <= 2.0 * width_mm * height_mm / (2.598 * reach_mm**2) + 2.0 * (width_mm + height_mm) / reach_mm + 1
    order = np.array(lattice_order(lattice, seed))
    assert len(order) == len(lattice) and len(np.unique(np.round(np.abs(order), 6), axis=0)) == len(np.unique(np.round(np.abs(lattice), 6), axis=0))


@hsettings(max_examples=12, deadline=None)
@given(width_mm=st.floats(5.0, 758.0), height_mm=st.floats(5.0, 758.0), grid_points=st.sampled_from([11, 121, 401]))
@example(width_mm=200.0, height_mm=200.0, grid_points=121)  # 14 641 cells at 2 mm: one probe score 42 s and 12 GB
def test_the_probe_scores_weigh_bounded_lattices_on_any_tissue(width_mm, height_mm, grid_points):
    """The free-form map's probe score weighs every candidate against every cell in doubt, so its cost goes as
    the lattice's cells squared: on any tissue the arm reaches (up to 758 mm) and any grid, at most AREA_CELLS
    cells, none closer than AREA_STEP_MM where the grid allows, and a score for every candidate."""
    from palpd.config import LearnerSettings
    from palpd.learner import Learner
    from palpd.learner.decision import AREA_CELLS, AREA_STEP_MM
    from palpd.learner.model import COVERAGE_CELLS

    learner = Learner((width_mm, height_mm), LearnerSettings(grid_points=grid_points), 0.3)
    lattice, cell_area = learner._area_lattice
    assert len(lattice) <= AREA_CELLS
    # so is the coverage's, whose best unfelt spot weighs every cell against every other (4.2 s on 140 x 100 mm)
    assert len(learner.coverage.cells_xy) <= COVERAGE_CELLS
    xs, ys = np.unique(learner.grid_xy[lattice, 0]), np.unique(learner.grid_xy[lattice, 1])
    if len(xs) > 1 and len(ys) > 1:
        assert cell_area == pytest.approx((xs[1] - xs[0]) * (ys[1] - ys[0]))
        fine = min(width_mm, height_mm) / (grid_points - 1)  # the grid's own step, when coarser than AREA_STEP_MM
        assert min(xs[1] - xs[0], ys[1] - ys[0]) >= min(AREA_STEP_MM, fine) - 1e-9
    rng = np.random.default_rng(0)
    for xy in rng.uniform(-0.5, 0.5, (6, 2)) * (width_mm, height_mm):  # a stiff half: the free-form map in doubt
        learner.observe(xy, 0.36 if xy[0] > 0 else 0.12, 0.001)
    cells, _ = learner._probe_cells
    gain = learner._free_form_area_gain(cells)
    assert gain is None or (gain.shape == (len(cells),) and np.all(np.isfinite(gain)) and gain.min() >= -1e-9)


@hsettings(max_examples=15, deadline=None)
@given(width_mm=st.floats(3.0, 200.0), height_mm=st.floats(3.0, 200.0))
@example(width_mm=3.0, height_mm=140.0)  # one step for both axes, the x one: 4 x 4 candidates, 47 mm apart along y
@example(width_mm=81.0, height_mm=81.0)  # coarsened along x first on a tie: a square tissue, an oblong lattice
def test_a_tissue_turned_a_quarter_is_read_on_the_same_lattices_turned(width_mm, height_mm):
    """The probe candidates, the coverage's cells and the free-form score's lattice are as fine along a tissue's
    long side as across it, within a grid cell of the stride asked, and a tissue turned a quarter has them turned."""
    from palpd.config import LearnerSettings
    from palpd.learner import Learner
    from palpd.learner.decision import CANDIDATE_STRIDE_MM

    def spacings(learner, cells):
        xy = learner.grid_xy[cells]
        return tuple(float(np.diff(np.unique(xy[:, axis]))[0]) if len(np.unique(xy[:, axis])) > 1 else math.inf
                     for axis in (0, 1))

    wide, tall = (Learner(size, LearnerSettings(), 0.3) for size in ((width_mm, height_mm), (height_mm, width_mm)))
    for lattice in (lambda l: l._candidates(), lambda l: l._area_lattice[0]):
        x, y = spacings(wide, lattice(wide))
        assert spacings(tall, lattice(tall)) == pytest.approx((y, x))
    cells = [len(np.unique(learner.coverage.cells_xy[:, axis])) for learner in (wide, tall) for axis in (0, 1)]
    assert cells[:2] == cells[2:][::-1]
    x, y = spacings(wide, wide._candidates())
    cell_x, cell_y = width_mm / (len(wide.xs) - 1), height_mm / (len(wide.ys) - 1)
    assert (x == math.inf or x <= max(CANDIDATE_STRIDE_MM, cell_x) + 1e-9) and (y == math.inf or y <= max(CANDIDATE_STRIDE_MM, cell_y) + 1e-9)


def test_the_covering_lattice_of_a_60_mm_square_at_11_mm_is_16_points_its_first_half_spread():
    from palpd.learner.design import covering_lattice, lattice_order

    lattice = covering_lattice((60.0, 60.0), 11.0)
    assert len(lattice) == 16 and len(covering_lattice((60.0, 60.0), 10.0)) == 18  # hexagonal there
    first = np.array(lattice_order(lattice, 0)[:8])
    assert np.min([math.dist(a, b) for i, a in enumerate(first) for b in first[i + 1:]]) >= 20.0


@hsettings(max_examples=20, deadline=None)
@given(width_mm=st.floats(5.0, 200.0), height_mm=st.floats(5.0, 200.0), reach_mm=st.floats(3.0, 15.0),
       wider_mm=st.floats(0.0, 10.0))
def test_the_none_reach_widens_only_as_far_as_the_covering_needs_to_stay_small(width_mm, height_mm, reach_mm, wider_mm):
    """`none` costs the covering lattice's points: on a tissue where the set reach needs more than NONE_POINTS,
    the reach widens to the first (on its REACH_STEP_MM steps) that needs no more, never past the widest."""
    from palpd.learner.design import NONE_POINTS, REACH_STEP_MM, covering_lattice, none_reach

    widest = reach_mm + wider_mm
    reach = none_reach((width_mm, height_mm), reach_mm, widest)
    assert reach_mm <= reach <= widest
    points = len(covering_lattice((width_mm, height_mm), reach))
    if len(covering_lattice((width_mm, height_mm), reach_mm)) <= NONE_POINTS:
        assert reach == reach_mm
    elif reach < widest:  # at the widest it may need more: the cap is the user's (--coverage-mm)
        assert points <= NONE_POINTS < len(covering_lattice((width_mm, height_mm), reach - REACH_STEP_MM))


def test_the_none_reach_is_11_mm_up_to_a_60_mm_square_and_wider_beyond():
    from palpd.learner.design import none_reach

    for size in ((40.0, 40.0), (60.0, 60.0), (70.0, 50.0), (80.0, 40.0)):
        assert none_reach(size, 11.0, 18.0) == 11.0, size
    assert 11.0 < none_reach((80.0, 80.0), 11.0, 18.0) < none_reach((100.0, 100.0), 11.0, 18.0) <= 18.0
    assert none_reach((80.0, 80.0), 11.0, 11.0) == 11.0  # --coverage-mm caps it: the user's side of the trade


def test_the_first_design_of_a_wide_tissue_is_toured_only_as_far_as_it_is_palpated():
    """The tour was quadratic in pure Python over every lattice point: a 2 m tissue's first design took
    minutes. Its first points are the whole tour's first points."""
    import time

    from palpd.learner.design import covering_lattice, first_design, lattice_order

    lattice = covering_lattice((60.0, 60.0), 11.0)
    for seed in range(8):
        assert lattice_order(lattice, seed, 10) == lattice_order(lattice, seed)[:10]
    wide = covering_lattice((750.0, 750.0), 11.0)
    started = time.process_time()
    design = first_design((750.0, 750.0), wide, 8, 0)
    assert len(design) == 8 and time.process_time() - started < 2.0  # CPU time: a busy machine does not stretch it


def test_readings_faintly_above_the_model_around_a_hole_send_the_next_probe_into_it():
    """Four readings each 2 sd above the chosen model around an unread spot: no one of them is a lump
    (evidence.supported), together they are (4 × 2 / √4 = 4 sd); one such reading alone, or readings below, are not."""
    from palpd.learner.coverage import Readings, hidden_lump_spot

    xs = np.arange(-30.0, 30.01, 2.0)
    gx, gy = np.meshgrid(xs, xs)
    readings_xy = np.array([[x, y] for x in (-22.5, -7.5, 7.5, 22.5) for y in (-22.5, -7.5, 7.5, 22.5)])
    readings = Readings(np.column_stack([gx.ravel(), gy.ravel()]), 1.5)
    for xy in readings_xy:
        readings.add(xy)
    around = np.hypot(*(readings_xy - [-15.0, 15.0]).T) < 11.0
    assert np.allclose(hidden_lump_spot(np.where(around, 2.0, 0.0), readings_xy, readings, 11.0), [-15.0, 15.0], atol=1.0)
    assert hidden_lump_spot(np.where(around, -2.0, 0.0), readings_xy, readings, 11.0) is None
    one = np.zeros(len(readings_xy))
    one[np.flatnonzero(around)[0]] = 2.0
    assert hidden_lump_spot(one, readings_xy, readings, 11.0) is None
    readings.probed((-15.0, 15.0))  # a palpation there gave no reading: looked at, not asked for again and again
    again = hidden_lump_spot(np.where(around, 2.0, 0.0), readings_xy, readings, 11.0)
    assert again is None or math.dist(again, (-15.0, 15.0)) >= 0.75 * 11.0


def test_a_reading_that_moves_the_centre_further_than_its_sd_allows_is_not_settled():
    """In a Gaussian posterior a reading z sd from its prediction moves a quantity by at most |z| of its sd
    before: a larger move (the posterior was narrower than the readings bear out) or a model that just
    changed is no place to stop, however small the sds are now; a move within that bound is, unless the
    reading before moved it further (one reading's agreement does not restore a posterior just shown too
    narrow)."""
    from dataclasses import replace

    from palpd.config import LearnerSettings
    from palpd.learner.describe import quantities
    from palpd.learner.model import Learner

    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=21), 0.3, 0)
    k_at = lambda p: 0.12 + 0.68 / (1 + (math.dist(p, (5.0, 5.0)) / 7.0) ** 8)  # noqa: E731
    for p in lattice() + [(5.0, 5.0), (11.0, 5.0), (5.0, 11.0)]:
        learner.observe(p, k_at(p), 0.02 * k_at(p))
    fit = learner.chosen_fit()
    assert fit.name == "circles:1"

    def is_settled() -> bool:
        learner._cache.clear()  # what the learner works out once an update, as a new reading would have it
        return learner._settled()

    cx = fit.family.lump_slice(0).start  # the lump's centre x in θ
    x_sd = math.sqrt(quantities(fit)[0] @ fit.cov @ quantities(fit)[0])
    for shift_sd, surprise_sd, settled_before, settled in [
            (0.5, 0.0, True, True), (3.0, 1.0, True, False), (-3.0, 0.3, True, False), (3.0, 3.5, True, True),
            (0.0, 0.0, True, True), (0.5, 0.0, False, False), (0.0, 0.0, False, False)]:
        theta = fit.theta.copy()
        theta[cx] -= shift_sd * x_sd  # the centre before this reading, shift_sd of its own sd away
        learner._fit_before, learner.surprise_sd = replace(fit, theta=theta), surprise_sd
        learner._settled_before = settled_before  # whether the reading before this one settled it
        assert is_settled() is settled, (shift_sd, surprise_sd, settled_before)
    learner._settled_before = True
    learner._fit_before = None  # no lump model before this reading
    assert not is_settled()
    # another shape of the same count (issue 48: its doubt is in P, which the tolerance bounds) settles when its
    # lumps moved within the tolerance, and not when they moved further; another count never does
    ellipse = replace(fit.family, kind="ellipses")
    learner._fit_before = replace(fit, family=ellipse)
    assert is_settled()
    theta = fit.theta.copy()
    theta[cx] -= 2.0 * learner.settings.tolerance_mm
    learner._fit_before = replace(fit, family=ellipse, theta=theta)
    assert not is_settled()
    learner._fit_before = learner.hypotheses.fits["none"]
    assert not is_settled()


def test_rivals_that_predict_alike_are_told_apart_around_the_lump_not_at_the_farthest_spot():
    """Eight first readings (recorded from a simulated low-contrast scene) of which one felt a lump: the
    circle and the ellipse fitted to it coincide (equal axes), so no reading's prediction tells them apart
    and the choice stays unconfident. The next probe goes where the lump's shape is read, near the
    reading that felt it; scored by disagreement alone (zero everywhere) it went to the tissue's farthest
    spot, and the scan spent its whole budget on plain tissue."""
    from palpd.config import LearnerSettings
    from palpd.learner.model import Learner

    felt = (7.5, -8.0)
    recorded = [(felt, 0.17993, 0.00217), ((22.5, -24.0), 0.12016, 0.00316), ((-7.5, -24.0), 0.11989, 0.003),
                ((-22.5, -8.0), 0.11993, 0.00308), ((-7.5, 8.0), 0.12027, 0.00325), ((7.5, 24.0), 0.12014, 0.00315),
                ((22.5, 8.0), 0.11922, 0.00322), ((-22.5, 24.0), 0.12065, 0.00302)]
    learner = Learner((60.0, 60.0), LearnerSettings(), 0.3, 2)
    for xy, k, relative_sd in recorded:
        learner.observe(xy, k, relative_sd * k)
    assert learner.choice.chosen == "circles:1" and learner.choice.weight < learner.settings.confidence, learner.choice
    assert learner.choice.runner_up == "ellipse:1"
    probe = learner.next_probe()
    assert math.dist(probe, felt) <= 12.0, probe


@hsettings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.001, 1.0), st.floats(-5.0, 5.0), st.floats(1e-8, 1.0)), min_size=2, max_size=4),
       st.floats(1e-8, 1.0))
def test_a_reading_tells_the_hypotheses_apart_by_at_most_the_entropy_of_their_weights(rivals, noise_var):
    """The information a reading carries about which hypothesis is right is between 0 (they predict alike)
    and the entropy of their weights (it tells them apart for sure), however far apart the predictions."""
    from palpd.learner.acquisition import disagreement

    predictions = [(w, np.array([m, 0.0]), np.array([v, v])) for w, m, v in rivals]
    for i, (w, m, v) in enumerate(rivals):  # the second cell: every hypothesis predicts the first one's
        predictions[i][1][1], predictions[i][2][1] = rivals[0][1], rivals[0][2]
    weights = np.array([w for w, _, _ in rivals]) / sum(w for w, _, _ in rivals)
    score = disagreement(predictions, noise_var)
    assert -1e-9 <= score[0] <= float(-weights @ np.log(weights)) + 1e-9
    assert abs(score[1]) <= 1e-9


def test_a_far_off_rival_of_little_weight_does_not_outbid_the_close_call_between_the_leading_two():
    """Where a 5 % rival predicts 50 sd off (a tilted background, in a tissue corner), a reading can tell
    little more than whether that rival is right; where the leading two (60 % and 35 %) differ by 3 sd it
    says which of them is. Scored by the moment-matched spread, the corner won 2.05 to 0.35 nats and drew
    three probes in a row there (four-lumps, seed 0)."""
    from palpd.learner.acquisition import disagreement

    sd = 0.01
    corner, lump = 0, 1
    predictions = [(0.6, np.array([0.0, 0.0]), np.full(2, sd**2)), (0.35, np.array([0.0, 3 * sd]), np.full(2, sd**2)),
                   (0.05, np.array([50 * sd, 0.0]), np.full(2, sd**2))]
    score = disagreement(predictions, sd**2)
    assert score[lump] > score[corner]


def test_where_the_chosen_fit_misses_what_the_free_form_map_shows_the_larger_miss_comes_first():
    """The misfit between the chosen fit and the free-form map ranks spots by how far apart they stand:
    as information about which of the two is right, an 8 sd and a 16 sd miss both tie at log 2, and the
    probes went to the nearest such spot, six in a row a few mm apart (touching-lumps, seed 1)."""
    from palpd.learner.acquisition import disagreement, misfit

    sd = 0.01
    fit = (np.zeros(3), np.full(3, sd**2))
    free_form = (np.array([0.0, 8 * sd, 16 * sd]), np.full(3, sd**2))
    score = misfit(fit, free_form, sd**2)
    assert score[0] == 0.0 and score[2] > score[1] + 0.5
    as_choice = disagreement([(0.5, *fit), (0.5, *free_form)], sd**2)
    assert as_choice[2] - as_choice[1] < 0.1  # why not that: both near its ceiling, log 2


def test_asking_for_the_estimate_between_readings_changes_nothing_the_learner_decides():
    """The daemon publishes the estimate after every palpation; a CLI scan asks only at the end. Both must
    take the same course: reading the estimate (which checks the chosen fit's covariance, posterior.py)
    between readings may not change the later fits, probes or stop."""
    from palpd.config import LearnerSettings
    from palpd.learner.model import Learner

    k_at = lambda p: 0.12 + 0.5 / (1 + (math.dist(p, (-6.0, 9.0)) / 6.0) ** 6)  # noqa: E731
    courses = []
    for watched in (False, True):
        learner = Learner((60.0, 60.0), LearnerSettings(grid_points=41), 0.3, 1)
        probes = []
        while len(probes) < 22 and (probe := learner.next_probe(40)) is not None:
            probes.append(probe)
            learner.observe(probe, k_at(probe), 0.02 * k_at(probe))
            if watched:
                learner.lumps(), learner.posterior_grid()
        courses.append((probes, [lump.as_dict() for lump in learner.lumps()], learner.model()))
    assert courses[0] == courses[1]


def test_the_lump_whose_edge_no_reading_touched_is_probed_first_and_a_lump_still_unsure_before_a_pinned_one():
    """Two lumps: the first read all round its edge but for a 135° stretch, the second read only at its centre.
    The edge to read next is the second's: taken lump by lump, the first lump's gap came first, and with four
    lumps the budget ran out while the last, never read at its edge, was reported at a third of its radius.
    But a lump whose posterior sd is over the tolerance comes before one already pinned (four lumps, seed 0: six
    probes went to gaps on lumps at 0.03 mm sd while one at 0.9 mm met the budget 0.8 mm off)."""
    from types import SimpleNamespace

    from palpd.learner import shapes
    from palpd.learner.coverage import uncovered_edge

    family = shapes.Family("circles", 2, 30.0)
    theta = np.concatenate([[math.log(0.12), 0.0, 0.0], shapes.make_lump((-12.0, 0.0), 6.0, 6.0, 4.0),
                            shapes.make_lump((14.0, 5.0), 5.0, 6.0, 4.0)])
    fit = SimpleNamespace(family=family, theta=theta)
    # the first lump's edge (6 mm out) read every 45° except from 0° to 135°; the second only at its centre
    first = [(-12.0 + 6.0 * math.cos(math.radians(a)), 6.0 * math.sin(math.radians(a))) for a in range(180, 360, 45)]
    readings = np.array([(-12.0, 0.0), (14.0, 5.0), *first])
    where = uncovered_edge(fit, readings, (60.0, 60.0), 2.0)
    assert where is not None and math.dist(where, (14.0, 5.0)) == pytest.approx(5.0, abs=1.0), where
    # once the second lump's edge is read all round, the first one's gap is next
    second = [(14.0 + 5.0 * math.cos(math.radians(a)), 5.0 + 5.0 * math.sin(math.radians(a))) for a in range(0, 360, 60)]
    where = uncovered_edge(fit, np.vstack([readings, second]), (60.0, 60.0), 2.0)
    assert where is not None and math.dist(where, (-12.0, 0.0)) == pytest.approx(6.0, abs=1.0)
    assert 0.0 < math.degrees(math.atan2(where[1], where[0] + 12.0)) < 135.0, where
    # a lump still unsure by its posterior sd goes first: the first lump's 135° gap before the second's whole edge
    where = uncovered_edge(fit, readings, (60.0, 60.0), 2.0, unsure=np.array([True, False]))
    assert where is not None and math.dist(where, (-12.0, 0.0)) == pytest.approx(6.0, abs=1.0), where
    assert 0.0 < math.degrees(math.atan2(where[1], where[0] + 12.0)) < 135.0, where
    # both unsure, or neither: the widest gap, as without
    for unsure in ([True, True], [False, False]):
        where = uncovered_edge(fit, readings, (60.0, 60.0), 2.0, unsure=np.array(unsure))
        assert where is not None and math.dist(where, (14.0, 5.0)) == pytest.approx(5.0, abs=1.0), (unsure, where)



def test_a_free_form_map_that_needs_more_noise_than_readings_have_is_probed_on_its_boundary():
    """Thirteen first readings (recorded from a simulated active scan of the measured half-stiff map, seed 0):
    the free-form map is chosen and needs more than twice the readings' noise (the map's own texture). It is
    the model of last resort, so that is no reason to go on (held to the parametric fits' bar, the measured map
    ended `undetermined` at IoU 0.99 on seeds 3-6), and there is nothing more flexible to compare it with. The next probe goes where the
    map is least sure which side of its boundary a spot lies. Scored by the free-form's disagreement with
    itself (0 at every cell) it went to the spot farthest from every probe, the tissue's edge: a measured
    map's corners and edges were read while its boundary stayed as unsure."""
    from scipy.stats import norm

    from palpd.config import Settings
    from palpd.learner.planner import make_learner

    recorded = [((-7.5, -8.0), 0.11577, 0.000371), ((-22.5, -24.0), 0.12033, 0.000379),
                ((7.5, -24.0), 0.27827, 0.000367), ((22.5, -8.0), 0.29931, 0.000414), ((7.5, 8.0), 0.29968, 0.000389),
                ((-7.5, 24.0), 0.26892, 0.000381), ((-22.5, 8.0), 0.12042, 0.000361), ((22.5, 24.0), 0.29702, 0.000388),
                ((-9.0, -7.0), 0.12345, 0.000376), ((-6.0, -9.0), 0.12138, 0.000353), ((-6.0, -7.0), 0.11917, 0.000354),
                ((22.5, -24.0), 0.30342, 0.000370), ((-22.5, 24.0), 0.12072, 0.000370)]
    learner = make_learner(Settings(), (60.0, 60.0), 0)
    for xy, k, sd in recorded:
        learner.observe(xy, k, sd)
    from palpd.learner.evidence import ADEQUATE_NOISE

    assert learner.choice.chosen == "free-form" and learner.choice.weight >= 0.9
    assert learner._chosen_noise_sd() > ADEQUATE_NOISE * learner.noise_floor and learner._adequate()
    m = learner.free_form_map()

    def stiff_probability(xy):
        row, col = int(np.argmin(np.abs(m.ys - xy[1]))), int(np.argmin(np.abs(m.xs - xy[0])))
        cell = row * len(m.xs) + col
        return norm.cdf((learner.gp.mean[cell] - math.log(m.tau[row, col])) / learner.gp.std()[cell])

    probe = learner.next_probe(40)
    assert 0.25 <= stiff_probability(probe) <= 0.75, probe  # before: (-30, -8), the farthest spot, at 0.21


@given(z=st.floats(0.0, 8.0), rho=st.floats(0.0, 1.0), other=st.floats(0.0, 1.0))
@hsettings(max_examples=60, deadline=None)
@example(z=0.0, rho=1.0, other=0.0)
@example(z=8.0, rho=1e-12, other=1.0)
def test_a_reading_takes_off_at_most_a_cells_misclassified_area_and_more_the_more_it_is_correlated(z, rho, other):
    """The misclassified area a reading is expected to take off a cell in doubt (min(P, 1 − P) of its area, P =
    Φ(z)) lies between nothing (a reading it is not correlated with) and all of it (a noise-free reading at the
    cell itself), and grows with the correlation: at the extremes of both z and ρ too."""
    from scipy.special import ndtr

    from palpd.learner.acquisition import MIN_CORRELATION, misclassified_area_gain

    var_cell, noise = 0.04, 1e-4
    low, high = sorted((rho, other))

    def gain(r: float) -> float:  # one candidate, one cell: cov for a correlation r with the reading
        cov = np.array([[r * math.sqrt((var_cell + noise) * var_cell)]])
        return float(misclassified_area_gain(cov, np.array([var_cell]), noise, np.array([z]), np.array([var_cell]), 4.0)[0])

    whole = 4.0 * float(ndtr(-z))
    table_error = 4.0 * 4e-4  # what is taken is read off a table (acquisition._area_taken): within 4e-4 a cell
    assert -1e-9 <= gain(low) <= gain(high) + 1e-9 <= whole + table_error
    if low <= MIN_CORRELATION:
        assert gain(low) == 0.0
    assert gain(1.0) == pytest.approx(whole, abs=table_error)


@given(seed=st.integers(0, 2**32 - 1), candidates=st.integers(1, 6), cells=st.integers(1, 9),
       spread=st.sampled_from([0.1, 1.0, 10.0]), strength=st.sampled_from([1.0, 0.05]))
@hsettings(max_examples=40, deadline=None)
def test_each_candidates_area_is_the_sum_over_its_own_pairs_whatever_the_cells(seed, candidates, cells, spread,
                                                                              strength):
    """The score of every candidate against every cell at once (each cell's z read once, each pair's ρ) is,
    candidate by candidate, the sum of Φ(−z) − 2·T(z, √(1 − ρ²)/ρ) over the cells it is correlated with by
    more than MIN_CORRELATION, to the table's error: z of any sign and size, ρ from 0 to 1, most pairs
    correlated (summed in place) or few (a list of pairs)."""
    from scipy.special import ndtr, owens_t

    from palpd.learner.acquisition import MIN_CORRELATION, misclassified_area_gain

    rng = np.random.default_rng(seed)
    var_candidates, var_cells, noise = rng.uniform(0.01, 0.1, candidates), rng.uniform(0.01, 0.1, cells), 1e-3
    bound = np.sqrt((var_candidates[:, None] + noise) * var_cells[None, :])
    cov = rng.uniform(-1.0, 1.0, (candidates, cells)) * bound * strength  # |ρ| ≤ 1
    z = rng.normal(0.0, spread, cells)
    got = misclassified_area_gain(cov, var_candidates, noise, z, var_cells, 2.0)
    rho = np.abs(cov) / bound
    safe = np.clip(rho, 1e-12, 1.0)
    exact = np.where(rho > MIN_CORRELATION,
                     ndtr(-np.abs(z))[None, :] - 2.0 * owens_t(np.abs(z)[None, :], np.sqrt(1.0 - safe**2) / safe), 0.0)
    assert got == pytest.approx(2.0 * exact.sum(axis=1), abs=2.0 * 4e-4 * cells)


def test_the_first_readings_area_score_read_a_band_of_cells_at_a_time_is_the_whole_sum_bit_for_bit():
    """While nearly every pair counts (the first readings), misclassified_area_gain reads the table a band of
    AREA_BLOCK_CELLS cells at a time (the band's rows stay in the cache): every pair's value and every
    candidate's sum are what the whole candidates × cells array at once gives, to the last bit, over cells
    that span several bands and one that ends part-way."""
    from palpd.learner.acquisition import AREA_BLOCK_CELLS, MIN_CORRELATION, _area_taken, misclassified_area_gain

    rng = np.random.default_rng(3)
    candidates, cells = 7, 2 * AREA_BLOCK_CELLS + 5
    var_candidates, var_cells, noise = rng.uniform(0.01, 0.1, candidates), rng.uniform(0.01, 0.1, cells), 1e-3
    bound = np.sqrt((var_candidates[:, None] + noise) * var_cells[None, :])
    cov = rng.uniform(0.05, 1.0, (candidates, cells)) * rng.choice([-1.0, 1.0], (candidates, cells)) * bound
    cov[0, :3] = 0.0  # a few pairs under MIN_CORRELATION, counted as nothing
    z = rng.normal(0.0, 1.5, cells)
    rho = np.abs(cov) / np.sqrt(var_candidates + noise)[:, None] / np.sqrt(var_cells)[None, :]
    assert np.count_nonzero(rho > MIN_CORRELATION) > 0.5 * rho.size  # the banded path
    rho[~(rho > MIN_CORRELATION)] = 0.0
    whole = 2.0 * _area_taken(np.abs(z), np.arange(cells)[None, :], rho).sum(axis=1)
    assert np.array_equal(misclassified_area_gain(cov, var_candidates, noise, z, var_cells, 2.0), whole)
    given_up = cov.copy()  # the learner's own cov, taken over: the same sums, one fresh array fewer
    assert np.array_equal(misclassified_area_gain(given_up, var_candidates, noise, z, var_cells, 2.0,
                                                  overwrite_cov=True), whole)
    assert not np.array_equal(given_up, cov)


def test_the_misclassified_area_a_reading_takes_off_is_what_the_field_would_show_after_it():
    """Monte Carlo over the readings a Gaussian field could give at one spot: the misclassified area left over
    three cells (one at the reading, one near, one far off) is what acquisition.misclassified_area_gain says
    the reading takes off, to the sampling error."""
    from scipy.special import ndtr

    from palpd.learner.acquisition import misclassified_area_gain

    rng = np.random.default_rng(1)
    points = np.array([[0.0], [2.0], [9.0]])  # the reading at the first
    cov = 0.09 * np.exp(-0.5 * (points - points.T) ** 2 / 3.0**2)
    mean, tau, noise = np.array([0.1, -0.15, 0.05]), 0.0, 0.01
    z = np.abs(mean - tau) / np.sqrt(np.diag(cov))
    before = ndtr(-z).sum()
    field = rng.multivariate_normal(mean, cov, size=200_000)
    reading = field[:, 0] + rng.normal(0.0, math.sqrt(noise), len(field))
    gain_k = cov[0] / (cov[0, 0] + noise)
    after_mean = mean + (reading - mean[0])[:, None] * gain_k
    after_sd = np.sqrt(np.diag(cov) - cov[0] ** 2 / (cov[0, 0] + noise))
    p = ndtr((after_mean - tau) / after_sd)
    after = np.minimum(p, 1.0 - p).sum(axis=1).mean()
    stated = misclassified_area_gain(cov[:1], np.array([cov[0, 0]]), noise, z, np.diag(cov), 1.0)[0]
    assert stated == pytest.approx(before - after, abs=3e-3)
    assert stated > 0.3  # the cell read itself all but settled


def test_a_chosen_free_form_map_reads_where_a_reading_takes_the_most_off_its_misclassified_area():
    """Twenty-six readings of the measured half-stiff map (a learner alone on the scene's field, seed 0): the
    free-form map is chosen, and the stop rule's misclassified area ∫ min(P, 1 − P) dA is 357 mm², most of it
    far from the boundary. Each next probe is the lattice cell a reading is expected to take the most off
    (acquisition.misclassified_area_gain; the learner's own score, before the travel it adds), and six of them
    take the area under three quarters of what it was (357 -> 252 mm²; the probes that read the boundary's
    position before took it to 248 and left most of the doubt far from it where it was, so that the scans of
    that map stated 3.6 mm at the budget for a true 0.38)."""
    from drivers.sim.scene import load_scene
    from drivers.sim.tissue import StiffnessField
    from palpd.config import LearnerSettings
    from palpd.learner.model import Learner

    scene = load_scene(Path(__file__).resolve().parent.parent / "config" / "scenes" / "half-stiff-map.toml")
    recorded = [((-7.5, -8.0), 0.11599), ((-22.5, -24.0), 0.12014), ((7.5, -24.0), 0.27963), ((22.5, -8.0), 0.29989),
                ((7.5, 8.0), 0.29868), ((-7.5, 24.0), 0.27041), ((-22.5, 8.0), 0.12205), ((22.5, 24.0), 0.30008),
                ((28.0, 2.0), 0.30537), ((-9.0, -8.0), 0.12036), ((-6.0, -8.0), 0.1197), ((22.5, -24.0), 0.303),
                ((-22.5, 24.0), 0.11811), ((26.0, 18.0), 0.30736), ((28.0, 18.0), 0.29614), ((-6.0, 9.0), 0.12648),
                ((-3.0, 8.0), 0.13288), ((-6.0, 12.0), 0.12776), ((-6.0, 18.0), 0.1927), ((6.0, -5.0), 0.23275),
                ((0.0, -29.0), 0.14804), ((3.0, -17.0), 0.14441), ((9.0, -12.0), 0.2739), ((2.0, 17.0), 0.30161),
                ((-12.0, 30.0), 0.29243), ((-14.0, 25.0), 0.14164)]
    learner = Learner((60.0, 60.0), LearnerSettings(), 0.3, 0)
    for xy, k in recorded:
        learner.observe(xy, k, 0.001)
    assert learner.choice.chosen == "free-form" and learner.choice.weight >= 0.9
    before = learner._boundary_error_parts()[0]
    assert 300.0 < before < 400.0
    field = StiffnessField(scene)
    for _ in range(6):
        cells, _ = learner._probe_cells
        score = learner._free_form_area_gain(cells)
        xy = learner.next_probe(40)
        best = np.flatnonzero(score > 0.0)[np.argmax(score[score > 0.0])]
        assert score[np.flatnonzero(np.all(learner.grid_xy[cells] == xy, axis=1))[0]] >= 0.5 * score[best], xy
        learner.observe(xy, field.k_at(*xy), 0.001)
    assert learner._boundary_error_parts()[0] <= 0.75 * before


@pytest.mark.parametrize("shape", ["half", "disc"])
def test_a_free_form_regions_sds_are_its_boundarys_carried_to_its_centroid_and_area(shape):
    """A map whose boundary is known to δ = σ/|∇μ| = 1 mm everywhere, ℓ = 6 mm: the region's centroid
    and equal-area radius have the sds that δ gives them (for a disc, a circle fit's δ·√(4/N) for the
    centre's distance, both axes, and δ/√N, N = 2πr/ℓ; for the stiff half of the tissue, found by
    integrating along its straight boundary), and the boundary's own sd is δ. A circle fitted to a
    straight boundary has no centre: reported that way, a half-stiff map's sds never came near the
    tolerance however well it was read."""
    from palpd.learner.lumps import Map, find_lumps

    axis = np.linspace(-30.0, 30.0, 121)
    gx, gy = np.meshgrid(axis, axis)
    across = gx - 3.0 if shape == "half" else 10.0 - np.hypot(gx, gy)  # mm inside the boundary
    mean = 0.12 + 0.2 / (1.0 + np.exp(-across / 2.0))  # slope 0.025 N/mm per mm at the boundary
    m = Map(axis, axis, mean, np.full_like(mean, 0.025), np.full_like(mean, 0.22), 6.0, 0.22)
    (lump,) = find_lumps(m, np.array([[20.0, 0.0] if shape == "half" else [0.0, 0.0]]))
    if shape == "half":
        area, length = 27.0 * 60.0, 60.0
        moment = 60.0 * 13.5**2 + 2.0 * 30.0**3 / 3.0  # ∫ |p − c|² along x = 3, c = (16.5, 0)
        centre_sd = math.sqrt(6.0 * moment) / area
        radius_sd = math.sqrt(6.0 * length) / (2.0 * math.sqrt(math.pi * area))
    else:
        n = 2.0 * math.pi * 10.0 / 6.0
        centre_sd, radius_sd = math.sqrt(4.0 / n), 1.0 / math.sqrt(n)
    assert lump.boundary_sd_mm == pytest.approx(1.0, rel=0.05)
    assert lump.center_sd_mm == pytest.approx(centre_sd, rel=0.1)
    assert lump.radius_sd_mm == pytest.approx(radius_sd, rel=0.1)
    assert "boundary_sd_mm" in lump.as_dict()


@hsettings(max_examples=40, deadline=None)
@given(width=st.floats(20.0, 100.0), height=st.floats(20.0, 100.0), radius=st.floats(3.0, 9.0),
       where=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)), reading=st.tuples(st.floats(-0.7, 0.7),
                                                                                       st.floats(-0.7, 0.7)))
def test_a_free_form_region_on_a_tissue_of_any_aspect_is_backed_by_its_reading_and_measured_in_mm(
        width, height, radius, where, reading):
    """The learner's grid has as many cells along y as along x, so on a tissue that is not square its cells
    are not square either. Each axis in its own step: a stiff reading inside the region backs it wherever it
    lies, and the region's area is in mm² (garg-phantom, 58 x 20 mm, was reported 10.5 mm too wide in
    radius, its cells counted as 0.97 mm squares, and a reading off the region's middle row looked up in
    another row)."""
    from palpd.learner.lumps import Map, find_lumps

    xs, ys = np.linspace(-width / 2, width / 2, 61), np.linspace(-height / 2, height / 2, 61)
    radius = min(radius, 0.3 * min(width, height))
    centre = np.array([where[0] * (width / 2 - radius - 1.0), where[1] * (height / 2 - radius - 1.0)])
    gx, gy = np.meshgrid(xs, ys)
    mean = np.where(np.hypot(gx - centre[0], gy - centre[1]) <= radius, 0.6, 0.12)
    m = Map(xs, ys, mean, np.full_like(mean, 0.01), np.full_like(mean, 0.36), 4.0, 0.36)
    stiff = centre + radius * np.array(reading)  # anywhere within 0.7 of the radius along each axis
    (lump,) = find_lumps(m, stiff[None, :])
    cell = max(xs[1] - xs[0], ys[1] - ys[0])
    assert lump.radius_mm == pytest.approx(radius, abs=cell), (lump.radius_mm, radius, cell)
    assert math.dist(lump.center_mm, centre) <= cell


@given(gap_p=st.floats(0.0, 0.49), gap_mm=st.floats(4.0, 30.0), length_mm=st.floats(2.0, 10.0))
@hsettings(max_examples=30, deadline=None)
def test_two_regions_of_the_map_are_one_by_the_chance_that_the_cells_between_them_are_lump(gap_p, gap_mm, length_mm):
    """The free-form map's count over its posterior (lumps.count_spread): two stiff strips `gap_mm` apart
    with P(lump) = `gap_p` between them are one with the chance of that gap being lump all across, cells ℓ
    apart independent (gap_p ** (gap / ℓ)), and plain tissue as much in doubt around them joins them no more:
    a way round is longer. A garg-phantom scan (seed 1) drew the rod and the strip along the phantom's edge
    as two regions across cells never read, and said `lumps` at weight 1.000, one of them false."""
    from palpd.learner.lumps import Map, count_spread

    axis = np.linspace(-30.0, 30.0, 121)
    gx, gy = np.meshgrid(axis, axis)
    half = gap_mm / 2.0
    stiff = (np.abs(gy) <= 12.0) & (np.abs(gx) >= half) & (np.abs(gx) <= half + 8.0)
    mean = np.where(stiff, 0.6, 0.12)
    m = Map(axis, axis, mean, np.full_like(mean, 0.01), np.full_like(mean, 0.36), length_mm, 0.36)
    p = np.where(stiff, 0.99, gap_p)
    spread = count_spread(m, np.array([[-half - 4.0, 0.0], [half + 4.0, 0.0]]), p)
    across = np.count_nonzero(np.abs(axis) < half) * (axis[1] - axis[0])  # the gap's cells along a row, in mm
    joined = max(gap_p, 1e-12) ** (across / length_mm)  # P floored at 1e-12 (a cell is never surely no lump)
    assert sum(spread.values()) == pytest.approx(1.0)
    assert spread.get(1, 0.0) == pytest.approx(joined, rel=1e-6), (spread, joined)


def test_the_count_says_how_large_a_lump_could_lie_unfelt_between_the_readings():
    """A lump whose disc holds no reading is felt by none: the report's model gives the largest such radius, the
    farthest spot's distance from every reading, and it shrinks where the next reading goes."""
    from palpd.config import Settings
    from palpd.learner.planner import make_learner

    learner = make_learner(Settings().updated(learner={"grid_points": 61}), (60.0, 60.0), 0)
    rng = np.random.default_rng(3)
    spots = [tuple(xy) for xy in rng.uniform(-28.0, 28.0, (6, 2))]  # no two spots equally far from the readings
    for xy in spots:
        learner.observe(xy, 0.12 * (1.0 + rng.normal(0.0, 0.02)), 0.0024)
    fine = np.stack(np.meshgrid(np.linspace(-30, 30, 241), np.linspace(-30, 30, 241)), axis=-1).reshape(-1, 2)
    reported = []
    for _ in range(3):
        distance = np.hypot(*(fine[:, None, :] - np.asarray(spots)[None]).transpose(2, 0, 1)).min(axis=1)
        truth = float(distance.max())
        reported.append(learner.model()["unfelt_radius_mm"])
        assert truth - math.sqrt(2.0) - 0.05 <= reported[-1] <= truth + 0.05  # on a 2 mm lattice of cells
        spots.append(tuple(fine[int(np.argmax(distance))]))  # the next reading where a lump could hide most
        learner.observe(spots[-1], 0.12, 0.0024)
    assert reported[-1] < reported[0]


def read_on(recorded, seed, truth, tissue=0.12):
    """A learner given recorded readings, then reading on where it asks, on the field the scene had (the
    simulator's lumps), until it stops: (the learner after the recorded readings' model, its next probe),
    and the metrics of what it ends on."""
    from palpd.config import Settings
    from palpd.learner.planner import make_learner
    from test_learner import field

    learner = make_learner(Settings(), (60.0, 60.0), seed)
    for xy, k, *sd in recorded:  # (xy, k) or (xy, k, sd)
        learner.observe(xy, k, sd[0] if sd else 0.001 * k)
    model, first = learner.model(), learner.next_probe()
    k_at = field(truth, tissue)
    while (xy := learner.next_probe()) is not None:
        learner.observe(xy, k_at(xy), 0.001 * k_at(xy))
    found = metrics.compare([{"center_mm": c, "radius_mm": r} for c, r, *_ in truth],
                            [lump.as_dict() for lump in learner.lumps()])
    return model, first, found


def test_a_rival_s_lump_where_nothing_was_read_is_read_once_before_the_choice_stands():
    """Twenty-six readings recorded from a simulated active scan of two-lumps (seed 7): the deep lump at
    (14, -13), 6 mm, felt only on its flank at (7.5, -8), was explained with the other by one long ellipse,
    chosen at 0.97 over the right two circles, whose second centre no reading had come within 8 mm of; the
    scan stopped there, one lump reported. A rival's lump that holds no palpation is read once first (or,
    refitted thoroughly before a stop, the ellipse gains and the rival falls under 1 %: where it predicts
    most unlike the ellipse); it reads on and ends on both lumps."""
    from palpd.config import Settings
    from palpd.learner.planner import make_learner

    recorded = [((-7.5, 8.0), 0.69743, 0.000392), ((7.5, 24.0), 0.12000, 0.000394), ((22.5, 8.0), 0.12035, 0.000354),
                ((7.5, -8.0), 0.18915, 0.000411), ((22.5, -24.0), 0.12671, 0.000369), ((-7.5, -24.0), 0.12058, 0.000363),
                ((-22.5, -8.0), 0.12001, 0.000356), ((-22.5, 24.0), 0.12011, 0.000350), ((-11.0, 14.0), 0.69949, 0.000406),
                ((-16.0, 18.0), 0.25440, 0.000403), ((8.0, 16.0), 0.11943, 0.000384), ((-20.0, -1.0), 0.12291, 0.000365),
                ((-22.5, -24.0), 0.12001, 0.000361), ((22.5, 24.0), 0.11985, 0.000370), ((2.0, 18.0), 0.12034, 0.000363),
                ((1.0, 15.0), 0.12153, 0.000362), ((-5.0, -15.0), 0.12221, 0.000388), ((-5.0, -12.0), 0.12176, 0.000360),
                ((-5.0, -10.0), 0.12134, 0.000370), ((9.0, 7.0), 0.12146, 0.000354), ((6.0, 7.0), 0.12062, 0.000388),
                ((4.0, 6.0), 0.12044, 0.000367), ((-29.0, 15.0), 0.12029, 0.000374), ((-25.0, 18.0), 0.11987, 0.000361),
                ((-26.0, 9.0), 0.12175, 0.000356), ((-25.0, 7.0), 0.12234, 0.000365)]
    model, first, found = read_on(recorded, 7, [((-12.0, 10.0), 8.0, 2.0, 0.7), ((14.0, -13.0), 6.0, 4.0, 0.5)])
    assert model["chosen"] == "ellipse:1" and model["weight"] >= 0.9, "the case needs one ellipse chosen"
    assert first is not None
    assert found["lumps_found"] == 2 and found["false_lumps"] == 0, found
    assert found["max_center_error_mm"] <= 0.5 and found["min_iou"] >= 0.9, found


def test_a_reading_that_surprises_the_chosen_fit_is_tried_as_one_lump_more():
    """Twenty-two readings recorded from a simulated active scan of four-lumps (seed 6): two lumps chosen at
    0.99, then a reading of 0.80 N/mm at (0, -14), where they predict tissue. Refitted from where they were,
    the two circles slid into a compromise between the old lump and the new one, and the three circles
    built on that compromise lost (50 nats below the three lumps the readings show): the free-form map was
    chosen for the next ten readings. The two circles as they were, plus a lump at the surprise, is tried."""
    from palpd.config import Settings
    from palpd.learner.planner import make_learner

    recorded = [
        ((7.5003, 8.0004), 0.188203, 0.0003782), ((22.4999, 24.0003), 0.120057, 0.0003754), ((-7.4995, 24.0004), 0.123294, 0.0003630),
        ((-22.4993, 8.0003), 0.127847, 0.0003466), ((-7.5007, -7.9996), 0.138790, 0.0003943), ((7.4995, -23.9997), 0.125945, 0.0003545),
        ((22.5008, -7.9998), 0.125018, 0.0003813), ((-22.5008, -23.9992), 0.119887, 0.0003567), ((6.0003, 6.0006), 0.128131, 0.0003872),
        ((9.0001, 9.0004), 0.406562, 0.0003802), ((22.0004, 22.0005), 0.123088, 0.0003724), ((7.9994, 11.0005), 0.349423, 0.0004101),
        ((5.9997, 14.0004), 0.153221, 0.0003811), ((4.9994, 11.0006), 0.135570, 0.0003801), ((7.9994, 16.0003), 0.221655, 0.0003973),
        ((13.0004, 12.0000), 0.599874, 0.0003883), ((9.9996, 15.0000), 0.525643, 0.0003836), ((-22.4999, 24.0003), 0.122404, 0.0003825),
        ((22.5009, -24.0000), 0.206960, 0.0003632), ((29.9996, -29.9999), 0.120092, 0.0003632), ((-12.0005, -18.0000), 0.123414, 0.0003858),
        ((0.0000, -13.9999), 0.799863, 0.0004157),
    ]
    learner = make_learner(Settings(), (60.0, 60.0), 6)
    for xy, k, sd in recorded[:-1]:
        learner.observe(xy, k, sd)
    assert learner.choice.chosen == "circles:2"
    learner.observe(*recorded[-1])
    assert learner.choice.chosen == "circles:3" and learner.choice.weight >= learner.settings.confidence
    centres = [lump.center_mm for lump in learner.lumps()]
    assert min(math.dist(c, (0.0, -14.0)) for c in centres) < 2.0, centres  # the new lump where it was felt
    assert min(math.dist(c, (15.0, 12.0)) for c in centres) < 1.0, centres  # the one mapped before, kept


def test_a_lump_whose_edge_locked_into_a_wrong_shape_is_refitted_out_of_it():
    """touching-lumps (seed 0) ended its budget on four circles, one false: the third lump's fit had locked
    into Gaussian tails (λ at its bound) and a 2.4 sharpness, 48 nats of log posterior below its true
    power-law edge, and a fourth lump made up the difference. Fresh starts (one lump more than the fit of
    two, k-means groups) did not find the way out on the scan's 36 spots; the fit itself with every lump's
    edge and tails reset does."""
    from drivers.sim.tissue import lump_profile, lump_sharpness
    from palpd.learner import evidence, hypotheses as hypotheses_module, shapes

    lumps, sharpness = [((-8.0, 0.0), 5.0), ((4.0, 0.0), 5.0), ((-1.0, 13.5), 5.0)], lump_sharpness(5.0, 2.0)
    spots = [(-7.5, -8.0), (-22.5, -24.0), (7.5, -24.0), (22.5, -8.0), (7.5, 8.0), (-7.5, 24.0), (-22.5, 8.0),
             (22.5, 24.0), (11.0, -10.0), (14.0, -1.0), (5.0, 9.0), (3.0, 9.0), (22.5, -24.0), (-22.5, 24.0),
             (-4.0, 3.0), (-14.0, 7.0), (16.0, 8.0), (4.0, -4.0), (7.0, -4.0), (-4.0, -9.0), (1.0, -6.0),
             (-12.0, -18.0), (-18.0, -8.0), (6.0, 7.0), (3.0, 7.0), (2.0, 18.0), (5.0, -2.0), (2.0, 16.0),
             (0.0, 12.0), (0.0, 10.0), (1.0, 1.0), (23.0, 1.0), (-7.2, 1.2), (-6.0, 14.0), (-11.0, 1.0), (9.0, 1.0)]
    assert len(spots) % hypotheses_module.RESTART_EVERY == 0  # a refit with fresh starts
    obs = Observations()
    for p in spots:  # as the simulator feels lumps of 0.8 N/mm 2 mm deep in 0.12 N/mm tissue
        obs.add(p, "fit", 0.12 + max(0.68 * lump_profile(math.dist(p, c), r, sharpness) for c, r in lumps), 0.0004)
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    priors = hypotheses.priors(obs)
    family = shapes.Family("circles", 3, priors.scale_mm)

    def fitted(tails_and_edges):
        lump_params = [[*c, math.log(r), tail, math.log(s), math.log(0.68 / 0.12)]
                       for (c, r), (tail, s) in zip(lumps, tails_and_edges)]
        return evidence.fit(family, obs, priors, [np.array([math.log(0.12), 0.0, 0.0, *np.ravel(lump_params)])], 0.01)

    truth = fitted([(0.0, sharpness)] * 3)
    locked = fitted([(0.0, sharpness)] * 2 + [(1.5, 2.4)])
    assert locked.log_posterior < truth.log_posterior - 20.0, "the case needs a mode the third lump is locked in"
    hypotheses.fits["circles:3"] = locked
    hypotheses.update(obs, [], math.log(0.12))
    assert hypotheses.fits["circles:3"].log_posterior >= truth.log_posterior - 1.0


def test_two_touching_lumps_read_around_but_not_between_are_read_in_the_middle_before_one_ellipse_stands():
    """Two 5 mm lumps whose edges are 2 mm apart, read around them (and inside, near either end) but not
    between: one ellipse over both explains every reading as well as two circles, and with fewer parameters
    won at 0.9999; it stopped there (a synthetic touching-lumps run: one lump of three reported, IoU 0.35).
    An ellipse is felt at its middle before it stands; the reading there is the two lumps' waist."""
    from palpd.config import LearnerSettings
    from palpd.learner import Learner
    from drivers.sim.tissue import lump_profile, lump_sharpness

    lumps, sharpness = [((-8.0, 0.0), 5.0), ((4.0, 0.0), 5.0)], lump_sharpness(5.0, 2.0)
    def k_at(p):
        return 0.12 + max(0.68 * lump_profile(math.dist(p, c), r, sharpness) for c, r in lumps)
    spots = [(7.5, -8.0), (-7.5, -24.0), (-22.5, -8.0), (-7.5, 8.0), (-22.5, 24.0), (7.5, 24.0), (22.5, 8.0),
             (22.5, -24.0), (-4.0, -9.0), (-7.0, -1.0), (-22.5, -24.0), (22.5, 24.0), (-7.0, 1.0), (-7.0, -5.0),
             (5.0, -2.0), (13.0, 3.0), (10.0, -1.0), (-13.0, 1.0)]
    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=61), 0.3, 1)
    for p in spots:
        learner.observe(p, k_at(p), 0.0004)
    assert learner.model()["chosen"] == "ellipse:1", "the case needs one ellipse chosen over both"
    middle = learner.next_probe()
    assert middle is not None and math.dist(middle, (-2.0, 0.0)) <= 1.5, middle
    learner.observe(middle, k_at(middle), 0.0004)
    assert learner.model()["chosen"] == "circles:2"


def test_one_ellipse_over_two_touching_lumps_does_not_stand_while_two_circles_explain_the_readings_as_well():
    """Seventeen readings recorded from a simulated touching-lumps scan (seed 3): one ellipse over two of the
    lumps (its middle read, inside the second) explains them to their noise, at weight 1.000. Two circles do
    too, but no start found them (k-means grouped one faint reading against the rest, and one lump plus a
    lump at the worst-explained reading slid into a compromise): the scan stopped there, one lump reported
    8.8 mm off. Circles now also start from the ellipse split along its major axis, the hypotheses are
    refitted thoroughly before a stop, and where the two circles, as good a fit, predict most unlike the
    ellipse one reading is taken: it ends on the two lumps it felt, none false (the third, 13.5 mm away
    and read only on its far tail, is the coverage trade the README measures)."""
    recorded = [((-7.5, -8.0), 0.14775), ((7.5, -24.0), 0.11977), ((22.5, -8.0), 0.12049), ((7.5, 8.0), 0.13633),
                ((22.5, 24.0), 0.11975), ((-7.5, 24.0), 0.12204), ((-22.5, 8.0), 0.12007), ((-22.5, -24.0), 0.11957),
                ((-6.0, -4.0), 0.58149), ((22.5, -24.0), 0.12048), ((-22.5, 24.0), 0.12014), ((-5.0, -2.0), 0.73011),
                ((-4.0, 5.0), 0.22917), ((3.0, -9.0), 0.13295), ((2.0, 0.0), 0.7983), ((17.0, 0.0), 0.12122),
                ((11.0, 1.0), 0.18189)]
    truth = [((-8.0, 0.0), 5.0, 2.0, 0.8), ((4.0, 0.0), 5.0, 2.0, 0.8), ((-1.0, 13.5), 5.0, 2.0, 0.8)]
    model, first, found = read_on(recorded, 3, truth)
    assert model["chosen"] == "ellipse:1" and model["weight"] >= 0.9, "the case needs one ellipse chosen"
    assert first is not None
    assert found["false_lumps"] == 0 and found["lumps_found"] >= 2, found
    felt = [lump for lump in found["per_lump"][:2]]
    assert all(l["found"] and l["center_error_mm"] <= 0.5 and l["iou"] >= 0.9 for l in felt), felt


def test_one_ellipse_over_a_lump_and_a_neighbours_edge_is_read_where_two_circles_disagree():
    """Fifteen readings recorded from a simulated scan of a random scene (random-6-6: an 11.3 mm lump 6 mm
    deep and a 4.5 mm one beside it, read once on its edge): one ellipse over both at weight 0.95, two
    circles as good a fit at a few millionths. Stopped there, the small lump was never reported. Where the
    two predict so differently that one reading could overturn the odds, that reading is taken first: it
    ends on both lumps."""
    recorded = [((-7.5, -8.0), 0.55930), ((-22.5, -24.0), 0.081766), ((7.5, -24.0), 0.32373), ((22.5, -8.0), 0.080828),
                ((7.5, 8.0), 0.10656), ((-7.5, 24.0), 0.082930), ((-22.5, 8.0), 0.10991), ((22.5, 24.0), 0.080335),
                ((-6.0, -8.0), 0.55484), ((-7.0, -2.0), 0.57959), ((-14.0, -7.0), 0.50468), ((-10.0, 4.0), 0.57438),
                ((-17.0, -16.0), 0.10821), ((22.5, -24.0), 0.080050), ((-22.5, 24.0), 0.081026)]
    truth = [((-7.723, -1.083), 11.30, 6.069, 0.5797), ((8.224, -19.364), 4.518, 1.786, 0.6320)]
    model, first, found = read_on(recorded, 0, truth, tissue=0.079926)
    assert model["chosen"] == "ellipse:1" and model["weight"] >= 0.9, "the case needs one ellipse chosen"
    assert first is not None
    assert found["lumps_found"] == 2 and found["false_lumps"] == 0, found
    assert found["max_center_error_mm"] <= 0.5 and found["min_iou"] >= 0.9, found


def test_a_satellite_hole_is_the_widest_gap_beside_the_lumps_and_none_once_read_closely():
    """coverage.satellite_holes' hole: cells outside the lumps within 3 radii of one, farther than reach x radius from
    every palpation; the farthest of them first, nothing inside a lump or far from all of them."""
    from palpd.learner import coverage

    gx, gy = np.meshgrid(np.arange(-30.0, 31.0, 2.0), np.arange(-30.0, 31.0, 2.0))
    discs = [(np.array([-8.0, 0.0]), 5.0), (np.array([4.0, 0.0]), 5.0)]

    def read(points):
        readings = coverage.Readings(np.column_stack([gx.ravel(), gy.ravel()]), 1.5)
        for xy in points:
            readings.add(xy)
        return readings

    centres_and_edges = np.array([(-8, 0), (4, 0), (-14, 0), (10, 0), (-8, 6), (-8, -6), (4, 6), (4, -6), (-2, 0)], float)
    hole = coverage.satellite_holes(discs, read(centres_and_edges), 1.5, 1.5)[0]
    assert hole is not None
    assert min(np.hypot(*(centres_and_edges - hole).T)) > 7.5  # a spot no reading is within 1.5 R of
    assert min(math.dist(hole, c) for c, _ in discs) <= 15.0  # beside a lump (within 3 R), not across the tissue
    assert all(math.dist(hole, c) > r for c, r in discs)  # never inside a found lump
    lattice = [(x, y) for x in np.arange(-30.0, 31.0, 5.0) for y in np.arange(-30.0, 31.0, 5.0)]
    assert coverage.satellite_holes(discs, read(lattice), 1.5, 1.5)[0] is None  # read 5 mm apart: no hole of 7.5 mm
    assert coverage.satellite_holes(discs, read(centres_and_edges), 4.0, 1.5)[0] is None  # a reach of 4 R: none
    tried = read(centres_and_edges)
    tried.probed(hole)  # a palpation there that gave no reading
    assert tried.distance_mm.max() == read(centres_and_edges).distance_mm.max()  # it is no reading...
    again = coverage.satellite_holes(discs, tried, 1.5, 1.5)[0]
    assert again is None or math.dist(again, hole) > 7.5  # ...but that hole was looked at


@given(points=st.lists(st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0)), min_size=1, max_size=30),
       more=st.lists(st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0)), min_size=1, max_size=10),
       reach=st.sampled_from([1.0, 1.5, 3.0]))
@hsettings(max_examples=40, deadline=None)
def test_the_share_of_the_cells_beside_the_lumps_in_a_hole_is_what_a_count_of_them_says_and_readings_only_shrink_it(
        points, more, reach):
    """coverage.satellite_holes' share, which the stop rule turns into the chance that no lump as small as the
    smallest found lies unfelt beside them (decision._satellites_in_doubt): the share of the cells outside
    the lumps within 3 radii of one that lie farther than reach x the smallest radius from every probe, counted
    cell by cell; 0 exactly when there is no satellite hole; never larger after more palpations."""
    from palpd.learner import coverage

    gx, gy = np.meshgrid(np.arange(-30.0, 31.0, 2.0), np.arange(-30.0, 31.0, 2.0))
    cells = np.column_stack([gx.ravel(), gy.ravel()])
    discs = [(np.array([-8.0, 0.0]), 5.0), (np.array([6.0, 3.0]), 7.0)]
    readings = coverage.Readings(cells, 1.5)
    for xy in points:
        readings.add(xy)
    share = coverage.satellite_holes(discs, readings, reach, 1.5)[1]
    d = [np.hypot(*(cells - c).T) for c, _ in discs]
    beside = np.any([di <= 3.0 * r for di, (_, r) in zip(d, discs)], axis=0) & np.all([di > r for di, (_, r) in zip(d, discs)], axis=0)
    nearest = np.min([np.hypot(*(cells - np.asarray(xy)).T) for xy in points], axis=0)
    assert share == pytest.approx(np.count_nonzero(beside & (nearest > reach * 5.0)) / np.count_nonzero(beside))
    assert (share == 0.0) == (coverage.satellite_holes(discs, readings, reach, 1.5)[0] is None)
    for xy in more:
        readings.add(xy)
    assert coverage.satellite_holes(discs, readings, reach, 1.5)[1] <= share


def test_a_satellite_hole_beside_a_large_lump_is_one_a_lump_as_small_as_the_smallest_found_could_lie_in():
    """Beside a 9.5 mm lump, a hole 12 mm from every probe: wider than 1.5 x the 6 mm lump found elsewhere,
    narrower than 1.5 x its own neighbour. A lump as small as the smallest found could lie there (random-2-12: a
    6.8 mm lump 6.9x as stiff, unread 12.4 mm from every probe beside a 9.6 mm one), so it is a hole."""
    from palpd.learner import coverage

    gx, gy = np.meshgrid(np.arange(-40.0, 41.0, 1.0), np.arange(-40.0, 41.0, 1.0))
    large, small = (np.array([0.0, 0.0]), 9.5), (np.array([0.0, 28.0]), 6.0)
    readings = coverage.Readings(np.column_stack([gx.ravel(), gy.ravel()]), 1.5)
    probes = [(x, y) for x in (-20.0, 0.0, 20.0) for y in (-10.0, 0.0, 10.0, 20.0, 28.0, 36.0)] + \
             [(-12.0, -22.0), (12.0, -22.0), (0.0, -34.0), (-30.0, -30.0), (30.0, -30.0)]
    for xy in probes:
        readings.add(xy)
    hole = coverage.satellite_holes([large, small], readings, 1.5, 1.5)[0]
    assert hole is not None and hole[1] < -10.0  # below the large lump, where no probe is within 9 mm
    assert 9.0 < min(math.dist(hole, p) for p in probes) < 14.25  # a hole only a lump as small as 6 mm is held to
    assert coverage.satellite_holes([large], readings, 1.5, 1.5)[0] is None  # alone, the large lump holds it to 14.25


def test_a_satellite_hole_probed_without_a_reading_is_not_asked_for_again():
    """A palpation at a hole that gave no stiffness (no contact, a rejected trace) counts as looked at: the same
    spot would give none again, and asking for it again and again spent the budget there."""
    from palpd.config import LearnerSettings
    from palpd.learner import Learner

    learner = Learner((60.0, 60.0), LearnerSettings(grid_points=61), 0.3, 0)
    k_at = lambda xy: 0.12 + 0.6 * (math.dist(xy, (-8.0, 0.0)) < 5.0 or math.dist(xy, (4.0, 0.0)) < 5.0)
    for xy in [(-8, 0), (4, 0), (-14, 0), (10, 0), (-8, 6), (-8, -6), (4, 6), (4, -6), (-2, 0), (-11, 3), (7, -3),
               (-5, -3), (1, 3), (-22.5, -24.0), (22.5, 24.0), (-22.5, 24.0), (22.5, -24.0)]:
        learner.observe(xy, k_at(xy) * 1.001, 0.0004)
    hole = learner._satellite_hole()
    assert hole is not None and learner.model()["chosen"] == "circles:2"
    learner.observe(tuple(hole), None, outcome="rejected")
    again = learner._satellite_hole()
    assert again is None or math.dist(again, hole) > 7.5


def test_a_gradual_lump_is_read_at_its_top_before_its_half_height_radius_stands():
    """Fourteen readings recorded from a simulated active scan of gradual-lump (seed 2: a Gaussian rise, sd
    7 mm, its half-height radius 8.25 mm), the nearest 4 mm from its centre (0.47 of the radius fitted),
    where it is at 85 % of its height. The family's profile drew the top from the readings farther out, a
    plateau a little lower than it is, and the half-height with it: the scan stopped there, the radius
    0.41 mm large at a stated sd of 0.2 mm. The top is read first (the readings leave the edge's sharpness
    and tail loose enough that 90 % of the height may lie nearer than 0.47), and the radius lands within
    0.1 mm."""
    from palpd.config import Settings
    from palpd.learner.planner import make_learner

    recorded = [((7.5, -8), 0.13581, 0.000388), ((22.5, -24), 0.11961, 0.000377), ((-7.5, -24), 0.12044, 0.000356),
                ((-22.5, -8), 0.12165, 0.000364), ((-7.5, 8), 0.49222, 0.000399), ((7.5, 24), 0.12418, 0.000374),
                ((22.5, 8), 0.11948, 0.000406), ((-22.5, 24), 0.11986, 0.000378), ((2, 14), 0.27900, 0.000380),
                ((-22.5, -24), 0.12021, 0.000374), ((22.5, 24), 0.12046, 0.000373), ((-2, -3), 0.30459, 0.000366),
                ((5, 4), 0.30506, 0.000398), ((-11, 1), 0.32721, 0.000415)]
    centre, sd_mm, tissue, top = (-4.0, 6.0), 7.0, 0.12, 0.56

    def k_at(xy):
        return tissue + (top - tissue) * math.exp(-math.dist(xy, centre) ** 2 / (2.0 * sd_mm**2))

    learner = make_learner(Settings(), (60.0, 60.0), 2)
    for xy, k, sd in recorded:
        learner.observe(xy, k, sd)
    assert learner.model()["chosen"] == "circles:1", "the case needs the one circle chosen"
    first = learner.next_probe()
    assert first is not None and math.dist(first, centre) <= 1.5, first
    while (xy := learner.next_probe()) is not None:
        learner.observe(xy, k_at(xy), 0.001 * k_at(xy))
    (lump,) = learner.lumps()
    half_height_radius = sd_mm * math.sqrt(2.0 * math.log(2.0))
    assert abs(lump.radius_mm - half_height_radius) <= 0.1 and math.dist(lump.center_mm, centre) <= 0.1, lump
    assert learner.points <= 20


def test_a_soft_reading_read_roughly_is_tried_as_a_soft_region_beside_a_lump_read_sharply():
    """A reading of soft tissue is a small force against the sensor's noise: far below the fits in stiffness,
    but fewer sds below them than a stiff reading beside it is above. soft-3-0 (a cyst 5x softer and a lump
    4.4x stiffer on 80 mm tissue, 0.06 N of noise): each read once, the soft region was never tried (the
    lump's reading missed by 62 sds at the floor, the cyst's by 34), every count of lumps misfit by 20-24x the
    floor, and the scan ended `undetermined` at 40. Which to try is what lies further in stiffness."""
    cyst, lump = np.array([-15.0, -10.0]), np.array([12.0, 15.0])
    def k_at(p):
        soft = 1.0 - 0.8 / (1.0 + (math.dist(p, cyst) / 10.0) ** 12)
        return 0.12 * soft * (1.0 + 1.5 / (1.0 + (math.dist(p, lump) / 5.0) ** 6))
    obs = Observations()
    for p in lattice(9.0) + [tuple(cyst + (1.0, 2.0)), tuple(lump + (2.0, -1.0))]:
        k = k_at(p)
        obs.add(p, "fit", k, k * (0.04 if k < 0.06 else 0.005))  # soft tissue read roughly, the rest sharply
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    hypotheses.update(obs, [], math.log(0.12))
    assert any("+soft" in name for name in hypotheses.fits), list(hypotheses.fits)
    choice = hypotheses.choice(None, obs)
    assert choice.chosen == "circles:1+soft:1", choice


def test_the_count_s_posterior_gathers_every_hypothesis_that_claims_it():
    from palpd.learner.hypotheses import Choice, lumps_claimed

    weights = {"circles:1": 0.56, "ellipse:1": 0.38, "circles:2": 0.04, "none+soft:1": 0.01, "free-form": 0.01}
    choice = Choice("circles:1", 0.56, "ellipse:1", weights,
                    {lumps_claimed(m): 0.0 for m in weights})
    for m, w in weights.items():
        choice.counts[lumps_claimed(m)] += w
    assert choice.counts == pytest.approx({1: 0.94, 2: 0.04, 0: 0.01, "free-form": 0.01})
    assert choice.count_weight == pytest.approx(0.94)  # one lump, surely; its outline less so (0.56)
    assert [choice.count_of(m) for m in ("none", "circles:3+soft:1", None)] == [0, 3, None]


def test_the_expected_boundary_error_is_the_uncertain_area_over_the_boundary_s_length():
    from palpd.learner.decision import _perimeter_mm

    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    assert _perimeter_mm(square) == pytest.approx(8.0)
    assert _perimeter_mm(square[:1]) == 0.0


@hsettings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(-3, 3), st.integers(-3, 3)), min_size=1, max_size=12), st.integers(1, 5))
@example([(0, 0)] * 5 + [(1, 1)], 3)  # fewer distinct spots than groups: k-means++ divided by zero
def test_grouping_readings_into_starts_warns_nothing_whatever_the_spots(spots, k):
    """scipy's k-means warned on stderr of an empty group and, with spots repeated, of a division by zero: lines
    a user saw in `palpd bench calibration`'s output and could do nothing about."""
    from palpd.learner.hypotheses import _kmeans

    points = np.asarray(spots, dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        labels = _kmeans(points, k)
    assert len(labels) == len(points) and 0 <= labels.min() and labels.max() < max(k, 1)
    same_spot = (points[:, None] == points[None]).all(axis=2)
    assert np.all(labels[:, None] == labels[None]) or not same_spot.all()  # one spot: one group


@pytest.mark.parametrize("regions, counted_with_one_lump", [(1, True), (2, False)])
def test_the_free_form_map_weighs_for_the_count_of_its_regions(regions, counted_with_one_lump):
    """The posterior of the count sums every hypothesis that claims as many lumps, the free-form map by its
    regions: a band across the tissue, read as one ellipse and as the map's one region by turns, had each
    reading "change the count" and ended `undetermined` at the budget with its boundary at IoU 0.96."""
    centre, radius = np.array([3.0, -2.0]), 8.0
    lump = lambda p: 0.12 + 0.4 / (1.0 + (math.dist(p, centre) / radius) ** 8)  # noqa: E731
    obs = readings(lump, lattice() + [tuple(centre), tuple(centre + (radius, 0.0))])
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    hypotheses.update(obs, [], math.log(0.12))
    best = max(fit.log_evidence for fit in hypotheses.fits.values() if fit.supported)
    choice = hypotheses.choice(best, obs, regions)  # the map as likely as the best parametric hypothesis
    one_lump = sum(share for name, share in choice.shares.items() if name != "free-form" and choice.count_of(name) == 1)
    assert choice.count_of("free-form") == regions and 0.3 < choice.shares["free-form"] < 0.7, choice
    assert choice.counts[1] == pytest.approx(one_lump + (choice.shares["free-form"] if counted_with_one_lump else 0.0))
    assert sum(choice.counts.values()) == pytest.approx(1.0)


def _bench_learner(tolerance_mm: float):
    """A learner fed the points of `palpd bench learner` (points it did not choose), on a coarse grid."""
    from palpd.commands.bench_learner import _field
    from palpd.config import LearnerSettings
    from palpd.learner.model import Learner

    settings = LearnerSettings(grid_points=41, initial_points=0, max_palpations=10**4, tolerance_mm=tolerance_mm)
    return Learner((60.0, 60.0), settings, 0.3), _field(70)


def test_each_reading_of_the_default_budget_refits_every_hypothesis_and_past_it_an_update_refits_one(monkeypatch):
    """An update refits every hypothesis while a default scan runs (40 readings), so no scan within the
    default budget is changed by the bound; past it, an update assimilates each reading and refits one
    hypothesis now and then from a few starts and steps: the bench's largest update, at its 59th reading
    (the soft-region fits new there, one of them 28 ms), was 61 ms here, over the issue's 50."""
    from palpd.commands import bench_learner
    from palpd.config import LearnerSettings
    from palpd.learner import evidence, hypotheses, model

    learner, (xy, k) = _bench_learner(1e-6)  # a tolerance never met: every update is an update of a scan going on
    fits, fit = [], evidence.fit  # each refit of an update: (hypothesis, starts, steps)
    monkeypatch.setattr(evidence, "fit", lambda family, obs, priors, starts, *a, **kw:
                        fits.append((family.name, len(starts), a[2])) or fit(family, obs, priors, starts, *a, **kw))
    per_update = []
    for i in range(len(xy)):
        fits.clear()
        learner.observe(xy[i], float(k[i]), 0.003)
        per_update.append((list(fits), set(learner.hypotheses.fits)))
    budget = LearnerSettings().max_palpations
    assert model.FULL_UPDATE_POINTS == budget == bench_learner.FULL_UPDATE_POINTS
    for refits, held in per_update[:budget]:  # every hypothesis held, refitted, each start to 60 steps
        assert {name for name, _, _ in refits} == held and all(steps == 60 for _, _, steps in refits), refits
    light = [refits for refits, _ in per_update[budget:]]
    assert all(len(refits) <= 1 for refits in light) and sum(map(len, light)) >= 3, light
    assert all(starts <= model.LIGHT_STARTS + 1 and steps == hypotheses.LIGHT_ITERATIONS  # (+1: `none`'s level)
               for refits in light for _, starts, steps in refits), light


def test_a_stop_past_the_default_budget_is_still_checked_by_a_thorough_refit(monkeypatch):
    """The refit from fresh starts, each run to its end, that a stop waits for (model.py: a warm fit in a poor
    mode lost two touching lumps to one ellipse) goes on past the default budget, to THOROUGH_STOP_POINTS
    readings: without it a rounded rectangle read to a budget of 80 stopped at 47, its boundary stated
    0.25 mm and 1.4 mm off. Beyond, readings fed on past a stop (a raster scan) would each pay one."""
    from palpd.learner import model

    learner, (xy, k) = _bench_learner(2.0)
    calls, weigh = [], model.Learner._weigh  # the readings at which a thorough refit was made
    monkeypatch.setattr(model.Learner, "_weigh",
                        lambda self, thorough=False: (thorough and calls.append(self.obs.n)) or weigh(self, thorough))
    for i in range(len(xy)):
        learner.observe(xy[i], float(k[i]), 0.003)
    assert learner.decided()
    assert max(calls) == model.THOROUGH_STOP_POINTS and min(calls) <= model.FULL_UPDATE_POINTS + 1, calls
