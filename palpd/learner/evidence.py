"""One hypothesis fitted to the readings, and its evidence (Laplace approximation of the marginal likelihood).

The priors are stated, proper and the same for every scene: a lump's centre
anywhere over the tissue or overlapping it, its radius log-uniform from 0.5 mm
to the tissue's size, its edge sharpness log-uniform, its contrast log-uniform
from `min_contrast` (the softest difference that counts as a lump) to 1000×,
an ellipse's log axis ratio up to log 8. The evidence is

    log Z = log L(θ̂) + log p(θ̂) + ½·d·log 2π − ½·log det H + log k!

with H the Gauss–Newton curvature of −log posterior (a uniform prior adds the
curvature of its own spread, so a parameter the data leave free costs what its
prior volume says, never an infinite bonus), and k! for the k interchangeable
lumps. A parameter the data pin down costs log(prior width / posterior width):
the simplest model wins unless the data clearly ask for more.

A lump must also be felt: removing it must change the prediction at some exact
reading by at least SUPPORT_SIGMA of that reading's noise (at the noise floor). A fit that needs an
unfelt lump is not a hypothesis the data support (it is the simpler one with an
invisible extra), and is left out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri

from palpd.learner import shapes
from palpd.learner.likelihood import log_likelihood, noise_sd_ml, residuals
from palpd.learner.observations import Observations
from palpd.learner.threshold import FALSE_LUMP_RATE

SUPPORT_SIGMA = 3.0
MAX_AXIS_RATIO = 8.0
EDGE_SHARPNESS = (1.5, 60.0)
MAX_CONTRAST = 999.0
MIN_RADIUS_MM = 0.5
LEVEL_SD, SLOPE_SD = 2.0, 0.25  # background prior: log level around the readings' median; log change per half-size
OVERLAP_MM = 0.25
COST_TOLERANCE = 1e-4  # nats: a fit is done when a step gains less (evidences differ by whole nats)  # softness of the rule that lumps do not sit inside one another


@dataclass(frozen=True)
class Priors:
    size_mm: tuple[float, float]
    min_contrast: float
    level: float  # centre of the background level's prior (log N/mm)

    @property
    def scale_mm(self) -> float:
        return 0.5 * max(self.size_mm)

    def bounds(self, family: shapes.Family) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = [-np.inf] * 3, [np.inf] * 3
        for _ in range(family.k):
            l, h = zip(*self._lump_box(family.kind == "ellipses"))
            lo += l
            hi += h
        return np.array(lo), np.array(hi)

    def _lump_box(self, ellipse: bool) -> list[tuple[float, float]]:
        margin = 0.25 * max(self.size_mm)
        half_w, half_h = self.size_mm[0] / 2 + margin, self.size_mm[1] / 2 + margin
        box = [(-half_w, half_w), (-half_h, half_h), (math.log(MIN_RADIUS_MM), math.log(max(self.size_mm)))]
        if ellipse:
            e = math.log(MAX_AXIS_RATIO)
            box += [(-e, e), (-e, e)]
        return box + [tuple(map(math.log, EDGE_SHARPNESS)), (math.log(self.min_contrast), math.log(MAX_CONTRAST))]

    def log_density(self, family: shapes.Family, theta: np.ndarray) -> float:
        """log p(θ) of the uniform lump boxes (the background's Gaussian prior is in its residuals)."""
        lo, hi = self.bounds(family)
        box = np.isfinite(lo)
        return float(-np.sum(np.log(hi[box] - lo[box])))

    def precision(self, family: shapes.Family) -> np.ndarray:
        """Curvature a uniform prior stands for (1 / its variance); zero where the prior is Gaussian."""
        lo, hi = self.bounds(family)
        box = np.isfinite(lo)
        out = np.zeros(family.size)
        out[box] = 12.0 / (hi[box] - lo[box]) ** 2
        return out


@dataclass
class Fit:
    family: shapes.Family
    theta: np.ndarray
    cov: np.ndarray
    noise_sd: float
    log_posterior: float
    log_evidence: float
    supported: bool
    n: int

    @property
    def name(self) -> str:
        return self.family.name


def prior_residuals(family: shapes.Family, theta: np.ndarray, priors: Priors) -> tuple[np.ndarray, np.ndarray]:
    """The background's Gaussian prior and the no-lump-inside-another rule, as residuals with their Jacobian."""
    rows = [np.eye(1, family.size, 0)[0] / LEVEL_SD, np.eye(1, family.size, 1)[0] / SLOPE_SD,
            np.eye(1, family.size, 2)[0] / SLOPE_SD]
    values = [(theta[0] - priors.level) / LEVEL_SD, theta[1] / SLOPE_SD, theta[2] / SLOPE_SD]
    for j in range(family.k):
        for m in range(j + 1, family.k):
            value, row = _overlap(family, theta, j, m)
            values.append(value)
            rows.append(row)
    return np.array(values), np.array(rows)


def _overlap(family: shapes.Family, theta: np.ndarray, j: int, m: int) -> tuple[float, np.ndarray]:
    """How far two lumps' centres sit inside half their summed radii (0 when apart), in OVERLAP_MM."""
    a, b = family.lump_slice(j), family.lump_slice(m)
    dx, dy = theta[a.start] - theta[b.start], theta[a.start + 1] - theta[b.start + 1]
    d = math.hypot(dx, dy) + 1e-9
    ra, rb = math.exp(theta[a.start + 2]), math.exp(theta[b.start + 2])
    excess = 0.5 * (ra + rb) - d
    row = np.zeros(family.size)
    if excess <= 0:
        return 0.0, row
    row[a.start], row[a.start + 1] = -dx / d, -dy / d
    row[b.start], row[b.start + 1] = dx / d, dy / d
    row[a.start + 2], row[b.start + 2] = 0.5 * ra, 0.5 * rb
    return excess / OVERLAP_MM, row / OVERLAP_MM


def fit(family: shapes.Family, obs: Observations, priors: Priors, starts: list[np.ndarray],
        noise_floor: float, noise_sd: float | None = None, tau_log: float | None = None) -> Fit | None:
    """The mode of the most evidence among those `starts` lead to, with σ_w re-estimated.

    Modes are compared by evidence, not by height: two configurations can fit the readings
    equally well while one is a narrow coincidence of parameters and the other is what the
    readings say whatever the details, and the second holds far more posterior mass."""
    lo, hi = priors.bounds(family)
    noise = max(noise_sd or noise_floor, noise_floor)
    best = None
    for start in starts:
        theta = _solve(family, obs, priors, _inside(start, lo, hi), lo, hi, noise)
        mode = _evidence(family, theta, obs, priors, noise, noise_floor)
        if best is None or mode.log_evidence > best.log_evidence:
            best = mode
    if best is None:
        return None
    theta = best.theta
    for _ in range(2):  # σ_w from the residuals, then the fit again at that σ_w
        f, _ = shapes.evaluate(family, theta, obs.xy, jacobian=False)
        exact = obs.exact
        new = noise_sd_ml(obs.y[exact] - f[exact], obs.sd[exact], noise_floor)
        if abs(math.log(new / noise)) < 0.05:
            break
        noise = new
        theta = _solve(family, obs, priors, theta, lo, hi, noise)
    return _evidence(family, theta, obs, priors, noise, noise_floor, tau_log)


def _inside(theta: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    return np.clip(theta, lo + 1e-6 * span, hi - 1e-6 * span)


def _stacked(family, theta, obs, priors, noise):
    f, jac = shapes.evaluate(family, theta, obs.xy)
    r, jr = residuals(f, jac, obs.y, obs.sd, obs.kind, noise)
    pr, pj = prior_residuals(family, theta, priors)
    return np.concatenate([r, pr]), np.vstack([jr, pj])


def _solve(family, obs, priors, theta0, lo, hi, noise) -> np.ndarray:
    return levenberg_marquardt(lambda theta: _stacked(family, theta, obs, priors, noise), theta0, lo, hi)


def levenberg_marquardt(fun, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_iter: int = 80) -> np.ndarray:
    """Minimise ½|r(x)|² within the box [lo, hi]; fun(x) returns (r, Jacobian).

    Marquardt's scaled damping with the step projected onto the box: the parameters
    are few and well scaled by the damping, so this small loop beats a general solver's overhead.
    """
    x = x0.copy()
    r, jac = fun(x)
    cost = 0.5 * float(r @ r)
    damping = 1e-3
    for _ in range(max_iter):
        a, g = jac.T @ jac, jac.T @ r
        scale = np.maximum(np.diag(a), 1e-12 * max(float(np.max(np.diag(a))), 1e-300))
        try:
            step = np.linalg.solve(a + damping * np.diag(scale), -g)
        except np.linalg.LinAlgError:
            damping *= 10.0
            continue
        trial = np.clip(x + step, lo, hi)
        r_new, jac_new = fun(trial)
        new_cost = 0.5 * float(r_new @ r_new)
        if np.isfinite(new_cost) and new_cost < cost:
            done = cost - new_cost <= COST_TOLERANCE or np.max(np.abs(trial - x)) < 1e-9
            x, r, jac, cost = trial, r_new, jac_new, new_cost
            damping = max(damping / 3.0, 1e-9)
            if done:
                break
        else:
            damping *= 4.0
            if damping > 1e10:
                break
    return x


def _log_posterior(family, theta, obs, priors, noise) -> float:
    f, _ = shapes.evaluate(family, theta, obs.xy, jacobian=False)
    r, _ = residuals(f, None, obs.y, obs.sd, obs.kind, noise)
    pr, _ = prior_residuals(family, theta, priors)
    return (log_likelihood(r, obs.sd, obs.kind, noise) - 0.5 * float(pr @ pr)
            + priors.log_density(family, theta))


def _evidence(family, theta, obs, priors, noise, noise_floor, tau_log=None) -> Fit:
    r, jac = _stacked(family, theta, obs, priors, noise)
    hessian = jac.T @ jac + np.diag(priors.precision(family))
    sign, logdet = np.linalg.slogdet(hessian)
    if sign <= 0:
        hessian += np.eye(family.size) * 1e-9 * np.trace(hessian)
        sign, logdet = np.linalg.slogdet(hessian)
    post = _log_posterior(family, theta, obs, priors, noise) - 0.5 * _gaussian_prior_norm(family)
    log_z = post + 0.5 * family.size * math.log(2.0 * math.pi) - 0.5 * logdet + math.lgamma(family.k + 1)
    cov = np.linalg.pinv(hessian)
    return Fit(family, theta, cov, noise, post, log_z, supported(family, theta, obs, noise_floor, tau_log), obs.n)


def _gaussian_prior_norm(family) -> float:
    """2·Σ log(σ√(2π)) of the background's Gaussian priors (their normalising constants)."""
    return 2.0 * (math.log(LEVEL_SD) + 2.0 * math.log(SLOPE_SD) + 1.5 * math.log(2.0 * math.pi))


def supported(family: shapes.Family, theta: np.ndarray, obs: Observations, noise: float,
              tau_log: float | None = None) -> bool:
    """Every lump changes some exact reading's prediction by SUPPORT_SIGMA of its noise at the floor
    (not the fit's own σ_w, which an unexplained lump elsewhere inflates), and, with a supervised τ,
    is felt at some reading surely above τ."""
    if family.k == 0:
        return True
    exact = obs.exact
    heights = shapes.heights_of(family, theta, obs.xy)[exact]
    total = np.sqrt(obs.sd[exact] ** 2 + noise**2)
    top = np.log1p(heights.max(axis=1))
    felt = np.argmax(heights, axis=1)
    above = np.ones(len(top), dtype=bool) if tau_log is None else \
        obs.y[exact] - float(ndtri(1.0 - FALSE_LUMP_RATE / max(len(top), 1))) * obs.sd[exact] > tau_log
    for j in range(family.k):
        others = np.delete(heights, j, axis=1)
        without = np.log1p(others.max(axis=1)) if others.shape[1] else np.zeros(len(top))
        if not np.any(((top - without) >= SUPPORT_SIGMA * total) & (felt == j) & above):
            return False
    return True
