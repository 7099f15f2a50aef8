"""The finite-element tissue against what is known exactly: Hertz, and Dimitriadis et al. 2002 for a layer.

A quarter of a block (mirror planes through the tip's axis), the tip pressed at its corner with the paraboloid
gap that both laws assume.
"""
from __future__ import annotations

import math

import numpy as np

from drivers.sim.mechanics.contact import contact_forces_n, sphere_gap_mm
from drivers.sim.mechanics.fem import Grid, SurfaceCompliance, depth_lines, graded

# Dimitriadis et al., Biophys. J. 2002, eq. 12, bonded to its base, incompressible (nu = 0.5)
BONDED_COEFFICIENTS = (1.0, 1.133, 1.283, 0.769, 0.0975)


def hertz_n(modulus_kpa: float, poisson: float, tip_radius_mm: float, depth_mm: float) -> float:
    """F = 4/3 E/(1 - nu^2) sqrt(R) delta^1.5 (kPa = mN/mm^2, so N after 1e-3)."""
    return 4.0 / 3.0 * modulus_kpa * 1e-3 / (1 - poisson**2) * math.sqrt(tip_radius_mm) * depth_mm**1.5


def bonded_layer_n(modulus_kpa, poisson, tip_radius_mm, depth_mm, thickness_mm) -> float:
    chi = math.sqrt(tip_radius_mm * depth_mm) / thickness_mm
    factor = sum(c * chi**i for i, c in enumerate(BONDED_COEFFICIENTS))
    return hertz_n(modulus_kpa, poisson, tip_radius_mm, depth_mm) * factor


def quarter_block(thickness_mm, modulus_kpa, poisson, fine_mm, extent_mm=None, fine_half_mm=2.0, growth=1.5,
                  depth_growth=1.5) -> SurfaceCompliance:
    """A quarter of a layer extent_mm wide each way from the tip (default: its thickness), elements fine_mm
    within fine_half_mm of the tip, growing by `growth` outward and by `depth_growth` downward."""
    extent = extent_mm or thickness_mm
    xs = graded(0.0, extent, fine_mm, fine_half_mm, growth=growth)
    zs = depth_lines(thickness_mm, fine_mm, growth=depth_growth)
    return SurfaceCompliance(Grid(xs, xs, zs), modulus_kpa, poisson, symmetric_quarter=True)


# Hertz's half-space, approximated by a block far thicker and wider than the contact: Dimitriadis' bonded factor
# 1 + 1.133 chi + ... (chi = sqrt(R delta) / h) says a 15 mm block reads 5-10 % over Hertz at delta 0.2-0.8 mm,
# a 100 mm one 1-2 %. Fine elements only under the tip (a contact radius a <= 1.41 mm), growing x2 outward and
# x1.5 downward, so the block's unknowns stay those of a thin layer's.
HALF_SPACE_MM = 100.0
HALF_SPACE_FINE_HALF_MM = 1.6
HALF_SPACE_GROWTH = 2.0
HALF_SPACE_DEPTH_GROWTH = 1.5


def half_space_block(modulus_kpa, poisson, fine_mm, thickness_mm=HALF_SPACE_MM,
                     depth_growth=HALF_SPACE_DEPTH_GROWTH) -> SurfaceCompliance:
    """A quarter of a block thickness_mm deep and as wide each way, graded from fine_mm under the tip."""
    return quarter_block(thickness_mm, modulus_kpa, poisson, fine_mm, fine_half_mm=HALF_SPACE_FINE_HALF_MM,
                         growth=HALF_SPACE_GROWTH, depth_growth=depth_growth)


def indentation_forces_n(block: SurfaceCompliance, tip_radius_mm, depths_mm, paraboloid=True, reach_mm=2.0):
    """Force at each indentation of a tip at the block's corner (the whole tip: four quarters)."""
    r = np.hypot(*block.surface_xy.T)
    near = np.flatnonzero(r < reach_mm)
    columns = block.columns(near)[near]
    compliance = (columns + columns.T) / 2.0  # symmetric but for round-off
    gap = sphere_gap_mm(r[near], tip_radius_mm, paraboloid=paraboloid)
    return [4.0 * contact_forces_n(compliance, gap, d).sum() for d in depths_mm]
