"""A Gaussian process over (x, y) that is updated one point at a time on a fixed candidate grid.

With the prior mean and the kernel hyperparameters held fixed, adding a point
appends one row to the Cholesky factor L, to w = L⁻¹(y − m) and to
V = L⁻¹ K(points, grid); the grid's posterior mean and variance then change by
v·w and −v² for the new row v. One update costs O(n·G) instead of the O(n²·G)
of a refit, which is what keeps the learner within its latency budget at a few
hundred points. Hyperparameters are refitted (scikit-learn's marginal-likelihood
optimiser) only when the caller decides it pays; a refit rebuilds everything.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular

JITTER = 1e-9  # keeps the factor positive definite when a point is probed twice with zero noise
SQRT5 = math.sqrt(5.0)


@dataclass(frozen=True)
class Hyper:
    mean: float            # prior mean (N/mm): the tissue level
    signal_var: float      # (N/mm)²
    length_mm: float
    white_var: float       # noise beyond each point's own fit uncertainty, (N/mm)²


def matern52(a: np.ndarray, b: np.ndarray, hyper: Hyper) -> np.ndarray:
    r = np.sqrt(np.maximum(_sq_dist(a, b), 0.0)) * (SQRT5 / hyper.length_mm)
    return hyper.signal_var * (1.0 + r + r * r / 3.0) * np.exp(-r)


def _sq_dist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T


class IncrementalGP:
    """Posterior mean and variance of the latent field on `grid_xy` (G × 2)."""

    def __init__(self, grid_xy: np.ndarray, hyper: Hyper) -> None:
        self.grid_xy = np.ascontiguousarray(grid_xy, dtype=float)
        self.hyper = hyper
        self.xy = np.empty((0, 2))
        self.y = np.empty(0)
        self.noise_var = np.empty(0)
        self._reset_factor(capacity=64)

    @property
    def n(self) -> int:
        return len(self.y)

    def add(self, xy, y: float, noise_var: float) -> None:
        self.xy = np.vstack([self.xy, np.asarray(xy, dtype=float).reshape(1, 2)])
        self.y = np.append(self.y, float(y))
        self.noise_var = np.append(self.noise_var, max(float(noise_var), 0.0))
        self._append_row(self.n - 1)

    def refit(self, hyper: Hyper) -> None:
        """New hyperparameters: rebuild the factor and the grid posterior from all points."""
        self.hyper = hyper
        self._reset_factor(capacity=max(64, 2 * self.n))
        for i in range(self.n):
            self._append_row(i)

    def std(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.var, 1e-12 * self.hyper.signal_var))

    def _reset_factor(self, capacity: int) -> None:
        self._L = np.zeros((capacity, capacity))
        self._V = np.zeros((capacity, len(self.grid_xy)))
        self._w = np.zeros(capacity)
        self.mean = np.full(len(self.grid_xy), self.hyper.mean)
        self.var = np.full(len(self.grid_xy), self.hyper.signal_var)

    def _append_row(self, i: int) -> None:
        if i >= self._L.shape[0]:
            self._grow(2 * self._L.shape[0])
        h, p = self.hyper, self.xy[i:i + 1]
        k_old = matern52(self.xy[:i], p, h)[:, 0]
        row = solve_triangular(self._L[:i, :i], k_old, lower=True, check_finite=False) if i else k_old
        k_self = h.signal_var + h.white_var + self.noise_var[i] + JITTER * h.signal_var
        d = math.sqrt(max(k_self - float(row @ row), JITTER * h.signal_var))
        self._L[i, :i], self._L[i, i] = row, d
        self._w[i] = (self.y[i] - h.mean - float(row @ self._w[:i])) / d
        v = matern52(p, self.grid_xy, h)[0]
        if i:
            v -= row @ self._V[:i]
        v /= d
        self._V[i] = v
        self.mean += v * self._w[i]
        self.var -= v * v

    def _grow(self, capacity: int) -> None:
        n = self._L.shape[0]
        L, V, w = self._L, self._V, self._w
        self._L = np.zeros((capacity, capacity))
        self._L[:n, :n] = L
        self._V = np.zeros((capacity, V.shape[1]))
        self._V[:n] = V
        self._w = np.zeros(capacity)
        self._w[:n] = w


def fit_hyper(xy: np.ndarray, y: np.ndarray, noise_var: np.ndarray, mean: float, start: Hyper,
              length_bounds_mm: tuple[float, float], min_signal_sd: float) -> Hyper:
    """Maximum-marginal-likelihood kernel for the points, with the prior mean given.

    The signal is held at least `min_signal_sd`, so a field that looks flat so far
    still admits a lump of the smallest contrast that matters where it was not probed.
    """
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    scale = max(float(np.std(y)), min_signal_sd, 1e-9)  # the optimiser works in units of the data's spread
    signal_bounds = ((min_signal_sd / scale) ** 2, 100.0)
    kernel = (ConstantKernel(float(np.clip(start.signal_var / scale**2, *signal_bounds)), signal_bounds)
              * Matern(float(np.clip(start.length_mm, *length_bounds_mm)), length_bounds_mm, nu=2.5)
              + WhiteKernel(float(np.clip(start.white_var / scale**2, 1e-6, 1.0)), (1e-6, 1.0)))
    gpr = GaussianProcessRegressor(kernel, alpha=noise_var / scale**2 + 1e-10, normalize_y=False)
    with warnings.catch_warnings():  # a bound reached is an answer here, not a problem
        warnings.simplefilter("ignore", ConvergenceWarning)
        gpr.fit(xy, (y - mean) / scale)
    k = gpr.kernel_
    return Hyper(mean, k.k1.k1.constant_value * scale**2, float(k.k1.k2.length_scale),
                 k.k2.noise_level * scale**2)
