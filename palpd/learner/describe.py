"""What a parametric hypothesis says about each lump, with the uncertainties its posterior gives.

Centre, radius (an ellipse's equal-area radius, plus its axes and angle), edge
width and their standard deviations come from the Laplace covariance through
the Jacobian of each reported quantity; the boundary is the lump's 50 % contour
(or, with a supervised τ, its contour at τ).
"""
from __future__ import annotations

import math

import numpy as np

from palpd.estimate import LumpEstimate
from palpd.learner import shapes
from palpd.learner.evidence import Fit

def lumps_of(fit: Fit, tau_n_per_mm: float | None = None) -> list[LumpEstimate]:
    out = []
    for j in range(fit.family.k):
        part = fit.family.lump_slice(j)
        scale = 1.0 if tau_n_per_mm is None else _level_scale(fit, part, tau_n_per_mm)
        if scale is not None:
            out.append(_one(fit.theta[part], fit.cov[part, part], fit.family.kind == "ellipses", scale))
    return out


def quantities(fit: Fit) -> np.ndarray:
    """Rows of the Jacobian of every reported centre coordinate and radius (or axis) w.r.t. θ."""
    rows = []
    for j in range(fit.family.k):
        part = fit.family.lump_slice(j)
        for local in _local_rows(fit.theta[part], fit.family.kind == "ellipses"):
            row = np.zeros(fit.family.size)
            row[part] = local
            rows.append(row)
    return np.array(rows).reshape(-1, fit.family.size)


def _local_rows(params: np.ndarray, ellipse: bool) -> list[np.ndarray]:
    size = len(params)
    cx, cy = np.eye(size)[0], np.eye(size)[1]
    if not ellipse:
        return [cx, cy, math.exp(params[2]) * np.eye(size)[2]]
    return [cx, cy, *_axes_jacobian(params)]


def _axes_jacobian(params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    major, minor, _ = shapes.axes_and_angle(params, ellipse=True)
    e1, e2 = params[3], params[4]
    eps = max(math.hypot(e1, e2), 1e-6)
    d_major, d_minor = np.zeros(len(params)), np.zeros(len(params))
    d_major[2], d_minor[2] = major, minor
    d_major[3:5] = 0.5 * major * np.array([e1, e2]) / eps
    d_minor[3:5] = -0.5 * minor * np.array([e1, e2]) / eps
    return d_major, d_minor


def _one(params: np.ndarray, cov: np.ndarray, ellipse: bool, scale: float) -> LumpEstimate:
    # The centre's sd is its distance from the truth (RMS over both axes), what `--tolerance-mm` bounds: per
    # axis, a lump the scan stopped on at 0.43 mm was 0.56 mm off (touching-lumps seed 2), as a 2-D error is.
    centre_sd = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
    radius = math.exp(params[2]) * scale
    radius_sd = radius * math.sqrt(max(cov[2, 2], 0.0))
    polygon = shapes.boundary_polygon(params, ellipse)
    polygon = params[:2] + (polygon - params[:2]) * scale
    extra = _ellipse_extras(params, cov, scale) if ellipse else {}
    edge, edge_sd = _edge(params, cov)
    return LumpEstimate((float(params[0]), float(params[1])), radius, centre_sd, radius_sd, polygon.tolist(),
                        edge_mm=edge, edge_sd_mm=edge_sd, **extra)


def _sd(row: np.ndarray, cov: np.ndarray) -> float:
    return math.sqrt(max(float(row @ cov @ row), 0.0))


def _ellipse_extras(params: np.ndarray, cov: np.ndarray, scale: float) -> dict:
    major, minor, angle = shapes.axes_and_angle(params, ellipse=True)
    d_major, d_minor = _axes_jacobian(params)
    e1, e2 = params[3], params[4]
    eps2 = max(e1 * e1 + e2 * e2, 1e-12)
    d_angle = np.zeros(len(params))
    d_angle[3:5] = math.degrees(0.5) * np.array([-e2, e1]) / eps2
    return {"axes_mm": (major * scale, minor * scale),
            "axes_sd_mm": (_sd(d_major, cov) * scale, _sd(d_minor, cov) * scale),
            "angle_deg": angle, "angle_sd_deg": min(_sd(d_angle, cov), 90.0)}


def _edge(params: np.ndarray, cov: np.ndarray) -> tuple[float, float]:
    edge = shapes.edge_width_mm(params)
    row = np.zeros(len(params))
    for i in (2, len(params) - 3, len(params) - 2):  # size, tail, sharpness: numerically, it is one number
        step = np.zeros(len(params))
        step[i] = 1e-6
        row[i] = (shapes.edge_width_mm(params + step) - shapes.edge_width_mm(params - step)) / 2e-6
    return edge, _sd(row, cov)


def _level_scale(fit: Fit, part: slice, tau_n_per_mm: float) -> float | None:
    """How far out (in units of the 50 % boundary) the lump's stiffness falls to τ; None if it never reaches τ."""
    params = fit.theta[part]
    base = math.exp(float(shapes.background(fit.theta, params[None, :2], fit.family.scale_mm)[0]))
    p = (tau_n_per_mm / base - 1.0) / math.exp(params[-1])
    if p >= 1.0:
        return None
    if p <= 0.0:
        return 1.0
    return shapes.rho_at(params, math.log((1.0 - p) / p))
