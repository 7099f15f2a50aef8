"""The posterior over the grid that plots and the live view draw: stiffness, its sd and P(lump).

The map is the chosen hypothesis's: for a parametric model its prediction, the
linearised sd and, per cell, the probability of lying inside a lump's 50 %
boundary (ρ < 1 with log ρ² normal under the Laplace posterior); for the
free-form model (and for `none`, against the softest contrast that would count
as a lump; for `none+soft:1`, that contrast over the fitted tissue around the soft
region) the GP's mean, sd and Φ((μ − log τ)/σ).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from palpd.learner import shapes


@dataclass(frozen=True)
class PosteriorGrid:
    xs: np.ndarray       # grid columns (mm)
    ys: np.ndarray       # grid rows (mm)
    mean: np.ndarray     # (ny, nx) stiffness, N/mm (the posterior median)
    sd: np.ndarray       # (ny, nx) N/mm
    p_lump: np.ndarray   # (ny, nx) P(inside a lump)


def parametric(fit, xs: np.ndarray, ys: np.ndarray, grid_xy: np.ndarray) -> PosteriorGrid:
    f, jac = shapes.evaluate(fit.family, fit.theta, grid_xy)
    var = shapes.row_variances(jac, fit.cov)
    p = inside_probability(fit, xs, ys)
    return _grid(xs, ys, f, var, p)


def from_log_field(xs, ys, mean_log: np.ndarray, var_log: np.ndarray, tau_log: np.ndarray) -> PosteriorGrid:
    p = ndtr((mean_log - tau_log) / np.sqrt(np.maximum(var_log, 1e-300)))
    return _grid(xs, ys, mean_log, var_log, p)


def inside_probability(fit, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """P(ρ_j < 1) of the lump felt most at each cell of the (len(ys) × len(xs), row-major) grid, flattened (0
    for `none`). Computed only within each lump's reach (`_reach_mm`), beyond which it is below Φ(−5)
    whatever the posterior, and that reach looked for only in the window of rows and columns that can hold
    it (as acquisition.block_near does): over a 121² grid the whole map cost ~4 ms an update, and the stop
    rule asks for it at every one."""
    family = fit.family
    if family.k == 0:
        return np.zeros(len(ys) * len(xs))
    near = np.zeros((len(ys), len(xs)), dtype=bool)
    ellipse = family.kind == "ellipses"
    for j in range(family.k):
        params = fit.theta[family.lump_slice(j)]
        reach = _reach_mm(params, fit.cov[family.lump_slice(j), family.lump_slice(j)], ellipse)
        cols = slice(np.searchsorted(xs, params[0] - reach), np.searchsorted(xs, params[0] + reach, side="right"))
        rows = slice(np.searchsorted(ys, params[1] - reach), np.searchsorted(ys, params[1] + reach, side="right"))
        near[rows, cols] |= np.hypot(xs[None, cols] - params[0], ys[rows, None] - params[1]) <= reach
    p = np.zeros(near.size)
    at = np.flatnonzero(near)
    if not len(at):
        return p
    xy_near = np.column_stack([xs[at % len(xs)], ys[at // len(xs)]])
    # the lump felt most at each cell: with one lump, that one (its heights need not be computed)
    top = np.zeros(len(at), dtype=int) if family.k == 1 else np.argmax(shapes.heights_of(family, fit.theta, xy_near), axis=1)
    p_near = np.zeros(len(xy_near))
    for j in range(family.k):
        rows = top == j
        part = family.lump_slice(j)
        lr2, d = shapes.log_rho2(fit.theta[part], xy_near[rows], ellipse)
        cov = fit.cov[part, part][: d.shape[1], : d.shape[1]]
        sd = np.sqrt(np.maximum(shapes.row_variances(d, cov), 1e-12))
        p_near[rows] = ndtr(-lr2 / sd)
    p[at] = p_near
    return p


def _reach_mm(params: np.ndarray, cov: np.ndarray, ellipse: bool) -> float:
    """How far from a lump's centre P(inside it) may still exceed Φ(−5): its major semi-axis grown by 5 sd of
    log ρ² far out (2 sd of log R, and of the ellipse's eccentricity terms), plus 5 sd of its centre."""
    major = shapes.axes_and_angle(params, ellipse)[0]
    shape_sd = 2.0 * math.sqrt(max(cov[2, 2], 0.0)) + (math.sqrt(max(cov[3, 3] + cov[4, 4], 0.0)) if ellipse else 0.0)
    centre_sd = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
    return major * math.exp(min(2.5 * shape_sd, 5.0)) + 5.0 * centre_sd + 1.0


def _grid(xs, ys, mean_log, var_log, p) -> PosteriorGrid:
    shape = (len(ys), len(xs))
    median = np.exp(mean_log)
    return PosteriorGrid(xs, ys, median.reshape(shape), (median * np.sqrt(np.maximum(var_log, 0.0))).reshape(shape),
                         p.reshape(shape))
