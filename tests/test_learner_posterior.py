"""The reported uncertainty is the posterior's, not only its linearisation's (learner/posterior.py).

A deep lump felt through 25 mm of tissue has the heaviest tails the lump family
allows (edge sharpness at its floor, power-law tails): to first order the
background, contrast, tail shape and radius trade off, so the Laplace radius sd
is far wider than what the readings allow. The check must bring it to what the
profile likelihood says, and leave a well-behaved lump's covariance as it was.
"""
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.stats import qmc

from palpd.learner import describe, evidence, posterior
from palpd.learner.hypotheses import Hypotheses
from palpd.learner.observations import Observations
from palpd.learner.solver import levenberg_marquardt

CENTRE, RADIUS_MM, TISSUE, LUMP = (-6.0, 5.0), 9.0, 0.12, 0.8


def readings(sharpness: float, count: int = 40, seed: int = 0) -> Observations:
    rng = np.random.default_rng(seed)
    xy = qmc.scale(qmc.Halton(d=2, scramble=True, seed=seed).random(count), [-30, -30], [30, 30])
    rho = np.hypot(*(xy - CENTRE).T) / RADIUS_MM
    k = TISSUE + (LUMP - TISSUE) / (1.0 + rho**sharpness)
    obs = Observations()
    for p, value in zip(xy, k * np.exp(rng.normal(0.0, 0.005, count))):
        obs.add(p, "fit", float(value), 0.001 * float(value))
    return obs


def circle(obs: Observations):
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    hypotheses.update(obs, [], float(np.median(obs.y)))
    return hypotheses.fits["circles:1"], hypotheses.priors(obs)


def radius_sd_mm(fit) -> float:
    (lump,) = describe.lumps_of(fit)
    return lump.radius_sd_mm


def profile_radius_sd_mm(fit, obs, priors) -> float:
    """Half the width of the radius interval where −log posterior (the rest refitted, the tails on their
    branch: the other is another mode, fitted and weighed apart) rises by ½."""
    lo, hi = priors.branch_bounds(fit.family, fit.theta)
    def least(theta, low, high) -> float:
        return levenberg_marquardt(lambda t: evidence.stacked(fit.family, t, obs, priors, fit.noise_sd),
                                   theta, low, high, 1e-6, 200)[1]
    base = least(fit.theta, lo, hi)
    def rise(delta_mm: float) -> float:
        low, high, start = lo.copy(), hi.copy(), fit.theta.copy()
        low[5] = high[5] = start[5] = math.log(math.exp(fit.theta[5]) + delta_mm)
        return least(start, low, high) - base
    steps = np.array([0.01, 0.03, 0.1, 0.3, 1.0, 2.0])
    widths = [np.interp(0.5, [0.0, *[rise(sign * s) for s in steps]], [0.0, *steps]) for sign in (1.0, -1.0)]
    return 0.5 * sum(widths)


@pytest.mark.parametrize("sharpness, count", [(2.0, 40), (4.0, 40), (6.0, 40), (12.0, 60)])
def test_the_reported_radius_sd_is_the_posteriors(sharpness, count):
    """From a deep lump's wide edge (sharpness 2, the family's floor) to a sharp one: the checked
    radius sd is within a factor of two of the profile likelihood's, whatever the linearisation said."""
    obs = readings(sharpness, count)
    fit, priors = circle(obs)
    assert math.exp(fit.theta[5]) == pytest.approx(RADIUS_MM, abs=0.3)
    checked = replace(fit, cov=posterior.checked_cov(fit, obs, priors))
    profile = profile_radius_sd_mm(fit, obs, priors)
    assert profile / 2.0 <= radius_sd_mm(checked) <= 2.0 * profile
    assert describe.lumps_of(checked)[0].center_sd_mm == pytest.approx(describe.lumps_of(fit)[0].center_sd_mm, rel=0.5)
    assert np.all(np.isfinite(checked.cov)) and np.allclose(checked.cov, checked.cov.T)


def test_a_centres_sd_is_its_rms_distance_from_the_truth():
    """What `--tolerance-mm` bounds is how far off a centre may be: the distance, both axes (per axis, a scan
    stopped on a lump at 0.43 mm that was 0.56 mm off it: touching-lumps seed 2)."""
    fit, _ = circle(readings(4.0, 40))
    centre = slice(fit.family.lump_slice(0).start, fit.family.lump_slice(0).start + 2)
    draws = np.random.default_rng(0).multivariate_normal(fit.theta, fit.cov, 20000)
    rms_mm = math.sqrt(np.mean(np.sum((draws[:, centre] - fit.theta[centre]) ** 2, axis=1)))
    assert describe.lumps_of(fit)[0].center_sd_mm == pytest.approx(rms_mm, rel=0.03)


def test_where_the_linearisation_is_wrong_it_is_corrected():
    """The deep lump: the Laplace radius sd is more than twice the posterior's; checked, it is not."""
    obs = readings(2.0)
    fit, priors = circle(obs)
    profile = profile_radius_sd_mm(fit, obs, priors)
    assert radius_sd_mm(fit) > 2.0 * profile
    assert radius_sd_mm(replace(fit, cov=posterior.checked_cov(fit, obs, priors))) < 1.2 * profile


def test_a_volume_direction_moves_each_edge_parameter_alone_into_the_box():
    """Several parameters on their priors' edge (power-law tails at 0): a direction mixing them moves one of
    them out of the box whichever way it goes, and would be measured as having no room at all."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    cov = a @ a.T + 0.1 * np.eye(6)
    theta = np.array([0.3, 0.0, -0.2, 0.0, 0.5, 0.0])  # parameters 1, 3 and 5 sit on their lower bound
    lo, hi = np.array([-1.0, 0.0, -1.0, 0.0, -1.0, 0.0]), np.full(6, 1.0)
    mixed = posterior._directions(cov, theta, lo, hi)
    assert any(posterior._room(theta, d, lo, hi) == 0 and posterior._room(theta, -d, lo, hi) == 0 for d in mixed.T)
    alone = posterior._directions(cov, theta, lo, hi, each_edge_alone=True)
    precision = np.linalg.inv(cov)
    for d in alone.T:
        assert max(posterior._room(theta, d, lo, hi), posterior._room(theta, -d, lo, hi)) > 0
        assert float(d @ precision @ d) == pytest.approx(1.0, rel=1e-6)  # still a 1-sd step by the curvature


def test_lumps_whose_tails_sit_on_the_prior_edge_keep_their_evidence():
    """Three sharp lumps, two or three of them fitted with the power-law tail at its prior's edge: the volume
    check may narrow each direction, but not dock the fit tens of nats for edges it could not step along
    (it did: -60 nats, and four lumps fitted right lost to `none`)."""
    lumps = [((-15.0, 12.0), 6.0), ((14.0, 10.0), 7.0), ((2.0, -16.0), 6.5)]
    for seed in (2, 3):
        rng = np.random.default_rng(seed)
        xy = qmc.scale(qmc.Halton(d=2, scramble=True, seed=seed).random(45), [-30, -30], [30, 30])
        k = TISSUE + sum(0.6 / (1.0 + (np.hypot(*(xy - c).T) / r) ** 8) for c, r in lumps)
        obs = Observations()
        for p, value in zip(xy, k * np.exp(rng.normal(0.0, 0.005, len(xy)))):
            obs.add(p, "fit", float(value), 0.001 * float(value))
        hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
        hypotheses.update(obs, [], float(np.median(obs.y)))
        fit, priors = hypotheses.fits["circles:3"], hypotheses.priors(obs)
        lo, hi = priors.branch_bounds(fit.family, fit.theta)  # Hill tails: the edge of their branch
        on_edge = np.isfinite(hi - lo) & (np.minimum(fit.theta - lo, hi - fit.theta) <= 1e-6)
        assert on_edge.sum() >= 2, f"seed {seed}: the case needs several parameters on an edge"
        ratio = posterior.log_volume_ratio(fit, obs, priors)
        assert ratio >= -0.5 * fit.family.size, f"seed {seed}: volume check {ratio:.1f} nats"


def test_a_radius_the_readings_leave_on_a_ridge_is_reported_as_unsure_as_the_ridge_is_long():
    """A lump read on a 6 mm lattice whose core readings all hit the force limit (each only 'at least
    0.6 N/mm'): a broad lump and a narrower, much stiffer one with a softer edge explain the edge readings
    alike, so the radius lies on a ridge of the posterior. The fit's starts end on both: 6.1 mm (chosen)
    and 9.0 mm (the truth), as high to ½ nat. The Laplace covariance and its straight-line check said
    6.07 ± 0.29 mm, 10 sd from the truth; the spread of the modes as likely must be in the reported sd."""
    from drivers.sim.tissue import lump_profile, lump_sharpness

    centre, radius = (5.0, -3.0), 9.0
    obs = Observations()
    axis = np.arange(-27.0, 27.1, 6.0)
    for p in [(x, y) for x in axis for y in axis]:  # as the simulator feels a lump 2 mm deep
        k = TISSUE + (0.8 - TISSUE) * lump_profile(math.dist(p, centre), radius, lump_sharpness(radius, 2.0))
        if k >= 0.6:
            obs.add(p, "too_stiff", 0.6, 0.0)
        else:
            obs.add(p, "fit", k, 0.0004)
    hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
    hypotheses.update(obs, [], math.log(TISSUE))
    fit = hypotheses.checked("circles:1", obs)
    assert fit.alternatives, "the case needs modes as likely as the chosen one"
    (lump,) = describe.lumps_of(fit)
    for other in fit.alternatives:
        assert abs(math.exp(other[5]) - lump.radius_mm) <= 1.5 * lump.radius_sd_mm
    assert abs(lump.radius_mm - radius) <= 2.0 * lump.radius_sd_mm, (lump.radius_mm, lump.radius_sd_mm)


def test_a_radius_on_a_ridge_no_start_found_is_reported_as_unsure_as_its_profile_is_flat():
    """Nineteen readings recorded from a simulated active scan of a 200 N/mm lump of 8 mm in 0.5 N/mm tissue
    (palpation.too_stiff = "bound"): four bounds ("at least 41-55 N/mm") inside, exact readings on its far
    tails outside, none across its edge. Radius, contrast and edge trade along a ridge on which 3.3 and 8 mm
    fit alike, but the fit's starts all ended near 3.3 mm, and the straight-line check of its covariance
    said 3.30 ± 0.23 mm: the scan stopped there, 4.5 mm off. Traced along the radius's profile, the ridge
    is in the reported sd, and the scan reads on."""
    from palpd.config import Settings
    from palpd.learner.planner import make_learner

    recorded = [
        ((-7.501, -8.0), 0.50286, 0.000404), ((-22.501, -23.999), 0.4999, 0.0004), ((7.499, -24.0), 0.49967, 0.000407),
        ((22.501, -8.0), 0.50076, 0.000405), ((7.5, 8.0), 0.5456, 0.000398), ((-7.5, 24.0), 0.50257, 0.000384),
        ((-22.499, 8.0), 0.50163, 0.000414), ((22.5, 24.0), 0.50005, 0.00039), ((9.999, 10.0), 0.50221, 0.000395),
        ((5.999, 5.0), 0.68743, 0.000439), ((5.0, 12.0), 0.95049, 0.000492), ((-3.001, 11.997), None, 40.68261),
        ((-2.999, 20.0), 0.68606, 0.000425), ((-9.0, 20.0), 0.68582, 0.00045), ((22.501, -24.0), 0.50035, 0.0004),
        ((-22.5, 24.0), 0.50021, 0.000415), ((-6.0, 7.997), None, 50.54457), ((-4.001, 4.995), None, 55.21839),
        ((-8.0, 10.996), None, 49.00562)]
    learner = make_learner(Settings(), (60.0, 60.0), 0)
    for xy, k, sd_or_bound in recorded:
        if k is None:
            learner.observe(xy, None, outcome="too_stiff", bound_n_per_mm=sd_or_bound)
        else:
            learner.observe(xy, k, sd_or_bound)
    (lump,) = learner.lumps()
    assert abs(lump.radius_mm - 8.0) <= 3.0 * lump.radius_sd_mm, (lump.radius_mm, lump.radius_sd_mm)
    assert not learner.decided() and learner.next_probe() is not None


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1e5, 1e5), min_size=1, max_size=8), st.floats(0.0, 1e4))
def test_the_shares_among_hypotheses_stay_a_distribution_however_far_apart_their_evidences(log_z, shift):
    """Thousands of nats apart (a sliding raster's ~1300 readings) the shares of the hypotheses whose lumps are
    apart had been taken from weights over every hypothesis, and all underflowed to 0 behind lumps laid over
    one another: 0 / 0 ended the scan with a traceback. From the likeliest of them, they never can."""
    from palpd.learner.hypotheses import shares_among

    evidences = {f"h{i}": v for i, v in enumerate(log_z)}
    shares = shares_among(evidences)
    assert all(math.isfinite(v) and 0.0 <= v <= 1.0 for v in shares.values())
    assert math.fsum(shares.values()) == pytest.approx(1.0, abs=1e-12)
    best = max(evidences, key=evidences.get)
    assert shares[best] >= 1.0 / len(evidences) - 1e-12
    shifted = shares_among({m: v - shift for m, v in evidences.items()})  # only differences count
    assert all(shifted[m] == pytest.approx(shares[m], abs=1e-9) for m in evidences)
    for m, v in evidences.items():  # each against the likeliest, as their evidences say where that is representable
        if evidences[best] - v < 700.0:
            assert shares[m] / shares[best] == pytest.approx(math.exp(v - evidences[best]), rel=1e-9)
