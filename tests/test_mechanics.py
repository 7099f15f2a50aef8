"""The finite-element tissue against the bonded-layer law (Dimitriadis et al. 2002), on a small coarse mesh."""
import numpy as np
import pytest

from drivers.sim.mechanics.contact import contact_forces_n, sphere_gap_mm
from drivers.sim.mechanics.validation import bonded_layer_n, hertz_n, indentation_forces_n, quarter_block

TOLERANCE = 0.05


def test_a_thin_bonded_layer_reads_the_dimitriadis_force_within_5_percent():
    block = quarter_block(thickness_mm=6.0, modulus_kpa=15.0, poisson=0.48, fine_mm=0.4)
    depths = [0.2, 0.4, 0.6, 0.8]
    forces = indentation_forces_n(block, 2.5, depths)
    for depth, force in zip(depths, forces):
        expected = bonded_layer_n(15.0, 0.48, 2.5, depth, 6.0)
        assert abs(force / expected - 1) <= TOLERANCE, (depth, force, expected)
    # and the layer is felt: 15-30 % stiffer than Hertz's half-space here
    assert forces[-1] > 1.1 * hertz_n(15.0, 0.48, 2.5, 0.8)


def test_contact_presses_only_where_the_tip_reaches_and_never_pulls():
    compliance = np.array([[2.0, 0.5, 0.1], [0.5, 2.0, 0.5], [0.1, 0.5, 2.0]])
    gap = sphere_gap_mm(np.array([0.0, 1.0, 2.4]), 2.5)
    forces = contact_forces_n(compliance, gap, 0.3)
    assert forces[0] > 0 and forces.min() >= 0
    surface = compliance @ forces
    touching = forces > 0
    assert np.allclose(surface[touching], 0.3 - gap[touching])  # on the tip where it presses
    assert np.all(surface[~touching] >= 0.3 - gap[~touching] - 1e-9)  # nowhere inside the tip
    assert sphere_gap_mm(np.array([2.6]), 2.5)[0] == np.inf  # past the rim the sphere never touches
    assert contact_forces_n(compliance, gap, 0.0).sum() == 0.0
