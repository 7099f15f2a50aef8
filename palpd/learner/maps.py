"""The posterior over the grid that plots and the live view draw: stiffness, its sd and P(lump).

The map is the chosen hypothesis's: for a parametric model its prediction, the
linearised sd and, per cell, the probability of lying inside a lump's 50 %
boundary (ρ < 1 with log ρ² normal under the Laplace posterior); for the
free-form model (and for `none`, against the softest contrast that would count
as a lump; for `none+soft:1`, that contrast over the fitted tissue around the soft
region) the GP's mean, sd and Φ((μ − log τ)/σ).
"""
from __future__ import annotations

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
    var = ((jac @ fit.cov) * jac).sum(axis=1)
    p = inside_probability(fit, grid_xy)
    return _grid(xs, ys, f, var, p)


def from_log_field(xs, ys, mean_log: np.ndarray, var_log: np.ndarray, tau_log: np.ndarray) -> PosteriorGrid:
    p = ndtr((mean_log - tau_log) / np.sqrt(np.maximum(var_log, 1e-300)))
    return _grid(xs, ys, mean_log, var_log, p)


def inside_probability(fit, xy: np.ndarray) -> np.ndarray:
    """P(ρ_j < 1) of the lump felt most at each point (0 for `none`)."""
    family = fit.family
    if family.k == 0:
        return np.zeros(len(xy))
    heights = shapes.heights_of(family, fit.theta, xy)
    top = np.argmax(heights, axis=1)
    p = np.zeros(len(xy))
    for j in range(family.k):
        rows = top == j
        part = family.lump_slice(j)
        lr2, d = shapes.log_rho2(fit.theta[part], xy[rows], family.kind == "ellipses")
        cov = fit.cov[part, part][: d.shape[1], : d.shape[1]]
        sd = np.sqrt(np.maximum(((d @ cov) * d).sum(axis=1), 1e-12))
        p[rows] = ndtr(-lr2 / sd)
    return p


def _grid(xs, ys, mean_log, var_log, p) -> PosteriorGrid:
    shape = (len(ys), len(xs))
    median = np.exp(mean_log)
    return PosteriorGrid(xs, ys, median.reshape(shape), (median * np.sqrt(np.maximum(var_log, 0.0))).reshape(shape),
                         p.reshape(shape))
