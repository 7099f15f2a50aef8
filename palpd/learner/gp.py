"""A Gaussian process over (x, y) of log stiffness, updated one point at a time on a fixed grid.

The kernel is a Matérn 5/2 field on a background plane whose level and slopes
have the same Gaussian priors as the parametric models' (so the GP's marginal
likelihood is the evidence of "background plus a free-form field", comparable
with theirs). With the kernel fixed, adding a point appends one row to the
Cholesky factor L, to w = L⁻¹(y − m) and to V = L⁻¹ K(points, grid); the grid's
posterior mean and variance change by v·w and −v² for the new row v: O(n·G).
A refit (new kernel) builds everything in one block: one Cholesky of K + D and
one triangular solve for [y − m | K(points, grid)]; only when that factor is
not positive definite (the same spot probed twice with no noise) does it fall
back to the row-by-row path, whose floor on each pivot keeps it finite.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky, solve_triangular

from palpd.learner.likelihood import gaussian_log_density

JITTER = 1e-9  # keeps the factor positive definite when a point is probed twice with zero noise
BLOCK_ROWS = 128  # V grows by blocks of rows (float32: a gemv over it is memory-bound, half the bytes is half the time)
PENDING_ROWS = 8  # rows of V left pending at most: a flush of n rows after a long wait cost 40 ms at 650 points
SQRT5 = math.sqrt(5.0)
LOG_2PI = math.log(2.0 * math.pi)
MAX_RESTARTS = 3  # fit_hyper: fresh L-BFGS-B starts from where the last one stopped, while they still gain


@dataclass(frozen=True)
class Hyper:
    mean: float            # prior mean of log stiffness (the background level's prior centre)
    signal_var: float      # Matérn field variance, (log units)²
    length_mm: float
    white_var: float       # noise beyond each point's own fit uncertainty, (log units)²
    level_var: float = 4.0     # background level prior variance (evidence.LEVEL_SD²)
    slope_var: float = 0.0625  # background slope prior variance, per half-size (evidence.SLOPE_SD²)
    scale_mm: float = 30.0     # the half-size the slopes are per


def kernel(a: np.ndarray, b: np.ndarray, hyper: Hyper) -> np.ndarray:
    r = np.sqrt(np.maximum(_sq_dist(a, b), 0.0)) * (SQRT5 / hyper.length_mm)
    plane = hyper.level_var + hyper.slope_var * (a @ b.T) / hyper.scale_mm**2
    return _matern(r, hyper) + plane


def _matern(r: np.ndarray, hyper: Hyper) -> np.ndarray:
    """The Matérn 5/2 part at scaled distances r = √5·d/ℓ."""
    return hyper.signal_var * (1.0 + r + r * r / 3.0) * np.exp(-r)


def lattice_steps(cells: np.ndarray) -> tuple[np.ndarray, int, float, float] | None:
    """For cells on a regular lattice: (each pair's offset in steps as one index, |i_a − i_b|·rows + |j_a − j_b|;
    rows; the step along x; along y), or None if they are not on one. Made once a lattice: the Matérn part of
    the kernel depends on the offset alone, so a new kernel is read off a table of the offsets (`lattice_kernel`)
    rather than computed pair by pair (~900 × 900 pairs on a 60 mm tissue: 15 ms → 5)."""
    steps = []
    for axis in (0, 1):
        values = np.unique(cells[:, axis])
        step = float(np.min(np.diff(values))) if len(values) > 1 else 1.0
        index = np.rint((cells[:, axis] - values[0]) / step).astype(np.int32)
        if not np.allclose(values[0] + index * step, cells[:, axis], rtol=0.0, atol=1e-9 * step):
            return None
        steps.append((index, step))
    (i, dx), (j, dy) = steps
    rows = int(j.max()) + 1
    offsets = np.abs(i[:, None] - i[None, :]) * np.int32(rows) + np.abs(j[:, None] - j[None, :])
    return offsets, rows, dx, dy


def lattice_kernel(cells: np.ndarray, offsets: np.ndarray, rows: int, dx: float, dy: float,
                   hyper: Hyper) -> np.ndarray:
    """kernel(cells, cells) for cells on a regular lattice (`lattice_steps`): the Matérn part read off a table
    of the offsets, the background plane as `kernel` adds it."""
    i, j = np.divmod(np.arange(int(offsets.max()) + 1), rows)
    r = np.hypot(i * dx, j * dy) * (SQRT5 / hyper.length_mm)
    prior = _matern(r, hyper)[offsets]
    plane = cells @ cells.T  # (in place: each pair-sized array a fresh 7 MB on a 60 mm tissue)
    plane *= hyper.slope_var / hyper.scale_mm**2
    prior += plane
    prior += hyper.level_var
    return prior


def kernel_to_grid(p: np.ndarray, grid_xy: np.ndarray, hyper: Hyper) -> np.ndarray:
    """kernel(p, grid) for one point, without the n×G distance matrix product (float32: V is float32 too)."""
    grid = grid_xy.astype(np.float32) if grid_xy.dtype != np.float32 else grid_xy
    to_r = np.float32(SQRT5 / hyper.length_mm)
    r = np.hypot(grid[:, 0] - np.float32(p[0]), grid[:, 1] - np.float32(p[1])) * to_r
    slope = np.float32(hyper.slope_var / hyper.scale_mm**2)
    plane = np.float32(hyper.level_var) + slope * (grid @ p.astype(np.float32))
    return np.float32(hyper.signal_var) * (1.0 + r + r * r / np.float32(3.0)) * np.exp(-r) + plane


def prior_var(grid_xy: np.ndarray, hyper: Hyper) -> np.ndarray:
    return hyper.signal_var + hyper.level_var + hyper.slope_var * (grid_xy * grid_xy).sum(1) / hyper.scale_mm**2


def _sq_dist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T


class IncrementalGP:
    """Posterior mean and variance of the latent log stiffness on `grid_xy` (G × 2)."""

    def __init__(self, grid_xy: np.ndarray, hyper: Hyper) -> None:
        self.grid_xy = np.ascontiguousarray(grid_xy, dtype=float)
        self._grid32 = self.grid_xy.astype(np.float32)
        self.hyper = hyper
        self._lattice_prior = None  # (lattice, hyper, its prior kernel): lattice_covariance
        self._lattice_steps = None  # (lattice, lattice_steps of its cells)
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
        if self._pending >= PENDING_ROWS:
            self._flush()

    @property
    def mean(self) -> np.ndarray:
        self._flush()
        return self._mean

    @property
    def var(self) -> np.ndarray:
        self._flush()
        return self._var

    def refit(self, hyper: Hyper) -> None:
        """New kernel: one Cholesky and one triangular solve (row by row only for a singular factor)."""
        self.hyper = hyper
        self._reset_factor(capacity=max(64, 2 * self.n))
        if self.n and not self._block_factor():
            self._reset_factor(capacity=max(64, 2 * self.n))
            for i in range(self.n):
                self._append_row(i)

    def std(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.var, 1e-12 * self.hyper.signal_var))

    def covariance(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Posterior covariance of the latent log stiffness between grid cells a and b (index arrays):
        the prior kernel less V[:, a]ᵀ V[:, b], V = L⁻¹ K(points, grid) as kept for the mean and variance."""
        self._flush()
        return self._posterior(kernel(self.grid_xy[a], self.grid_xy[b], self.hyper), a, b)

    def lattice_covariance(self, lattice: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """`covariance` between the cells lattice[a] and lattice[b] (a and b index the lattice), its prior kernel
        over the whole lattice computed once while the kernel holds: a fixed lattice asked at every update (the
        free-form map's probe score, ~900 × 900 cells of a 60 mm tissue, whose kernel was 15-20 ms of it)."""
        self._flush()
        return self._posterior(self.hold_lattice(lattice)[np.ix_(a, b)], lattice[a], lattice[b])  # one copy, not two

    def hold_lattice(self, lattice: np.ndarray) -> np.ndarray:
        """The prior kernel over the lattice that `lattice_covariance` reads, made unless held for this lattice
        and kernel, read off a table of the lattice's offsets (lattice_steps, made once a lattice). The learner
        asks it as it is made (~5 ms for a 60 mm tissue's offsets, ~7 for the kernel), so that the first
        update, whose kernel is the one the learner was made with, pays neither."""
        if self._lattice_steps is None or self._lattice_steps[0] is not lattice:
            self._lattice_steps = (lattice, lattice_steps(self.grid_xy[lattice]))
        held = self._lattice_prior
        if held is None or held[0] is not lattice or held[1] != self.hyper:
            cells, steps = self.grid_xy[lattice], self._lattice_steps[1]
            prior = kernel(cells, cells, self.hyper) if steps is None else lattice_kernel(cells, *steps, self.hyper)
            held = self._lattice_prior = (lattice, self.hyper, prior)
        return held[2]

    def _posterior(self, prior: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The prior covariance of grid cells a and b (`prior`, a fresh array: taken over) less what the points
        have told of both. In place: a first update's arrays are ~900 × 900, each a fresh 7 MB whose page
        faults that update pays."""
        if self.n:
            prior -= self._columns(a).T @ self._columns(b)
        return prior

    def _columns(self, cells: np.ndarray) -> np.ndarray:
        """V's columns for the cells (n × len(cells)), in float64."""
        return np.concatenate([block[:, cells] for block in self._blocks])[:self.n].astype(np.float64)

    def log_marginal_likelihood(self) -> float:
        """log p(y | kernel): the evidence of the free-form model at this kernel."""
        n = self.n
        w = self._w[:n]
        return float(-0.5 * w @ w - self._log_det - 0.5 * n * LOG_2PI)

    def loo_log_density(self) -> np.ndarray:
        """Each point's log density under the predictive of the others (the kernel fixed), in closed form from
        the factor (Rasmussen & Williams 2006, 5.4.2): with K = LLᵀ, α = K⁻¹(y − m), the point left out is
        predicted at y_i − α_i / [K⁻¹]_ii with variance 1 / [K⁻¹]_ii. O(n³/3) for L⁻¹: asked only when a
        choice fails its predictive check (decision.drawn_by)."""
        n = self.n
        inverse = solve_triangular(self._L[:n, :n], np.eye(n), lower=True, check_finite=False)  # L⁻¹
        precision = np.einsum("ij,ij->j", inverse, inverse)  # diag K⁻¹ = diag L⁻ᵀL⁻¹
        alpha = inverse.T @ self._w[:n]  # K⁻¹(y − m) = L⁻ᵀ w
        return gaussian_log_density(alpha / precision, 1.0 / precision)

    def _self_var(self, i: int) -> float:
        h = self.hyper
        p = self.xy[i]
        return float(h.signal_var + h.level_var + h.slope_var * (p @ p) / h.scale_mm**2
                     + h.white_var + self.noise_var[i] + JITTER * h.signal_var)

    def _block_factor(self) -> bool:
        n, h = self.n, self.hyper
        k = kernel(self.xy, self.xy, h)
        k[np.diag_indices(n)] = [self._self_var(i) for i in range(n)]
        try:
            low = cholesky(k, lower=True, check_finite=False)
        except LinAlgError:
            return False
        rhs = np.empty((n, 1 + len(self.grid_xy)))
        rhs[:, 0] = self.y - h.mean
        rhs[:, 1:] = self._kernel_to_grid(0, n)
        solved = solve_triangular(low, rhs, lower=True, check_finite=False, overwrite_b=True)
        self._L[:n, :n], self._w[:n] = low, solved[:, 0]
        self._log_det = float(np.sum(np.log(np.diag(low))))
        for start in range(0, n, BLOCK_ROWS):
            block = np.zeros((BLOCK_ROWS, len(self.grid_xy)), dtype=np.float32)
            part = solved[start:start + BLOCK_ROWS, 1:]
            block[:len(part)] = part
            self._blocks.append(block)
        grid_part = solved[:, 1:]
        self._mean = h.mean + grid_part.T @ solved[:, 0]
        self._var = prior_var(self.grid_xy, h) - np.einsum("ij,ij->j", grid_part, grid_part)
        return True

    def _reset_factor(self, capacity: int) -> None:
        self._L = np.zeros((capacity, capacity))
        self._w = np.zeros(capacity)
        self._log_det = 0.0
        self._blocks: list[np.ndarray] = []  # V = L⁻¹ K(points, grid) in float32 row blocks: no copy as it grows
        self._mean = np.full(len(self.grid_xy), self.hyper.mean)
        self._var = prior_var(self.grid_xy, self.hyper)
        self._pending = 0  # rows n − _pending … n − 1 are in the factor but not yet in V, mean and var

    def _append_row(self, i: int) -> None:
        """Row i of the factor, of w and of log det: O(i²). Its row of V = L⁻¹ K(points, grid), O(i·G),
        waits until the grid is asked for or PENDING_ROWS are pending (_flush): while a parametric model
        is chosen, most updates never look at the free-form map."""
        if i >= self._L.shape[0]:
            self._grow(2 * self._L.shape[0])
        h, p = self.hyper, self.xy[i:i + 1]
        k_old = kernel(self.xy[:i], p, h)[:, 0]
        row = solve_triangular(self._L[:i, :i], k_old, lower=True, check_finite=False) if i else k_old
        d = math.sqrt(max(self._self_var(i) - float(row @ row), JITTER * h.signal_var))
        self._L[i, :i], self._L[i, i] = row, d
        self._log_det += math.log(d)
        self._w[i] = (self.y[i] - h.mean - float(row @ self._w[:i])) / d
        self._pending += 1

    def _flush(self) -> None:
        """The pending rows of V in one block: V_p = L_pp⁻¹ (K(p, grid) − L_p,old V_old), then the
        grid's mean and variance: one matrix product instead of a vector product per row."""
        if not self._pending:
            return
        n, first = self.n, self.n - self._pending
        k_new = self._kernel_to_grid(first, n)
        if first:
            k_new -= self._project(self._L[first:n, :first])
        v = solve_triangular(self._L[first:n, first:n], k_new.astype(np.float64), lower=True, check_finite=False)
        for offset, row in enumerate(v):
            self._store(first + offset, row)
        self._mean += v.T @ self._w[first:n]
        self._var -= np.einsum("ij,ij->j", v, v)
        self._pending = 0

    def _kernel_to_grid(self, first: int, stop: int) -> np.ndarray:
        """kernel(points first … stop − 1, grid) in float32: V is kept in float32, and half the bytes
        make the n×G kernel of a refit half its cost (in float64 it was about half of the refit)."""
        return np.stack([kernel_to_grid(self.xy[i], self._grid32, self.hyper) for i in range(first, stop)])

    def _project(self, rows: np.ndarray) -> np.ndarray:
        """rows @ V[:rows.shape[1]] over the row blocks (float32, as V is kept)."""
        out = np.zeros((len(rows), len(self.grid_xy)), dtype=np.float32)
        rows32 = rows.astype(np.float32)
        for b, block in enumerate(self._blocks):
            part = rows32[:, b * BLOCK_ROWS:(b + 1) * BLOCK_ROWS]
            if part.size:
                out += part @ block[:part.shape[1]]
        return out

    def _store(self, i: int, v: np.ndarray) -> None:
        if i // BLOCK_ROWS >= len(self._blocks):
            self._blocks.append(np.zeros((BLOCK_ROWS, len(self.grid_xy)), dtype=np.float32))
        self._blocks[i // BLOCK_ROWS][i % BLOCK_ROWS] = v

    def _grow(self, capacity: int) -> None:
        n = self._L.shape[0]
        L, w = self._L, self._w
        self._L = np.zeros((capacity, capacity))
        self._L[:n, :n] = L
        self._w = np.zeros(capacity)
        self._w[:n] = w


def fit_hyper(xy: np.ndarray, y: np.ndarray, noise_var: np.ndarray, start: Hyper,
              length_bounds_mm: tuple[float, float], white_floor_var: float) -> Hyper:
    """Maximum-marginal-likelihood Matérn field variance, length scale and white noise, the background
    plane's priors fixed: L-BFGS-B on their logs from `start`, within bounds, with the exact gradient.

    This is scikit-learn's GaussianProcessRegressor.fit for the kernel
    C·Matérn(ν=5/2) + plane + White (same parametrisation, bounds, objective and optimiser call; a test
    holds the two together), written over this module's kernel so that a learner does not import
    scikit-learn: its import (with scipy.stats) cost every daemon and scan process ~0.75 s of CPU.
    """
    from scipy.optimize import minimize  # here: slow to import (~0.5 s), and only a relearn needs it (a Learner
    #                                        imports it as it is built, so that no update pays for it)

    scale = start.scale_mm  # the optimiser works in half-sizes, where the plane's slopes are per unit
    u = xy / scale
    n = len(u)
    distance = np.sqrt(np.maximum(_sq_dist(u, u), 0.0))
    plane = start.level_var + start.slope_var * (u @ u.T)
    diagonal = np.diag_indices(n)
    residual = y - start.mean
    bounds = np.log([(1e-6, 1e2), (length_bounds_mm[0] / scale, length_bounds_mm[1] / scale),
                     (white_floor_var, max(1.0, 2.0 * white_floor_var))])
    theta0 = np.clip(np.log([start.signal_var, start.length_mm / scale, start.white_var]), bounds[:, 0], bounds[:, 1])

    def negative_lml_and_gradient(theta: np.ndarray):
        signal_var, length, white_var = np.exp(theta)
        r = (SQRT5 / length) * distance
        decay = np.exp(-r)
        matern = (1.0 + r + r * r / 3.0) * decay
        k = signal_var * matern + plane
        k[diagonal] += white_var + noise_var + JITTER
        try:
            factor = cholesky(k, lower=True, check_finite=False)
        except LinAlgError:
            return np.inf, np.zeros(3)
        alpha = cho_solve((factor, True), residual, check_finite=False)
        lml = -0.5 * residual @ alpha - np.log(np.diag(factor)).sum() - 0.5 * n * LOG_2PI
        inner = np.outer(alpha, alpha) - cho_solve((factor, True), np.eye(n), check_finite=False)
        gradient = 0.5 * np.array([(inner * (signal_var * matern)).sum(),  # ∂K/∂log σ²
                                   (inner * (signal_var * r * r / 3.0 * (1.0 + r) * decay)).sum(),  # ∂K/∂log ℓ
                                   white_var * np.trace(inner)])  # ∂K/∂log white = white · I
        return -lml, -gradient

    # L-BFGS-B sometimes stops on a step that barely lowered the objective (its "relative reduction" test)
    # with the gradient far from zero: its curvature memory misled the line search on a ridge, e.g. 0.05 nat
    # short with ∂/∂log white = 0.08. Started again from there, with the memory cleared, it goes on; a
    # converged start ends in one or two evaluations.
    result = minimize(negative_lml_and_gradient, theta0, jac=True, method="L-BFGS-B", bounds=bounds)
    for _ in range(MAX_RESTARTS):
        again = minimize(negative_lml_and_gradient, result.x, jac=True, method="L-BFGS-B", bounds=bounds)
        if not again.fun < result.fun - 1e-9 * max(1.0, abs(result.fun)):
            break
        result = again
    signal_var, length, white_var = np.exp(result.x)
    return Hyper(start.mean, float(signal_var), float(length) * scale, float(white_var), start.level_var,
                 start.slope_var, start.scale_mm)
