"""Palpation at the extremes of a 3-D tissue, through the simulator (issue 49): layers 1-30 mm thick on their
rigid base, 1-2000 kPa, Poisson's ratio 0.3-0.495, tips 2.5-8 mm, sensor noise up to 0.2 N, and a sphere under the
tip from 10 times softer to 100 times stiffer. Every press stays within the force cap and above the base, and
reads the table's own force law within its stated uncertainty, or a named outcome."""
import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, example, given, settings as hsettings, strategies as st

from drivers.sim.mechanics.table import MIN_TIP_RADIUS_MM
from drivers.sim.scene import Scene
from palpd.config import Settings
from palpd.scan import palpate
from test_extremes import tared_bench  # the same bench, started, above the tissue and tared

SETTINGS = Settings()
SIZE_MM = 12.0  # a small layer: its table builds in 0.1-1.3 s


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PALPD_CACHE_DIR", str(tmp_path))


def layer(thickness_mm, modulus_kpa, poisson=0.48, tip_mm=2.5, noise_n=0.01, inclusion=None, seed=0) -> Scene:
    return Scene.model_validate({
        "name": "extreme-3d", "seed": seed,
        "tissue": {"size_mm": [SIZE_MM, SIZE_MM], "thickness_mm": thickness_mm, "modulus_kpa": modulus_kpa,
                   "poisson": poisson},
        "inclusion": [inclusion] if inclusion else [], "probe": {"tip_radius_mm": tip_mm},
        "sensor": {"noise_n": noise_n, "tilt": True}})


def pressed(scene):
    bench = tared_bench(scene)
    return bench, palpate(bench, SETTINGS, (0.0, 0.0))


def true_force_n(world, depth_mm):
    """What the simulated tissue pushes back with at (0, 0), pressed depth_mm below its surface, slowly."""
    return world.table.force_n(0.0, 0.0, depth_mm) + world.base.force_n(0.0, 0.0, depth_mm)


def true_reading(world, probe):
    """The force law along the press, read as the chosen model reads it, as (low, high): a line's slope over the
    recorded depths, else the tangent at the model's reference depth (depths from the contact point the press found; the true
    surface is at z = 0)."""
    below = -probe.record.contact_z_mm  # how far below the true surface the contact was placed

    def force(depth_mm):
        return true_force_n(world, max(depth_mm + below, 0.0))

    if probe.fit.model in ("linear", "linear-offset"):
        depth = np.asarray(probe.record.depth_mm)
        slope = float(np.polyfit(depth, [force(d) for d in depth], 1)[0])
        return slope, slope
    # the table is a power law between its depths, so its slope at a tabulated depth (the reference is one)
    # has two sides: between them is the truth
    x, h = probe.fit.chosen.reference_depth_mm, 0.01
    left, right = (force(x) - force(x - h)) / h, (force(x + h) - force(x)) / h
    return min(left, right), max(left, right)


def check_safe_and_honest(bench, probe, scene, deep_enough: bool):
    world, rec = bench.world, probe.record
    deepest_mm = SETTINGS.palpation.depth_mm + SETTINGS.safety.indentation_margin_mm
    if probe.outcome == "no_contact":  # honest only where, as deep as the probe may go, the tissue reads below the noise
        assert true_force_n(world, deepest_mm) < scene.sensor.noise_n, probe.rejected
        assert world.max_indentation_mm <= deepest_mm
        return
    assert probe.outcome in ("fit", "too_stiff", "too_soft"), (probe.outcome, probe.rejected)
    assert tuple(rec.target_xy_mm) == pytest.approx(tuple(rec.xy_mm), abs=1.0)  # where it was aimed
    assert world.max_contact_force_n <= SETTINGS.safety.force_cap_n  # what the tissue really took
    assert world.max_indentation_mm <= scene.tissue.thickness_mm + 0.1  # the base holds
    if probe.outcome != "fit":
        return
    assert math.isfinite(probe.stiffness_n_per_mm) and probe.stiffness_n_per_mm > 0
    # Read where the press went: the base never felt, and the reference depth within the press. A press the force
    # limit stopped short is read along its fitted curve beyond its data (palpd.stiffness.fit.REACH), which a
    # curve that bends past the data misses: a 2 mm tip on a 2000 kPa layer, stopped near 1 mm, was fitted as
    # δ^1.5 (Hertz, right there) and read 6.4 ± 0.2 N/mm at 2 mm, where the sphere, sunk to its equator, has
    # the table rising at 4.2. Found by this test too: while the table pressed one surface node below ~1 mm
    # (F linear, then kinked up as the next ring entered), a 1330 kPa layer read 4.0 ± 0.2 where it rose at
    # 10.1 (now Hertz's onset, table.py). Still open, found by a wider draw (PALPD_HYPOTHESIS=explore): a 7.2 mm
    # tip over a sphere 1 mm down, noise 0.001 N, read 0.052 ± 0.0006 where the table rises at 0.043: one power
    # law over a press whose exponent changes as the contact reaches the sphere, its sd the fit's, not the
    # misfit's (docs/explanation/extremes.md, "3-D tissue").
    if deep_enough and probe.fit.chosen.reference_depth_mm <= max(rec.depth_mm):
        low, high = true_reading(world, probe)
        error = max(low - probe.stiffness_n_per_mm, probe.stiffness_n_per_mm - high, 0.0)
        assert error <= 3.0 * probe.fit.stiffness_se_n_per_mm + 0.15 * low, (probe.fit.model, probe.stiffness_n_per_mm, low, high)


def test_a_press_deeper_than_a_thin_layer_meets_its_rigid_base_and_stops_on_force():
    # The table is linear elastic: before the base was felt, a 4 mm press went 2.8 mm into a 1 mm layer at 2.6 N.
    scene = layer(1.0, 15.0)
    bench, probe = pressed(scene)
    assert probe.record.stop_reason == "force"
    assert bench.world.max_indentation_mm <= 1.1
    assert bench.world.max_contact_force_n <= SETTINGS.safety.force_cap_n


# Each example builds a small table (0.1-1.3 s) and presses once: a few, unshrunk, the same every run (conftest).
@hsettings(max_examples=int(os.environ.get("PALPD_EXTREMES_EXAMPLES", "6")), deadline=None,
           suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
           phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(thickness_mm=st.floats(1.0, 30.0), log_e=st.floats(math.log(1.0), math.log(2000.0)),
       poisson=st.floats(0.3, 0.495), tip_mm=st.floats(MIN_TIP_RADIUS_MM, 8.0), noise_n=st.floats(0.001, 0.2),
       log_ratio=st.one_of(st.none(), st.floats(math.log(0.1), math.log(100.0))), radius_mm=st.floats(1.0, 4.0),
       top_mm=st.floats(0.5, 5.0), seed=st.integers(0, 1000))
# Found by this test: a soft layer under 0.12 N of noise, its contact placed 1.5 mm below the surface (the truth is
# read from there); and a stiff one the force limit stopped at 1.1 mm, read beyond its data (see check_safe_and_honest)
@example(thickness_mm=12.69, log_e=2.07, poisson=0.35, tip_mm=2.5, noise_n=0.123, log_ratio=None, radius_mm=2.1,
         top_mm=0.5, seed=403)
@example(thickness_mm=14.17, log_e=7.19, poisson=0.43, tip_mm=2.88, noise_n=0.048, log_ratio=None, radius_mm=3.3,
         top_mm=0.72, seed=290)
def test_any_3d_layer_palpated_through_the_simulator_stays_safe_and_reads_honestly(
        thickness_mm, log_e, poisson, tip_mm, noise_n, log_ratio, radius_mm, top_mm, seed):
    modulus = math.exp(log_e)
    inclusion = None
    if log_ratio is not None:
        assume(top_mm + 2 * radius_mm < thickness_mm)  # inside the layer
        inclusion = {"shape": "sphere", "center_mm": [0.0, 0.0, top_mm + radius_mm], "radius_mm": radius_mm,
                     "modulus_kpa": modulus * math.exp(log_ratio)}
    scene = layer(thickness_mm, modulus, poisson, tip_mm, noise_n, inclusion, seed)
    bench, probe = pressed(scene)
    deepest_mm = SETTINGS.palpation.depth_mm + SETTINGS.safety.indentation_margin_mm
    check_safe_and_honest(bench, probe, scene, deep_enough=thickness_mm > deepest_mm + 2.0)


def test_the_3d_extremes_bench_scenes_in_the_docs_load_and_fit_their_layers():
    # docs/explanation/extremes.md scans these with `palpd bench extremes --scenes ...`: they must stay valid
    from pathlib import Path

    from drivers.sim.scene import load_scene, truth_lumps

    paths = sorted((Path(__file__).parent.parent / "docs" / "examples" / "extremes-3d").glob("*.toml"))
    assert [p.stem for p in paths] == ["noisy-3d", "soft-3d", "stiff-3d", "thin-3d"]
    for path in paths:
        scene = load_scene(path)
        assert scene.tissue.is_3d and len(truth_lumps(scene)) == 1, path
