"""Palpation at the extremes of sensor and tissue, through the simulator: noise 0.001-0.3 N, tissue 0.005-5 N/mm
and what is pressed up to 50 N/mm (a lump of 100 N/mm below, 20 times the stiffest tissue), exponent 1-2, damping 0-0.01 N·s/mm. Each palpation gives a stiffness within its stated uncertainty, or a named
outcome (a bound the truth satisfies), always where it was aimed."""
import dataclasses
import math
import os
import random

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, example, given, settings as hsettings, strategies as st

from conftest import SCENES
from drivers.sim.scene import Scene, load_scene
from drivers.sim.tissue import StiffnessField
from palpd.learner.planner import make_learner
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.contact import contact_thresholds, measure_noise
from palpd.control.onset import hinge
from palpd.control.segment import Segmenter
from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.scan import failure_reason, palpate
from palpd.stiffness import fit
from palpd.stiffness.palpation import depth_rate_mm_s
from palpd.probe import BOUND_OVER_FIT_REL_SD, Probe, judge
from palpd.control.palpation import PalpationRecord

SETTINGS = Settings()
SPEED_MM_S = SETTINGS.palpation.speed_mm_s


def tared_bench(scene):
    bench = open_simulated_bench(SETTINGS, scene)
    bench.servo.start()
    above = (0.0, 0.0, SETTINGS.palpation.clearance_mm)
    bench.servo.run(MoveTo(above, 80.0, 2000.0))
    tare = HoldAndCollect(SETTINGS.palpation.tare_samples, where=above)
    bench.servo.run(tare)
    bench.servo.forces.tare(tare.samples)
    return bench


def felt_n_per_mm(k, n, b, x_mm, speed_mm_s=SPEED_MM_S):
    """dF/dx of k·xⁿ + b·xⁿ·v at an indentation speed v: what a press at that constant speed feels."""
    return (k + b * speed_mm_s) * n * x_mm ** (n - 1.0)


def true_reading(probe, k, n, b):
    """The simulator's force law along the palpation's own motion (its speed sags below the commanded one as
    the force grows), read as the chosen model reads it: a straight line's slope over the recorded depths (a
    line fitted to a gently curved trace is its mean slope), else the tangent at the reference depth."""
    depth = np.asarray(probe.record.depth_mm)
    rate = depth_rate_mm_s(depth, SETTINGS.servo.rate_hz)
    if probe.fit.model not in ("linear", "linear-offset"):
        return felt_n_per_mm(k, n, b, probe.fit.chosen.reference_depth_mm, float(np.median(rate)))
    x = np.maximum(depth - probe.record.contact_z_mm, 0.0)  # the true surface is at z = 0
    return float(np.polyfit(depth, k * x**n + b * x**n * rate, 1)[0])


def check_honest(probe, k, n, b):
    rec = probe.record
    assert tuple(rec.target_xy_mm) == pytest.approx(tuple(rec.xy_mm), abs=1.0)  # where it was aimed
    assert probe.outcome in ("fit", "too_stiff", "too_soft"), (probe.outcome, probe.rejected)
    if probe.outcome == "fit":
        truth = true_reading(probe, k, n, b)
        error = abs(probe.stiffness_n_per_mm - truth)
        assert error <= 3.0 * probe.fit.stiffness_se_n_per_mm + 0.1 * truth, (probe.fit.model, probe.stiffness_n_per_mm, truth)
    elif probe.outcome == "too_stiff":
        assert probe.stiffness_bound_n_per_mm <= 1.1 * felt_n_per_mm(k, n, b, max(rec.depth_mm, default=0.05))
    else:
        assert probe.stiffness_bound_n_per_mm >= 0.9 * felt_n_per_mm(k, n, b, max(rec.depth_mm))


# Each example is a simulated palpation (~0.5 s): a few, unshrunk (a failure prints its example as drawn).
# PALPD_HYPOTHESIS=explore PALPD_EXTREMES_EXAMPLES=400 draws more, afresh, to look for failures on purpose
# (README, "Palpation at the extremes"); the suite draws the same 8 every run (tests/conftest.py).
@hsettings(max_examples=int(os.environ.get("PALPD_EXTREMES_EXAMPLES", "8")), deadline=None, suppress_health_check=[HealthCheck.too_slow],
           phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(noise_n=st.floats(0.001, 0.3), log_k=st.floats(math.log(0.005), math.log(50.0)), n=st.floats(1.0, 2.0),
       b=st.sampled_from([0.0, 0.01]), seed=st.integers(0, 1000))
# Found by this test. Damping that reversed the simulated tip within a physics step: the chatter, rectified by the
# contact law, read 0.56 ± 0.023 N/mm on 0.44 (a power law that missed the trace over hundreds of samples) and
# 0.29 ± 0.03 on 0.17 (SimWorld._damping_substeps)
@example(noise_n=0.3, log_k=-2.9456357392431016, n=1.88348743750813, b=0.01, seed=654)
@example(noise_n=0.2622544676785593, log_k=-4.8363431391686795, n=1.988769447230295, b=0.01, seed=75)
# and an exponential chosen by BIC 2.3 over the power law it could not exclude, which read the slope 4 times less surely
@example(noise_n=0.0980665, log_k=-3.4279241847715376, n=1.708769841848929, b=0.0, seed=273)
# and a rise in an approach no threshold caught, its onset picked by the noise 12 mm down: 0.095 ± 0.030 on 0.005
# (since issue 51 no approach goes deeper than the depth and the margin: 0.025 N there, under 0.24 N of noise)
@example(noise_n=0.2366, log_k=-5.298317366548035, n=1.0, b=0.0, seed=203)
# and, read at the deepest point of a press the force limit stopped short, an exponential chosen by 6.2 BIC units
# over the power law it had then excluded: 4.07 ± 0.08 where the power law read 3.21 and the truth was 3.20
@example(noise_n=0.13238342408143006, log_k=0.0, n=1.8690717692378425, b=0.0, seed=0)
# and a damped press whose stop, braking at almost constant depth, took 1 N of its 2.5 N away: 0.52 ± 0.018 on 0.37
@example(noise_n=0.23, log_k=-3.661264287080963, n=1.94, b=0.01, seed=519)
@example(noise_n=0.16059924251422103, log_k=-3.2058860874878343, n=1.7297662719042006, b=0.01, seed=176)
def test_any_noise_and_tissue_palpated_through_the_simulator_gives_an_honest_reading(noise_n, log_k, n, b, seed):
    k = math.exp(log_k)
    scene = Scene(name="extreme", seed=seed, tissue={"stiffness_n_per_mm": k, "exponent": n, "damping_n_s_per_mm": b},
                  sensor={"noise_n": noise_n, "tilt": True})
    bench = tared_bench(scene)
    probe = palpate(bench, SETTINGS, (3.0, -2.0))
    if probe.outcome == "no_contact":  # honest only where, as deep as the probe may go, the tissue reads below the noise
        deepest_mm = SETTINGS.palpation.depth_mm + SETTINGS.safety.indentation_margin_mm
        assert (k + b * SETTINGS.palpation.speed_mm_s) * deepest_mm ** n < noise_n, probe.rejected
        assert bench.world.max_indentation_mm <= deepest_mm
        return
    check_honest(probe, k, n, b)


@pytest.fixture(scope="module")
def stiff_lump():
    """2 N/mm tissue with a 12 N/mm lump: the force limit comes at a third of a millimetre over the lump."""
    scene = Scene(name="stiff", tissue={"stiffness_n_per_mm": 2.0},
                  lump=[{"center_mm": (0.0, 0.0), "radius_mm": 10.0, "stiffness_n_per_mm": 12.0}], sensor={"tilt": True})
    bench = tared_bench(scene)
    return [palpate(bench, SETTINGS, xy) for xy in ((0.0, 0.0), (-20.0, 20.0))]


def test_the_stiffest_spot_is_measured_not_dropped(stiff_lump):
    centre, background = stiff_lump
    assert centre.record.stop_reason == "force" and centre.outcome == "fit"
    assert centre.stiffness_n_per_mm == pytest.approx(12.0, abs=3.0 * centre.fit.stiffness_se_n_per_mm + 1.2)
    assert background.fit.model in ("linear", "linear-offset")
    assert background.stiffness_n_per_mm == pytest.approx(2.0, rel=0.05)


@pytest.fixture(scope="module")
def stiffer_lumps():
    """5 N/mm tissue with lumps of 6 and 20 times that: the force limit comes 0.14 and 0.09 mm in."""
    scene = Scene(name="stiffer", tissue={"stiffness_n_per_mm": 5.0}, sensor={"tilt": True},
                  lump=[{"center_mm": (-15.0, 0.0), "radius_mm": 8.0, "stiffness_n_per_mm": 30.0},
                        {"center_mm": (15.0, 0.0), "radius_mm": 8.0, "stiffness_n_per_mm": 100.0}])
    bench = tared_bench(scene)
    bound = SETTINGS.updated(palpation={"too_stiff": "bound"})
    # 100 N/mm first, from the tare: the press bounces on it (position control on a spring that stiff)
    too_stiff = palpate(bench, SETTINGS, (15.0, 0.0))
    spots = ((-15.0, 0.0), (-16.0, 1.0), (-14.0, -1.0))
    return [palpate(bench, SETTINGS, xy) for xy in spots], too_stiff, [palpate(bench, bound, xy) for xy in spots]


def test_a_press_that_meets_the_force_limit_early_is_repeated_gently_or_bounded_as_the_settings_say(stiffer_lumps):
    gentle, too_stiff, once = stiffer_lumps
    for again, first in zip(gentle, once):
        assert again.presses == 2 and first.presses == 1
        assert first.record.stop_reason == again.record.stop_reason == "force"
        assert again.as_dict()["presses"] == 2
        # the gentle press reads the same depth over more samples (a quarter of the speed)
        assert len(again.record.depth_mm) > 2 * len(first.record.depth_mm)
        for probe in (again, first):
            # a fit sure to a quarter, or the bound the press gives for sure: never a guess such as 25.5 ± 31 N/mm,
            # a reading plain 5 N/mm tissue would give as likely (a scan of such lumps said "no lump")
            if probe.outcome == "fit":
                assert probe.fit.stiffness_se_n_per_mm <= BOUND_OVER_FIT_REL_SD * probe.stiffness_n_per_mm
                assert probe.stiffness_n_per_mm == pytest.approx(30.0, abs=2.0 * probe.fit.stiffness_se_n_per_mm)
            else:
                assert probe.outcome == "too_stiff" and "says less than the bound" in probe.rejected
                assert 2.0 * 5.0 < probe.stiffness_bound_n_per_mm <= 30.0  # honest, and far over the tissue
    # 100 N/mm meets 4 N within four encoder steps: a bound, honest, never a slope (it read 20 ± 5 N/mm); not
    # pressed again, as a gentler press stops as shallow
    assert too_stiff.outcome == "too_stiff" and too_stiff.presses == 1 and too_stiff.fit is None
    assert 15.0 < too_stiff.stiffness_bound_n_per_mm <= 100.0


@pytest.mark.parametrize("side, tissue, lump, radius", [(60.0, 0.12, 50.0, 8.0), (40.0, 5.0, 15.0, 6.0)],
                         ids=["400x", "3x-in-stiff-tissue"])
def test_a_lump_the_force_limit_stops_every_press_on_is_found_not_read_as_noise(side, tissue, lump, radius):
    """Over these lumps the 4 N limit comes about 0.1 and 0.3 mm in, far short of the reading's 2 mm: kept as fits,
    the presses read 91.8 ± 201 and 16.2 ± 11.7 N/mm, as likely under the plain tissue, and the active scan
    (seed 0) said "no lump" at weight 1.000 (after 10 palpations, on the smaller tissue). As bounds they are what
    the presses measured."""
    from palpd.embedded import run_simulated_scan

    scene = Scene(name="hard", seed=0, tissue={"size_mm": (side, side), "stiffness_n_per_mm": tissue},
                  lump=[{"center_mm": (5.0, 5.0) if side > 50 else (3.0, 4.0), "radius_mm": radius,
                         "stiffness_n_per_mm": lump}])
    report, _ = run_simulated_scan(SETTINGS.updated(scan={"strategy": "active", "seed": 0}), scene, in_process=True)
    assert report["verdict"] == "lumps", report["model"]
    assert report["metrics"]["lumps_found"] == 1 and report["metrics"]["false_lumps"] == 0, report["metrics"]
    bounds = [p for p in report["probes"] if p["outcome"] == "too_stiff"]
    assert bounds and all(tissue < p["stiffness_bound_n_per_mm"] <= lump for p in bounds)


# Each example: 8 presses within 5 mm of the centre of a lump of 100-300 N/mm in 0.5 N/mm tissue (~1 s).
@hsettings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(log_k=st.floats(math.log(100.0), math.log(300.0)), too_stiff=st.sampled_from(["bound", "repalpate"]),
       seed=st.integers(0, 1000))
def test_tissue_too_stiff_to_press_is_a_bound_and_never_pushes_past_the_cap(log_k, too_stiff, seed):
    """A probe pressing 100-300 N/mm bounces (palpd.control.palpation, REBOUND_STOP_FRACTION): the press ends at
    the rebound, or releases at once when the limit stops it that shallow. Before, 22 of 24 runs of 10 such
    presses at 150 and 250 N/mm met a force_cap fault (up to 7.2 N), in either mode."""
    k = math.exp(log_k)
    scene = Scene(name="rock", seed=seed, tissue={"stiffness_n_per_mm": 0.5}, sensor={"noise_n": 0.01, "tilt": True},
                  lump=[{"center_mm": (0.0, 0.0), "radius_mm": 8.0, "depth_mm": 1.0, "stiffness_n_per_mm": k}])
    bench = tared_bench(scene)
    settings = SETTINGS.updated(palpation={"too_stiff": too_stiff})
    rng = random.Random(seed)
    for _ in range(8):
        probe = palpate(bench, settings, (rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0)))  # a fault raises
        assert probe.outcome == "too_stiff" and probe.presses == 1, (probe.outcome, probe.rejected)
        assert probe.stiffness_bound_n_per_mm <= k and probe.record.stop_reason == "force"
    assert bench.world.reset_peak() < SETTINGS.safety.force_cap_n  # the true peak, between samples too


@pytest.mark.parametrize("k, reference_mm", [(1.5, 2.0), (3.0, 2.0), (12.0, None)])
def test_a_press_the_limit_stops_short_on_hardening_tissue_is_read_at_the_reference_along_its_curve(k, reference_mm):
    """Tissue of exponent 2 stiff enough that 4 N comes at 1.63, 1.15 or 0.58 mm of the 2 mm reference: read
    along the press's own curve at 2 mm, or at twice the deepest sample, never beyond. Read at the deepest
    sample, the first came out 0.82 times the truth (a lump's radius then 0.6 mm large)."""
    scene = Scene(name="hardening", tissue={"stiffness_n_per_mm": k, "exponent": 2.0}, sensor={"tilt": True})
    probe = palpate(tared_bench(scene), SETTINGS, (0.0, 0.0))
    assert probe.record.stop_reason == "force" and probe.outcome == "fit", probe.rejected
    deepest = max(probe.record.depth_mm)
    read_at = probe.fit.chosen.reference_depth_mm
    assert read_at == pytest.approx(reference_mm or fit.REACH * deepest) and read_at > deepest
    truth = felt_n_per_mm(k, 2.0, 0.0, read_at - probe.record.contact_z_mm)  # the true surface is at z = 0
    assert probe.stiffness_n_per_mm == pytest.approx(truth, abs=3.0 * probe.fit.stiffness_se_n_per_mm + 0.05 * truth)


@pytest.mark.parametrize("lead_counted", [True, False])
def test_a_press_on_a_stiff_lump_reaches_its_depth(monkeypatch, lead_counted):
    """The paper scene's lump pushes back 2 N at 4 mm, and the servo's spring (1.5 N/mm) then holds its setpoint
    1.3 mm below the tip. Bounding the setpoint itself by the floor (0.75 mm under the deepest press) ended every
    press there, 2.9-3.4 mm down (labelled `depth`; a press short of its depth is `floor` now); counting the lead
    the push holds, the press reads to the 4 mm asked (`surface.held_lead_mm`; without it this test fails)."""
    import palpd.control.sensing as sensing
    if not lead_counted:
        monkeypatch.setattr(sensing, "held_lead_mm", lambda *args: 0.0)
    bench = tared_bench(load_scene(SCENES / "paper.toml"))
    probe = palpate(bench, SETTINGS, (7.5, -4.0))  # the lump's centre
    deepest = max(probe.record.depth_mm)
    assert probe.outcome == "fit" and probe.record.max_force_n > 1.5
    if lead_counted:
        assert probe.record.stop_reason == "depth" and deepest >= SETTINGS.palpation.depth_mm - 0.05, deepest
        assert bench.world.max_indentation_mm <= SETTINGS.palpation.depth_mm + SETTINGS.safety.indentation_margin_mm
    else:  # what the floor alone did, and the record now says so
        assert probe.record.stop_reason == "floor" and deepest < SETTINGS.palpation.depth_mm - 0.5, deepest


def test_a_press_set_shallower_than_the_reference_is_read_where_it_ends():
    """palpation.depth_mm 1.5 under the 2 mm reference: every press stops by depth, and all are read at their
    deepest sample, comparable with each other, not along a curve beyond what any of them pressed."""
    scene = Scene(name="hardening", tissue={"stiffness_n_per_mm": 0.3, "exponent": 2.0}, sensor={"tilt": True})
    shallow = SETTINGS.updated(palpation={"depth_mm": 1.5})
    probe = palpate(tared_bench(scene), shallow, (0.0, 0.0))
    assert probe.record.stop_reason == "depth" and probe.outcome == "fit", probe.rejected
    assert probe.fit.chosen.reference_depth_mm == pytest.approx(max(probe.record.depth_mm))


def test_tissue_too_soft_to_outrun_a_drift_follower_is_still_read_from_its_approach():
    """0.005 N/mm pressed at 10 mm/s rises 0.05 N/s: a zero that followed it during the approach lagged by less
    than the 0.03 N threshold, contact never fired, and the too_soft bound (k <= 0.0021) was below the truth.
    Since issue 51 the approach ends at the depth the probe may go (0.023 N there, under the threshold still):
    the rise is read from the approach's trace, its contact point found again near the surface."""
    scene = Scene(name="soft", seed=5, tissue={"stiffness_n_per_mm": 0.005}, sensor={"noise_n": 0.01, "tilt": True})
    bench = tared_bench(scene)
    probe = palpate(bench, SETTINGS, (28.4, 26.6))
    assert probe.record.stop_reason == "no_contact" and abs(probe.record.contact_z_mm) < 0.5, probe.rejected
    assert probe.outcome == "fit" and probe.stiffness_n_per_mm == pytest.approx(0.005, rel=0.2)  # 0.0042: 4.5 mm of it
    assert bench.world.max_indentation_mm <= SETTINGS.palpation.depth_mm + SETTINGS.safety.indentation_margin_mm


def test_no_lump_is_said_only_once_a_lump_like_the_soft_tissue_one_could_not_hide():
    """The soft-tissue scene's field as the simulator feels it, read as its palpations read it (±2 %): with
    every spot within 18 mm of a reading the learner said "no lump" after 10 palpations, none of them within
    11 mm of the 10 mm lump's centre. It must palpate inside the lump before it stops."""
    scene = load_scene(SCENES / "soft-tissue.toml")
    field, (lump,) = StiffnessField(scene), scene.lump
    learner = make_learner(SETTINGS.updated(learner={"grid_points": 61}), scene.tissue.size_mm, 0)
    rng, felt = np.random.default_rng(0), False
    while not felt and (xy := learner.next_probe(40)) is not None:
        k = field.k_at(*xy)
        learner.observe(xy, k * (1.0 + rng.normal(0.0, 0.02)), 0.02 * k)
        felt = math.dist(xy, lump.center_mm) < lump.radius_mm
    assert felt, f"stopped with {learner.verdict()!r} after {learner.points} palpations, none inside the lump"


@pytest.fixture(scope="module")
def noisy_sensor():
    scene = Scene(name="noisy", tissue={"stiffness_n_per_mm": 0.12}, sensor={"noise_n": 0.3, "tilt": True})
    bench = tared_bench(scene)
    return bench, [palpate(bench, SETTINGS, xy) for xy in ((5.0, -5.0), (-10.0, 10.0), (15.0, 3.0))]


def test_contact_thresholds_rise_with_the_measured_noise_and_the_contact_point_is_found_again(noisy_sensor):
    bench, probes = noisy_sensor
    noise = bench.servo.forces.noise
    assert noise.sd_n == pytest.approx(0.3, rel=0.15)
    assert probes[0].record.contact_on_n > 0.2  # far above the 0.03 N floor: the noise cannot reach it
    for probe in probes:
        assert probe.outcome == "fit" and abs(probe.record.contact_z_mm) < 1.0  # the surface is at z = 0
        assert probe.stiffness_n_per_mm == pytest.approx(0.12, abs=3.0 * probe.fit.stiffness_se_n_per_mm + 0.006)


def test_a_palpation_that_finds_nothing_is_reported_where_it_was_aimed():
    probe = judge(PalpationRecord((12.0, -7.0), stop_reason="no_contact"), SETTINGS)
    assert probe.outcome == "no_contact" and probe.fit is None and probe.stiffness_bound_n_per_mm is None
    report = probe.as_dict()
    assert report["xy_mm"] == report["target_xy_mm"] == [12.0, -7.0] and "contact_xy_mm" not in report


def test_hinge_finds_the_onset_under_noise_a_threshold_fires_millimetres_late():
    rng = np.random.default_rng(0)
    z = np.linspace(3.0, -4.0, 1400)  # tip height, mm: the surface at 0
    force = 0.12 * np.maximum(-z, 0.0) + rng.normal(0.0, 0.3, z.size)
    onset, zero, spread_mm = hinge(z, force, fallback=1100)
    assert abs(z[onset]) < 0.4 and abs(zero) < 0.05 and spread_mm < 2.0  # placed within the 4 mm pressed
    assert hinge(z, rng.normal(0.0, 0.3, z.size), fallback=1100)[0] is None  # flat: no contact at all


def test_a_faint_rise_the_trace_cannot_place_is_a_bound_not_a_reading():
    """No threshold fired all the way down a 15 mm approach; the trace rises significantly, but onsets
    many millimetres apart fit it as well as the best, so the slope after the one picked is the noise's."""
    rng = np.random.default_rng(3)
    z = np.linspace(1.5, -14.0, 1550)
    force = 0.005 * np.maximum(-z, 0.0) + rng.normal(0.0, 0.24, z.size)
    force[-180:] += np.linspace(0.0, 0.1, 180)  # and a faint rise over the last 1.8 mm
    onset, zero, spread_mm = hinge(z, force, fallback=z.size - 1)
    assert onset is not None and spread_mm > z[onset] - z[-1]
    record = PalpationRecord((3.0, -2.0), contact=True, contact_z_mm=float(z[onset]), stop_reason="no_contact",
                             depth_mm=list(z[onset] - z[onset:]), force_n=list(force[onset:] - zero),
                             contact_on_n=0.3, lowest_z_mm=float(z[-1]), onset_spread_mm=spread_mm)
    probe = judge(record, SETTINGS)
    assert probe.outcome == "too_soft" and probe.fit is None and "too faint to place" in probe.rejected
    assert probe.stiffness_bound_n_per_mm == pytest.approx(0.3 / 14.0)
    placed = judge(dataclasses.replace(record, onset_spread_mm=0.1), SETTINGS)
    assert placed.outcome == "fit"  # the same trace, placed: read as it is (the rule is the spread, not the trace)


def test_noise_is_measured_about_the_drift_and_scales_the_thresholds_above_the_floors():
    rng = random.Random(1)

    class Sample:
        def __init__(self, t, sd):
            self.t_s, self.force_n = t, (rng.gauss(0, sd), rng.gauss(0, sd), 0.5 * t + rng.gauss(0, sd))

    quiet = measure_noise([Sample(i * 0.001, 0.001) for i in range(200)])
    loud = measure_noise([Sample(i * 0.001, 0.3) for i in range(200)])
    assert quiet.sd_n == pytest.approx(0.001, rel=0.2) and quiet.drift_n_per_s == pytest.approx(0.5, rel=0.1)
    p = SETTINGS.palpation
    assert contact_thresholds(p, quiet, 1000.0).on_n == p.contact_on_n  # the floor
    high = contact_thresholds(p, loud, 1000.0)
    assert high.on_n > 10 * p.contact_on_n and high.off_n < high.on_n


def test_nan_samples_are_dropped_and_counted():
    segmenter = Segmenter(0.06, 0.03)
    for i in range(100):
        segmenter.push(i * 0.001, (0.0, 0.0, 1.0), math.nan if i % 10 == 0 else 0.0)
    assert segmenter.dropped == 10


def test_palpations_that_keep_failing_are_undetermined_with_the_reason():
    def probe(outcome, bound=None):
        return Probe(PalpationRecord((0.0, 0.0)), None, "x", outcome, bound)

    assert failure_reason([probe("no_contact")] * 38 + [probe("rejected")] * 2) == (
        "38 of 40 palpations found no contact: check the tissue placement (tissue.origin_mm) and the force sensor")
    assert failure_reason([probe("too_stiff", 20.0)] * 5) is None  # censored readings are evidence
