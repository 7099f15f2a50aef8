"""Where to palpate once readings come in (the first design is design.py's): where a reading teaches the most.

- While the hypotheses disagree (the chosen one's weight is below the
  confidence asked for), where their predictions differ most relative to the
  noise and their own uncertainty: ½·log(1 + Var_m[μ_m] / (σ² + E_m[v_m])), the
  information a reading carries about which hypothesis is right (BALD).
- Once one is chosen, where a reading shrinks the posterior variance of what
  is reported the most: for a parametric model the summed variance of every
  centre coordinate and radius (or axis), |W Σ g|² / (gᵀ Σ g + σ²) with g the
  model's gradient there (the lumps' boundaries, naturally); for the free-form
  map, the loss the stop rule reads itself: the misclassified area
  ∫ min(P, 1 − P) dA a reading is expected to take off, through the GP's
  posterior covariance between the reading and each cell in doubt (Bryan et
  al.'s straddle, z·σ − |μ − τ|, where no cell is).

Every score is divided by the robot time the move adds (travel at the travel
speed, in units of one palpation), and cells closer than the minimum spacing to
an earlier probe are never chosen again.
"""
from __future__ import annotations

import functools
from statistics import NormalDist

import numpy as np
from scipy.special import ndtr, owens_t

from palpd.learner import shapes
from palpd.learner.describe import quantities

MIN_CORRELATION = 0.02  # a reading correlated with a cell by less is not counted for it (at most ρ/π of its area)
AREA_BLOCK_CELLS = 64  # cells read at a time while nearly every pair counts (misclassified_area_gain)
TAKEN_Z_MAX = 4.0  # |z| of the table of what a reading takes off a cell (Φ(−4) = 3e-5: not in doubt past it)


def moments(fit, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A parametric fit's predicted log stiffness at xy, its linearised variance and its gradient."""
    f, jac = shapes.evaluate(fit.family, fit.theta, xy)
    return f, shapes.row_variances(jac, fit.cov), jac


def boundary_gain(fit, xy: np.ndarray, noise_var: float, size_mm=None) -> np.ndarray:
    """Total variance (mm²) taken off the reported centres and radii by one reading at each cell."""
    _, var, jac = moments(fit, xy)
    w = quantities(fit, size_mm)
    if len(w) == 0:
        return np.zeros(len(xy))
    projected = jac @ (fit.cov @ w.T)  # (cells × quantities): cov(quantity, reading)
    return np.einsum("ij,ij->i", projected, projected) / (var + noise_var)


def misclassified_area_gain(cov: np.ndarray, var_candidates: np.ndarray, noise_var: float, z: np.ndarray,
                            var_cells: np.ndarray, cell_area_mm2: float, overwrite_cov: bool = False) -> np.ndarray:
    """The misclassified area (mm²) one reading at each candidate is expected to take off: the stop rule's
    ∫ min(P, 1 − P) dA over cells x, where P = Φ(z_x), z_x = (μ_x − τ_x)/σ_x of a Gaussian field.

    A reading at c moves μ_x by a normal of sd s = |cov(x, c)| / √(var_c + noise) and leaves σ_x'² = σ_x² − s².
    Averaged over that move, min(P', 1 − P') is the chance the field and its new mean lie on opposite sides of
    τ, a bivariate normal's two orthants (correlation ρ = s/σ_x), which is 2·T(|z_x|, √(1 − ρ²)/ρ), T Owen's
    function: min(P, 1 − P) itself at ρ = 0, nothing at ρ = 1 (`_area_taken`). cov is candidates × cells; pairs
    correlated by under MIN_CORRELATION are skipped (each would take at most ρ/π of its cell's area off, at the
    boundary itself: on the half-stiff and garg maps the best candidate's gain moved by 0.02 mm² of 1-11).
    `overwrite_cov`: cov is the caller's to give up, and holds the correlations after (one fresh array fewer)."""
    rho = np.abs(cov, out=cov) if overwrite_cov else np.abs(cov)
    rho /= np.sqrt(var_candidates + noise_var)[:, None]
    rho /= np.sqrt(var_cells)[None, :]
    counted = rho > MIN_CORRELATION
    z = np.abs(z)
    if np.count_nonzero(counted) > 0.5 * counted.size:  # the first readings: nearly every pair, summed in place
        rho[~counted] = 0.0  # (the table's ρ = 0 column is 0: nothing taken)
        # what each pair takes, read a band of cells at a time: a band's rows of the table interpolated at its
        # cells' z (AREA_BLOCK_CELLS × 361) stay in the cache while every candidate reads them, where all the
        # cells' rows (2.8 MB on a 60 mm tissue) did not: the same values, summed as before (18-22 ms → 8-13)
        for start in range(0, len(z), AREA_BLOCK_CELLS):  # each band's ρ replaced by what its pairs take
            band = slice(start, start + AREA_BLOCK_CELLS)
            rho[:, band] = _area_taken(z[band], np.arange(len(z[band]))[None, :], rho[:, band])
        return cell_area_mm2 * rho.sum(axis=1)
    rows, cols = np.nonzero(counted)  # later ones: a reading's correlations fall off, pairs are fewer
    return cell_area_mm2 * np.bincount(rows, weights=_area_taken(z, cols, rho[rows, cols]),
                                       minlength=len(var_candidates))


def _area_taken(z: np.ndarray, cells: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Φ(−z) − 2·T(z, √(1 − ρ²)/ρ) for each pair (its cell's z ≥ 0 by `cells`, its 0 ≤ ρ ≤ 1; `cells` and `rho`
    broadcast together: a list of pairs, or a row of cells against candidates × cells), read off a table
    by bilinear interpolation (within 3e-4 of Owen's T, which cost 100 ns a pair, ~40 ms an update of the
    free-form map). Rows |z| up to TAKEN_Z_MAX (a cell further out is not in doubt), columns θ = asin ρ. A cell's
    z is the same for every candidate, so the table is interpolated along z once a cell, and a pair reads its
    cell's row at its θ: two look-ups a pair, not four (the first readings leave every cell correlated with
    every candidate through the prior's level and slopes: ~900 × 900 pairs on a 60 mm tissue)."""
    table = area_taken_table()
    rows, cols = table.shape
    fz = np.minimum(z, TAKEN_Z_MAX) * ((rows - 1) / TAKEN_Z_MAX)
    iz = np.minimum(fz.astype(np.intp), rows - 2)
    dz = (fz - iz)[:, None]
    at_z = (table[iz] * (1.0 - dz) + table[iz + 1] * dz).ravel()  # cells × θ
    # in place wherever it can be: ~900 × 900 pairs an array, each new one a fresh 7 MB the first update pays
    # page faults for (this function was 19-52 ms of it with ten such arrays, four now)
    ft = np.minimum(rho, 1.0)
    np.arcsin(ft, out=ft)
    ft *= (cols - 1) / (0.5 * np.pi)
    it = ft.astype(np.intp)
    np.minimum(it, cols - 2, out=it)
    ft -= it  # the step to the next θ
    it += cells * cols
    low = at_z[it]
    it += 1
    taken = at_z[it]
    taken -= low
    taken *= ft
    taken += low
    return taken


@functools.lru_cache(maxsize=1)
def area_taken_table() -> np.ndarray:
    """`_area_taken`'s table, built once a process (~20 ms: the learner builds it as it is made, not in an update)."""
    z = np.linspace(0.0, TAKEN_Z_MAX, 481)[:, None]
    rho = np.clip(np.sin(np.linspace(0.0, 0.5 * np.pi, 361)), 1e-12, 1.0 - 1e-12)[None, :]
    table = ndtr(-z) - 2.0 * owens_t(z, np.sqrt(1.0 - rho * rho) / rho)
    table[:, 0] = 0.0
    table.flags.writeable = False
    return table


def disagreement(predictions: list[tuple[float, np.ndarray, np.ndarray]], noise_var: float) -> np.ndarray:
    """Information (nats) a reading carries about which hypothesis is right; (weight, mean, var) each.

    The mixture's mutual information by its pairwise-distance estimate with the Bhattacharyya distance
    (Kolchinsky & Tracey 2017): 0 where the hypotheses predict alike, the entropy of their weights where
    a reading tells them apart for sure, never more. (A moment-matched ½·log(1 + spread/var) grows
    without bound with the distance between predictions: a rival at 5 % whose tilted background lay far
    off in a corner outbid the close call between the two leading hypotheses, and drew three probes
    there in a row, each a few mm from the last.)"""
    weights = np.array([w for w, _, _ in predictions])
    weights = weights / weights.sum()
    means = np.array([m for _, m, _ in predictions])
    variances = np.array([v for _, _, v in predictions]) + noise_var
    pair_var = variances[:, None] + variances[None, :]
    distance = ((means[:, None] - means[None, :]) ** 2 / (4.0 * pair_var)
                + 0.5 * np.log(pair_var / (2.0 * np.sqrt(variances[:, None] * variances[None, :]))))
    return -weights @ np.log(np.einsum("j,ijc->ic", weights, np.exp(-distance)))


def misfit(first: tuple[np.ndarray, np.ndarray], second: tuple[np.ndarray, np.ndarray], noise_var: float) -> np.ndarray:
    """How far two predictions (mean, var) stand apart at each spot: ½·log(1 + ¼Δ²/(noise + mean var)).
    Where the chosen fit misses what the free-form map shows, the spots that miss most come first:
    scored by `disagreement` they tie at log 2 wherever a reading would tell the two apart, and the probes
    went to the nearest of them, six in a row a few mm apart (touching-lumps, seed 1)."""
    (mean_a, var_a), (mean_b, var_b) = first, second
    return 0.5 * np.log1p(0.25 * (mean_a - mean_b) ** 2 / (noise_var + 0.5 * (var_a + var_b)))


def straddle(mean: np.ndarray, std: np.ndarray, tau: np.ndarray, confidence: float) -> np.ndarray:
    return NormalDist().inv_cdf(confidence) * std - np.abs(mean - tau)


def best_candidate(score: np.ndarray, cells_xy: np.ndarray, blocked: np.ndarray, here_mm,
                   travel_mm_per_palpation: float) -> tuple[float, float] | None:
    """The cell with the most score per unit of robot time, or None if nothing scores."""
    usable = (score > 0.0) & ~blocked
    if not usable.any():
        return None
    gain = np.where(usable, score, -np.inf)
    if here_mm is not None:
        travel = np.hypot(cells_xy[:, 0] - here_mm[0], cells_xy[:, 1] - here_mm[1])
        gain = gain / (1.0 + travel / travel_mm_per_palpation)
    best = int(np.argmax(gain))
    return float(cells_xy[best, 0]), float(cells_xy[best, 1])


def block_near(blocked: np.ndarray, xs: np.ndarray, ys: np.ndarray, xy_mm, spacing_mm: float) -> None:
    """Mark the cells of the (len(ys) × len(xs), row-major) grid within the minimum spacing of a new
    probe: only the window of rows and columns that can hold them is looked at."""
    cols = slice(*np.searchsorted(xs, [xy_mm[0] - spacing_mm, xy_mm[0] + spacing_mm]))
    rows = slice(*np.searchsorted(ys, [xy_mm[1] - spacing_mm, xy_mm[1] + spacing_mm]))
    near = np.hypot(xs[None, cols] - xy_mm[0], ys[rows, None] - xy_mm[1]) < spacing_mm
    blocked.reshape(len(ys), len(xs))[rows, cols] |= near
