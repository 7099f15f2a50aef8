import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from drivers.sim.scene import Scene
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.errors import ConfigError
from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.scan import palpate
from palpd.stiffness import REASONS, FitRejected, fit_stiffness
from palpd.stiffness.batch import fit_batch, linear_batch
from palpd.control.palpation import PalpationRecord
from palpd.stiffness.palpation import before_the_stop, depth_rate_mm_s, fit_palpation

DEPTH = np.linspace(0.0, 4.0, 400)


def tared_palpation(scene, settings, xy=(5.0, -5.0)):
    bench = open_simulated_bench(settings, scene)
    bench.servo.start()
    above = (xy[0], xy[1], settings.palpation.clearance_mm)
    bench.servo.run(MoveTo(above, 80.0, 2000.0))
    tare = HoldAndCollect(200, where=above)
    bench.servo.run(tare)
    bench.servo.forces.tare(tare.samples)
    return palpate(bench, settings, xy)


@pytest.mark.parametrize("k, n", [(0.12, 1.0), (0.6, 1.0), (0.12, 1.5), (0.3, 2.0)])
def test_simulated_palpation_recovers_the_scene_k_and_n_within_5_percent(k, n):
    scene = Scene(name="hc", tissue={"stiffness_n_per_mm": k, "exponent": n}, sensor={"tilt": True})
    # k and n trade off against each other over a short, noisy curve: a deep, slow press makes both identifiable.
    settings = Settings().updated(stiffness={"model": "power"},  # Hunt–Crossley without damping: constant speed
                                  palpation={"depth_mm": 8.0, "speed_mm_s": 5.0, "max_force_n": 5.0})
    probe = tared_palpation(scene, settings)
    params = probe.fit.chosen.params
    assert params["k_n_per_mm_n"] == pytest.approx(k, rel=0.05)
    assert params["n"] == pytest.approx(n, rel=0.05)
    reference = k * n * 2.0 ** (n - 1)  # dF/dx at the 2 mm reference indentation
    assert probe.stiffness_n_per_mm == pytest.approx(reference, rel=0.05)


@pytest.mark.parametrize("model", ["hunt-crossley", "kelvin-voigt"])
def test_a_damping_model_at_one_constant_speed_is_refused_with_what_to_set(model):
    with pytest.raises(ConfigError, match=r"not identifiable at one constant indentation speed.*speed_profile"):
        Settings().updated(stiffness={"model": model})
    Settings().updated(stiffness={"model": model}, palpation={"speed_profile": "varying"})


def test_simulated_palpation_of_damped_tissue_recovers_k_n_and_b_within_their_uncertainty():
    k, n, b = 0.2, 1.3, 0.015  # damping: b·xⁿ·ẋ is about half of k·xⁿ at the 10 mm/s indentation
    scene = Scene(name="damped", tissue={"stiffness_n_per_mm": k, "exponent": n, "damping_n_s_per_mm": b},
                  sensor={"tilt": True})
    # the varying speed separates b from k: the press runs at 0.2-1.8 x the speed
    settings = Settings().updated(stiffness={"model": "hunt-crossley"}, palpation={"speed_profile": "varying"})
    probe = tared_palpation(scene, settings)
    params, se = probe.fit.chosen.params, probe.fit.chosen.se
    # k and n trade off over one press (k's se is ~6 %): each is right within its own stated uncertainty
    for name, truth in (("k_n_per_mm_n", k), ("n", n), ("b_n_s_per_mm_n1", b)):
        assert abs(params[name] - truth) <= 2.5 * se[name] + 0.01 * truth, (name, params[name], se[name])
        assert se[name] <= 0.15 * truth  # the fit's residuals run together a little (serial correlation)
    assert probe.stiffness_n_per_mm == pytest.approx(k * n * 2.0 ** (n - 1), rel=0.05)  # dF/dx at 2 mm


def test_varying_speed_profile_presses_the_same_depths_slowly_and_quickly():
    scene = Scene(name="lin", tissue={"stiffness_n_per_mm": 0.12})
    probe = tared_palpation(scene, Settings().updated(palpation={"speed_profile": "varying"}))
    rate = depth_rate_mm_s(probe.record.depth_mm, Settings().servo.rate_hz)[20:-20]
    assert rate.min() < 0.5 * 10.0 and rate.max() > 1.4 * 10.0  # swings around the 10 mm/s default
    assert probe.stiffness_n_per_mm == pytest.approx(0.12, rel=0.03)


def test_selection_keeps_a_linear_tissue_linear_and_reports_k():
    probe = tared_palpation(Scene(name="lin", tissue={"stiffness_n_per_mm": 0.12}), Settings())
    assert probe.fit.model in ("linear", "linear-offset")  # no damping term bought at one constant speed
    assert probe.stiffness_n_per_mm == pytest.approx(0.12, rel=0.03)
    assert 0 < probe.fit.stiffness_se_n_per_mm < 0.01 * 0.12
    assert probe.as_dict()["stiffness_model"] == probe.fit.model


def test_selection_picks_a_curved_model_for_a_curved_trace():
    rng = np.random.default_rng(1)
    result = fit_stiffness(DEPTH, 0.2 * (DEPTH + 0.3) ** 1.5 + rng.normal(0, 0.01, DEPTH.size))
    assert result.model == "power"
    assert result.chosen.params["n"] == pytest.approx(1.5, rel=0.05)
    assert result.stiffness_n_per_mm == pytest.approx(0.2 * 1.5 * 2.0**0.5, rel=0.02)
    straight = fit_stiffness(DEPTH, 0.3 * DEPTH + 0.05 + rng.normal(0, 0.01, DEPTH.size), criterion="bic")
    assert straight.model == "linear-offset" and straight.stiffness_n_per_mm == pytest.approx(0.3, rel=0.01)


def test_hunt_crossley_recovers_damping_when_the_rate_varies():
    t = np.linspace(0.0, 1.0, 1000)
    depth = 2.0 - 2.0 * np.cos(math.pi * t)  # in and out again, so the rate changes sign
    rate = 2.0 * math.pi * np.sin(math.pi * t)
    x = depth + 0.2
    force = 0.15 * x**1.3 + 0.02 * x**1.3 * rate + np.random.default_rng(2).normal(0, 0.005, t.size)
    result = fit_stiffness(depth, force, rate, model="hunt-crossley")
    p = result.chosen.params
    assert p["k_n_per_mm_n"] == pytest.approx(0.15, rel=0.05) and p["n"] == pytest.approx(1.3, rel=0.05)
    assert p["b_n_s_per_mm_n1"] == pytest.approx(0.02, rel=0.05)
    assert all(se > 0 for se in result.chosen.se.values())
    kv = fit_stiffness(depth, 0.2 * depth + 0.03 * rate + 0.01, rate, model="kelvin-voigt").chosen.params
    assert kv["k_n_per_mm"] == pytest.approx(0.2) and kv["b_n_s_per_mm"] == pytest.approx(0.03)


@pytest.mark.parametrize("depth, force, reason", [
    ([], [], "too_few_samples"),
    ([1.0], [0.1], "too_few_samples"),
    ([1.0, 2.0], [0.1, 0.2], "too_few_samples"),
    ([0.0, 1.0, 2.0], [0.0, 0.1, 0.25], None),
    ([1.0] * 10, list(np.linspace(0, 1, 10)), "no_range"),
    (list(1.0 + np.linspace(0, 5e-5, 10)), list(np.linspace(0, 1, 10)), "no_range"),
    (list(DEPTH), [0.4] * DEPTH.size, "constant_force"),
    (list(DEPTH), list(-0.3 * DEPTH), "reversed"),
    ([np.nan] * 5 + [np.inf] * 5, list(range(10)), "too_few_samples"),
    ([[1.0, 2.0]], [[1.0, 2.0]], "bad_shape"),
    ([1.0, 2.0, 3.0], [1.0, 2.0], "bad_shape"),
])
def test_degenerate_traces_are_rejected_by_name(depth, force, reason):
    if reason is None:
        assert fit_stiffness(depth, force).stiffness_n_per_mm > 0
        return
    with pytest.raises(FitRejected) as caught:
        fit_stiffness(depth, force)
    assert caught.value.reason == reason and str(caught.value)


def test_saturated_samples_are_dropped_or_named():
    force = np.minimum(0.5 * DEPTH, 1.0)  # flat above 1 N: the sensor saturated
    kept = fit_stiffness(DEPTH, force, saturated=force >= 1.0, model="linear-offset")
    assert kept.stiffness_n_per_mm == pytest.approx(0.5) and kept.chosen.samples == np.count_nonzero(force < 1.0)
    with pytest.raises(FitRejected) as caught:
        fit_stiffness(DEPTH, force, saturated=np.arange(DEPTH.size) > 1)
    assert caught.value.reason == "saturated"


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(k=st.floats(1e-4, 1e3), depth_max=st.floats(1e-3, 30.0), n=st.integers(4, 600),
       noise=st.floats(0.0, 0.02), seed=st.integers(0, 2**16))
def test_any_stiffness_and_indentation_fits_correctly(k, depth_max, n, noise, seed):
    depth = np.linspace(0.0, depth_max, n)
    top = k * depth_max
    force = k * depth + 0.01 * top + np.random.default_rng(seed).normal(0.0, noise * top, n)
    result = fit_stiffness(depth, force)
    assert math.isfinite(result.stiffness_n_per_mm) and math.isfinite(result.stiffness_se_n_per_mm)
    assert result.stiffness_n_per_mm == pytest.approx(k, rel=0.05 + 20 * noise / math.sqrt(n))


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=40),
       st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=40),
       st.sampled_from(["select", "linear", "hunt-crossley", "exponential"]))
def test_arbitrary_samples_fit_or_are_rejected_by_name(depth, force, model):
    size = min(len(depth), len(force))
    depth, force = depth[:size], force[:size]
    rate = [1.0] * size
    try:
        result = fit_stiffness(depth, force, rate if model == "hunt-crossley" else None, model=model)
    except FitRejected as exc:
        assert exc.reason in REASONS
        return
    assert math.isfinite(result.stiffness_n_per_mm) and math.isfinite(result.stiffness_se_n_per_mm)


def test_a_million_samples_fit_in_bounded_time():
    depth = np.linspace(0.0, 4.0, 1_000_000)
    force = 0.25 * depth + np.random.default_rng(3).normal(0, 0.01, depth.size)
    result = fit_stiffness(depth, force)
    assert result.stiffness_n_per_mm == pytest.approx(0.25, rel=0.01)


def test_batch_linear_fits_match_one_by_one_and_mark_bad_rows():
    rng = np.random.default_rng(4)
    ks = np.array([0.1, 0.5, 2.0])
    depth = np.tile(DEPTH, (4, 1))
    force = np.vstack([ks[:, None] * DEPTH + rng.normal(0, 0.01, (3, DEPTH.size)), np.full(DEPTH.size, 0.3)])
    depth[1, 100:] = np.nan  # a shorter trace, padded
    batch = linear_batch(depth, force)
    assert batch["stiffness_n_per_mm"][:3] == pytest.approx(ks, rel=0.02)
    assert math.isnan(batch["stiffness_n_per_mm"][3]) and batch["samples"][1] == 100
    one_by_one = fit_batch([(depth[i], force[i]) for i in range(4)], model="linear-offset")
    assert [r.stiffness_n_per_mm for r in one_by_one[:3]] == pytest.approx(batch["stiffness_n_per_mm"][:3].tolist())
    assert isinstance(one_by_one[3], FitRejected) and one_by_one[3].reason == "constant_force"


def test_a_curved_fit_at_the_edge_of_its_parameters_or_read_before_its_data_is_no_reading():
    """A fit whose parameter sits on its bound has no optimum inside the box and no curvature to give an sd; one
    whose onset puts the first sample past the reference indentation would read its tangent where it has no data.
    Either is rejected by name, and selection goes on without it."""
    rng = np.random.default_rng(0)
    depth = np.linspace(0.0, 5.0, 400)
    steeper_than_any_power = 0.002 * depth**5 + rng.normal(0.0, 0.002, depth.size)  # x^5: n runs to its bound, 3
    with pytest.raises(FitRejected, match="edge of its parameters \\(n\\)"):
        fit_stiffness(depth, steeper_than_any_power, model="power")
    onset_before_contact = 0.05 * np.expm1(0.8 * (depth + 3.0)) + rng.normal(0.0, 0.002, depth.size)
    with pytest.raises(FitRejected, match="first sample 3.0. mm in, past the 2 mm reference"):
        fit_stiffness(depth, onset_before_contact, model="exponential")
    assert fit_stiffness(depth, onset_before_contact).model != "exponential"


@settings(max_examples=40, deadline=None)
@given(steps=st.lists(st.floats(-0.05, 0.05), min_size=1, max_size=400), rate_hz=st.sampled_from([500.0, 1000.0, 2000.0]))
def test_the_depth_rate_is_scipy_s_savitzky_golay_derivative(steps, rate_hz):
    from scipy.signal import savgol_filter

    depth = np.cumsum(steps)
    window = min(int(0.015 * rate_hz) | 1, depth.size if depth.size % 2 else depth.size - 1)
    expected = savgol_filter(depth, window, 2, deriv=1, delta=1.0 / rate_hz) if window >= 5 else np.zeros_like(depth)
    assert depth_rate_mm_s(depth, rate_hz) == pytest.approx(expected, abs=1e-6)


def test_the_stop_s_braking_is_left_out_of_a_constant_speed_fit_only_when_it_took_force_away():
    t = np.arange(600) / 1000.0
    speed = np.where(t < 0.56, 10.0, 10.0 * np.exp(-(t - 0.559) / 0.012))  # 10 mm/s, then braking to rest
    depth = np.concatenate([[0.0], np.cumsum(speed[1:]) / 1000.0])
    noise = np.random.default_rng(0).normal(0.0, 0.01, depth.size)
    k, b = 0.03, 0.01
    damped = (k + b * speed) * depth**1.9 + noise  # k·x^1.9 + b·x^1.9·v: the braking takes b·v away
    elastic = (k + b * 10.0) * depth**1.9 + noise  # the same press on tissue whose force follows its depth
    kept = before_the_stop(depth, damped, 1000.0)
    assert 555 <= kept <= 562 and np.all(depth_rate_mm_s(depth, 1000.0)[kept:] < 9.0)
    assert before_the_stop(depth, elastic, 1000.0) == depth.size  # braking that lost nothing: all kept
    pressing = depth[:560]
    assert before_the_stop(pressing, damped[:560], 1000.0) == pressing.size  # no braking: every sample kept
    truth = (k + b * 10.0) * 1.9 * Settings().stiffness.reference_depth_mm ** 0.9
    for force in (damped, elastic):
        record = PalpationRecord((0.0, 0.0), contact=True, depth_mm=list(depth), force_n=list(force))
        fit = fit_palpation(record, Settings().stiffness, 1000.0)
        assert abs(fit.stiffness_n_per_mm - truth) <= 3.0 * fit.stiffness_se_n_per_mm + 0.01 * truth
