"""A rigid spherical tip pressed into the condensed surface: frictionless contact as a small quadratic program."""
from __future__ import annotations

import numpy as np


def sphere_gap_mm(r_mm: np.ndarray, tip_radius_mm: float, paraboloid: bool = False) -> np.ndarray:
    """Height of the tip's surface above its lowest point at lateral distance r (infinite past its rim).
    Hertz's law assumes the paraboloid r^2 / 2R; the simulator uses the sphere itself."""
    if paraboloid:
        return r_mm * r_mm / (2.0 * tip_radius_mm)
    inside = r_mm < tip_radius_mm
    gap = np.full(np.shape(r_mm), np.inf)
    gap[inside] = tip_radius_mm - np.sqrt(tip_radius_mm**2 - r_mm[inside] ** 2)
    return gap


def contact_forces_n(compliance_mm_per_n: np.ndarray, gap_mm: np.ndarray, depth_mm: float) -> np.ndarray:
    """Nodal forces f >= 0 with the surface (w = C f) touching the tip where f > 0 and below it elsewhere:
    min 1/2 f'Cf - b'f over f >= 0, b = depth - gap, as a non-negative least-squares problem on C = L L'."""
    from scipy.linalg import cholesky, solve_triangular
    from scipy.optimize import nnls

    reach = np.isfinite(gap_mm) & (gap_mm < depth_mm)
    forces = np.zeros(len(gap_mm))
    if not reach.any():
        return forces
    c = compliance_mm_per_n[np.ix_(reach, reach)]
    lower = cholesky(c, lower=True)
    target = solve_triangular(lower, depth_mm - gap_mm[reach], lower=True)
    forces[reach] = nnls(lower.T, target)[0]
    return forces
