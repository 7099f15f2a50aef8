import pytest
from hypothesis import given, strategies as st

from drivers.clock import VirtualClock
from drivers.phantom import model
from drivers.sim.scene import Scene
from drivers.sim.tissue import StiffnessField, hunt_crossley_n
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
