"""The likelihood of the readings under a model, as residuals a least-squares solver can minimise.

A reading is y = f(x) + noise, the noise being its own fit uncertainty plus a
shared extra term σ_w (repeatability, model misfit) that each model estimates
for itself, never below a floor: a model that leaves structure behind pays for
it as a larger σ_w. A censored reading (k ≥ B or k ≤ B) contributes
P(reading beyond B) = Φ(z); as a residual r = √(−2 log Φ(z)), so that ½Σr² is
still −log L and the same solver handles both.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import log_ndtr

from palpd.learner.observations import AT_LEAST, AT_MOST, EXACT

LOG_2PI = math.log(2.0 * math.pi)
MEDIAN_OVER_MEAN_CHI2 = 0.4549  # the median of χ² with one degree of freedom (its mean is 1)
# The relative standard error of an sd estimated from the median of m χ²₁ draws is MEDIAN_SE / √m: the median's
# variance is 1 / (4 m f²) at the χ²₁ density there, f = 0.4711, i.e. (1.061 / 0.4549)² / m of its value squared,
# and an sd's relative error is half its variance's.
MEDIAN_SE = 1.17
MAD_TO_SD = 1.4826  # a Gaussian's sd over its median absolute deviation
TYPICAL_SPREAD = 2.0  # texture spreads every error alike: σ_w beyond this multiple of the typical error is a few
NEIGHBOURS = 4  # each reading's nearest readings, for how alike neighbouring errors are (error_structure_z)
STRUCTURE_Z = 3.0  # errors this many sds more alike among neighbours than independent ones would be are no texture


def residuals(f: np.ndarray, jac: np.ndarray | None, y: np.ndarray, sd: np.ndarray, kind: np.ndarray,
              noise_sd: float) -> tuple[np.ndarray, np.ndarray | None]:
    """Residuals (½Σr² = −log L up to the normalising terms) and their Jacobian w.r.t. the parameters;
    f (n) and jac (n × d), or S of each (S × n, S × n × d) from as many parameter vectors."""
    total = np.sqrt(sd * sd + noise_sd * noise_sd)
    r = (y - f) / total
    d_r_df = -1.0 / total
    censored = kind != EXACT
    if censored.any():
        sign = np.where(kind[censored] == AT_LEAST, 1.0, -1.0)
        z = -sign * r[..., censored]  # AT_LEAST: (f − B)/σ; AT_MOST: (B − f)/σ
        rc, drc_dz = _censored_residual(z)
        r[..., censored] = rc
        d_r_df = np.broadcast_to(d_r_df, r.shape).copy()
        d_r_df[..., censored] = drc_dz * sign / total[censored]
    return r, (None if jac is None else d_r_df[..., None] * jac)


def _censored_residual(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    log_phi = log_ndtr(z)
    r = np.sqrt(np.maximum(-2.0 * log_phi, 0.0))
    mills = np.exp(-0.5 * z * z - 0.5 * LOG_2PI - log_phi)  # φ(z)/Φ(z)
    with np.errstate(divide="ignore", invalid="ignore"):
        dr = np.where(r > 1e-9, -mills / r, 0.0)
    return r, dr


def log_likelihood(r: np.ndarray, sd: np.ndarray, kind: np.ndarray, noise_sd: float) -> float:
    exact = kind == EXACT
    var = sd[exact] ** 2 + noise_sd**2
    return float(-0.5 * np.sum(r * r) - 0.5 * np.sum(np.log(var)) - 0.5 * LOG_2PI * np.count_nonzero(exact))


def gaussian_log_density(error: np.ndarray, var: np.ndarray) -> np.ndarray:
    """log N(error; 0, var), elementwise: how well a predictive distribution foresaw each reading."""
    return -0.5 * (error * error / var + np.log(var) + LOG_2PI)


def noise_sd_ml(error: np.ndarray, sd: np.ndarray, floor: float) -> float:
    """Maximum-likelihood σ_w for exact readings with errors `error` and own sds `sd`, at least `floor`."""
    if error.size == 0:
        return floor
    var = max(float(np.mean(error * error - sd * sd)), floor**2)
    for _ in range(20):  # fixed point of Σ w²(e² − s² − σ²) = 0, w = 1/(s² + σ²)
        w2 = 1.0 / (sd * sd + var) ** 2
        new = max(float(np.sum(w2 * (error * error - sd * sd)) / np.sum(w2)), floor**2)
        if abs(new - var) <= 1e-6 * var:
            break
        var = new
    return math.sqrt(var)


def error_structure_z(xy: np.ndarray, error: np.ndarray) -> float:
    """How much more alike the errors of neighbouring readings are than independent errors would be, in sds:
    Moran's I of the errors over each reading's NEIGHBOURS nearest readings (row-standardised weights), against
    its mean and variance when the errors are independent (its normal approximation); 0 on too few readings."""
    n = len(error)
    k = min(NEIGHBOURS, n - 2)
    if k < 1:
        return 0.0
    from scipy.sparse import csr_matrix
    from scipy.spatial import cKDTree

    near = cKDTree(xy).query(xy, k=k + 1)[1][:, 1:]  # (a reading repeated at one spot: its twin is a neighbour)
    z = error - error.mean()
    spread = float(z @ z)
    if spread <= 0.0:
        return 0.0
    moran = float(z @ z[near].mean(axis=1)) / spread
    weights = csr_matrix((np.full(n * k, 1.0 / k), (np.repeat(np.arange(n), k), near.ravel())), shape=(n, n))
    s1 = 0.5 * float((weights + weights.T).power(2).sum())
    s2 = float(np.sum((np.asarray(weights.sum(axis=1)).ravel() + np.asarray(weights.sum(axis=0)).ravel()) ** 2))
    mean = -1.0 / (n - 1)
    variance = (n * n * s1 - n * s2 + 3.0 * n * n) / ((n * n - 1.0) * n * n) - mean * mean
    return (moran - mean) / math.sqrt(variance) if variance > 0.0 else 0.0


def neighbour_scatter(xy: np.ndarray, error: np.ndarray, sd: np.ndarray) -> tuple[float, int]:
    """How much neighbouring readings' errors differ beyond their own sds: the nugget of the errors'
    variogram, (sd, pairs it rests on), from each reading and its nearest neighbour.

    Texture (a tissue's own stiffness varying from spot to spot, as a measured map's does) makes
    neighbours differ as much as the errors scatter overall; a lump a model misses raises the errors
    of the readings on it together, and their neighbours' differences hardly at all. The median of
    the pairs' squared differences (over its value for a Gaussian, 0.455 of the mean) keeps the few
    pairs that straddle an unmodelled edge from counting as texture."""
    if len(xy) < 2:
        return 0.0, 0
    from scipy.spatial import cKDTree  # loaded with scipy.optimize already; O(n log n), not an n x n matrix

    i = np.arange(len(xy))
    two = cKDTree(xy).query(xy, k=2)[1]
    nearest = np.where(two[:, 1] == i, two[:, 0], two[:, 1])  # a reading repeated at one spot: not itself
    once = (i < nearest) | (nearest[nearest] != i)  # a pair of mutual nearest neighbours counts once
    i, j = i[once], nearest[once]
    excess = 0.5 * (error[i] - error[j]) ** 2 / MEDIAN_OVER_MEAN_CHI2 - 0.5 * (sd[i] ** 2 + sd[j] ** 2)
    return math.sqrt(max(float(np.median(excess)), 0.0)), len(i)


def texture_sd(xy: np.ndarray, error: np.ndarray, sd: np.ndarray, min_pairs: int) -> float:
    """The largest σ_w the tissue's texture accounts for (0 on fewer than `min_pairs` neighbour pairs: a
    median of a few says nothing): no more than neighbouring readings differ by, nor than TYPICAL_SPREAD
    times the typical error (texture spreads every error alike; a lump missed makes a few large, and pairs
    across its edge can still make neighbours differ), with one standard error of the neighbours' estimate
    to spare (it and σ_w measure the same spread: held to it exactly, a tissue of texture alone failed half
    its updates, 10 % texture with no lump ended `undetermined`). Nor any, where neighbouring errors are alike
    (`error_structure_z` over STRUCTURE_Z): texture varies from spot to spot, a region the model misses makes
    the errors of the readings on it alike; a 6 x 6 raster of a real phantom read `none` at weight 0.998 over
    a band 4x stiffer than the rows beside it, its σ_w 80x the floor taken for texture (Moran z 3.9; the
    textured shipped maps' errors -0.9 and -1.2)."""
    scatter, pairs = neighbour_scatter(xy, error, sd)
    if pairs < min_pairs or error_structure_z(xy, error) > STRUCTURE_Z:
        return 0.0
    typical = MAD_TO_SD * float(np.median(np.abs(error - np.median(error))))
    return min(scatter, TYPICAL_SPREAD * typical) * (1.0 + MEDIAN_SE / math.sqrt(pairs))


__all__ = ["AT_LEAST", "AT_MOST", "EXACT", "error_structure_z", "log_likelihood", "neighbour_scatter", "noise_sd_ml",
           "residuals", "texture_sd"]
