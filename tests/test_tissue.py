import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from drivers.clock import VirtualClock
from drivers.phantom import model
from drivers.sim.scene import Scene, load_scene
from drivers.sim.tissue import OVERSHOOT_SHARE, StiffnessField, hunt_crossley_n
from drivers.sim.world import SimWorld


def scene(**tissue):
    return Scene(name="t", tissue=tissue, sensor={"noise_n": 0.0, "bias_n": 0.0})


def contact_force_at(world: SimWorld, x_mm, y_mm, depth_mm) -> float:
    """Hold the simulated tip still at a depth and read the tissue's normal force."""
    world.arm.q = list(model.inverse(world.frame.to_robot((x_mm / 1000, y_mm / 1000, -depth_mm / 1000))))
    world.arm.qd = [0.0, 0.0, 0.0]
    world.advance_to(world.t_s + 0.0005)
    return world.frame.vector_from_robot(world.contact_force_robot)[2]


@pytest.mark.parametrize("k, n", [(0.12, 1.0), (0.3, 1.5), (0.05, 2.0)])
def test_simulated_force_follows_the_scenes_contact_law(k, n):
    world = SimWorld(scene(stiffness_n_per_mm=k, exponent=n), VirtualClock())
    for depth in (0.5, 1.0, 2.0, 4.0):
        # The encoders quantise where the tip is, but the physics sees the true position.
        assert contact_force_at(world, 3.0, -2.0, depth) == pytest.approx(k * depth**n, rel=0.02)
    assert contact_force_at(world, 0.0, 0.0, -1.0) == 0.0  # above the surface: no force


def test_damping_adds_force_while_pressing_and_never_pulls():
    assert hunt_crossley_n(0.2, 1.0, 0.01, 2.0, 10.0) == pytest.approx(0.2 * 2 + 0.01 * 2 * 10)
    assert hunt_crossley_n(0.2, 1.0, 0.5, 2.0, -100.0) == 0.0  # fast withdrawal: tissue lets go
    assert hunt_crossley_n(0.2, 1.0, 0.0, -1.0, 0.0) == 0.0


def lump_scene(depth_mm):
    return Scene(name="l", lump=[{"center_mm": [5, 5], "radius_mm": 8, "depth_mm": depth_mm, "stiffness_n_per_mm": 0.9}])


def test_lump_is_felt_fully_over_its_centre_and_halfway_at_its_radius():
    field = StiffnessField(lump_scene(2.0))
    assert field.k_at(5, 5) == pytest.approx(0.9)
    assert field.k_at(13, 5) == pytest.approx((0.9 + 0.12) / 2)
    assert field.k_at(-25, -25) == pytest.approx(0.12, abs=1e-4)


def test_deeper_lumps_have_a_wider_softer_edge():
    shallow, deep = StiffnessField(lump_scene(0.0)), StiffnessField(lump_scene(6.0))
    assert deep.k_at(16, 5) > shallow.k_at(16, 5)  # outside the radius: felt further out
    assert deep.k_at(10, 5) < shallow.k_at(10, 5)  # inside: less than the full stiffness


@given(st.floats(-40, 40), st.floats(-40, 40))
def test_field_stays_between_tissue_and_lump_stiffness(x, y):
    two = Scene(name="two", lump=[
        {"center_mm": [-10, 0], "radius_mm": 6, "depth_mm": 1, "stiffness_n_per_mm": 0.8},
        {"center_mm": [-4, 0], "radius_mm": 6, "depth_mm": 5, "stiffness_n_per_mm": 0.4},
    ])
    assert 0.12 - 1e-12 <= StiffnessField(two).k_at(x, y) <= 0.8 + 1e-12


def _crowded_raster(tmp_path, row_mm: float, step_mm: float, noise: float, repeats: float, contrast: float, seed: int):
    """A sliding raster's readings as a measured map: rows `row_mm` apart read every `step_mm` along them, each
    reading off by `noise` (relative), a share `repeats` of the spots read again 2 µm on with another value (the
    arm paused), a stiff patch `contrast` times the tissue in the middle. Returns the scene and the readings."""
    rng = np.random.default_rng(seed)
    rows = []
    for y in np.arange(-9.0, 9.01, row_mm):
        for x in np.arange(-14.0, 14.01, step_mm):
            k = 0.12 * (contrast if abs(x) < 4.0 and abs(y) < 4.0 else 1.0) * (1.0 + noise * rng.standard_normal())
            rows.append((x + 0.01 * rng.standard_normal(), y + 0.01 * rng.standard_normal(), k))
            if rng.random() < repeats:
                rows.append((rows[-1][0] + 0.002, rows[-1][1], k * (1.0 + noise * rng.standard_normal())))
    with (tmp_path / "raster.csv").open("w") as out:
        out.write("x_mm,y_mm,stiffness_n_per_mm\n")
        out.writelines(f"{x:.4f},{y:.4f},{k:.5f}\n" for x, y, k in rows)
    (tmp_path / "raster.toml").write_text('name = "raster"\n[tissue]\nsize_mm = [28.0, 18.0]\nmap = "raster.csv"\n')
    return load_scene(tmp_path / "raster.toml"), np.array([round(k, 5) for _, _, k in rows])  # as written


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(row_mm=st.floats(2.0, 4.0), step_mm=st.floats(0.1, 0.5), noise=st.floats(0.0, 0.1),
       repeats=st.floats(0.0, 0.5), contrast=st.floats(1.0, 4.0), seed=st.integers(0, 2**16))
def test_a_crowded_raster_map_is_felt_within_its_readings(tmp_path, row_mm, step_mm, noise, repeats, contrast, seed):
    """Between a measured map's readings the simulator feels no stiffness far past them: through a sliding
    raster's readings the interpolant had drawn 8 N/mm where none read over 0.44 (tissue._within_the_readings_around)."""
    scene, k = _crowded_raster(tmp_path, row_mm, step_mm, noise, repeats, contrast, seed)
    field = StiffnessField(scene)
    slack = OVERSHOOT_SHARE * np.ptp(k)
    felt = np.array([field.k_at(x, y) for x in np.arange(-14.0, 14.01, 0.25) for y in np.arange(-9.0, 9.01, 0.25)])
    assert felt.max() <= k.max() + slack + 1e-9 and felt.min() >= min(k.min() - slack, 0.1 * k.min()) - 1e-9


def test_a_raster_scan_over_a_crowded_raster_map_reads_only_what_the_map_holds(tmp_path):
    """Through the simulator, the drivers and the stiffness fit: every palpation of a 5 x 5 raster reads a
    stiffness within the map's readings (and their slack); before, one read 1.3 N/mm off readings of 0.11-0.33."""
    from palpd.bench import open_simulated_bench
    from palpd.config import Settings
    from palpd.scan import plan, run_scan

    scene, k = _crowded_raster(tmp_path, 3.0, 0.2, 0.03, 0.3, 2.5, 0)
    settings = Settings().updated(scan={"strategy": "raster"})
    report = run_scan(open_simulated_bench(settings, scene, seed=0), settings,
                      plan("raster", scene.tissue.size_mm, 25, 0, settings))
    read = [p["stiffness_n_per_mm"] for p in report["probes"] if p["outcome"] == "fit"]
    assert report["faults"] == [] and len(read) == 25, report["faults"]
    slack = OVERSHOOT_SHARE * np.ptp(k)
    assert k.min() - slack <= min(read) and max(read) <= 1.05 * (k.max() + slack), (min(read), max(read))
