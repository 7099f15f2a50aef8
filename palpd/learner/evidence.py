"""One hypothesis fitted to the readings, and its evidence (Laplace approximation of the marginal likelihood).

The priors are stated, proper and the same for every scene: a lump's centre
anywhere on the tissue (its disc may reach past it), its radius log-uniform from 0.5 mm
to half the tissue's longer side (most of it), its edge sharpness log-uniform, its tail shape uniform
(from tails that end at a finite distance through power-law to Gaussian, shapes.py), its contrast log-uniform
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
invisible extra), and is left out. Nor is a fit whose lumps share more than SHARED_AREA of the smaller
one's area (`apart`) an answer: lumps laid over one another to tile a stiff region are one region of a
shape no lump of the family makes, the free-form map's to describe, not k lumps (hypotheses.choice).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from palpd.learner import shapes
from palpd.learner.shapes import BACKGROUND_PARAMS as BACKGROUND
from palpd.learner.priors import LEVEL_SD, SLOPE_SD, Priors  # noqa: F401  (Priors: part of this API)
from palpd.learner.likelihood import gaussian_log_density, log_likelihood, noise_sd_ml, residuals
from palpd.learner.solver import levenberg_marquardt, levenberg_marquardt_many
from palpd.learner.observations import AT_LEAST, EXACT, Observations

SUPPORT_SIGMA = 3.0
ADEQUATE_NOISE = 2.0  # σ_w beyond this multiple of the floor: the model misses something (decision.py)
OVERLAP_MM = 0.25  # softness of the rule that lumps do not sit inside one another
SHARED_AREA = 0.2  # two lumps sharing more of the smaller's area are one region (`apart`)
SURE_SDS = 4.0  # a pair of lumps this many sds apart (or overlapping) is left to its mode's answer
COUNT_DRAWS = 64  # draws of the parameters for a count whose pairs are unsure
HOPELESS = 30.0  # nats: a start this far below the height a start before it reached is dropped (after GIVE_UP_AFTER steps)
GIVE_UP_AFTER = 8
RIDGE_NATS = 0.5  # a mode this little below the chosen one is as likely as the points 1 sd from it
CALL_OVERHEAD = 1000  # an evaluation's fixed cost, in residual entries (Python and numpy call overhead)
MAX_LEVERAGE = 0.99  # loo_log_density: a reading's share of its own fit, at most (1: the fit passes through it)
COST_TOLERANCE = 1e-4  # nats: a fit is done when a step gains less (evidences differ by whole nats)


@dataclass
class Fit:
    family: shapes.Family
    theta: np.ndarray
    cov: np.ndarray
    noise_sd: float
    log_posterior: float
    log_evidence: float
    supported: bool
    n: int  # readings when fitted
    log_det: float  # log det of the curvature then
    work: int = 0  # what the fit cost, in evaluated residual entries (deterministic, unlike a clock)
    checked: bool = False  # cov checked against the posterior along its widest directions (posterior.py)
    evidence_checked: bool = False  # log_evidence with the posterior's volume measured (posterior.py)
    alternatives: tuple = ()  # other modes the starts reached, as high as this one (within RIDGE_NATS)

    @property
    def name(self) -> str:
        return self.family.name


def prior_residuals(family: shapes.Family, theta: np.ndarray, priors: Priors) -> tuple[np.ndarray, np.ndarray]:
    """The background's Gaussian prior and the no-lump-inside-another rule, as residuals with their Jacobian
    (for S parameter vectors at once too: theta S × size gives S of each)."""
    values = (theta[..., :BACKGROUND] - (priors.level, 0.0, 0.0)) / (LEVEL_SD, SLOPE_SD, SLOPE_SD)
    rows = _background_rows_for(family.size, theta.shape[:-1])
    parts = [(values, rows)]
    if family.k >= 2:
        parts.append(_overlaps(family, theta))
    if family.soft:
        parts.append(_soft_off_tissue(family, theta, priors))
        if family.k:
            parts.append(_soft_beside_lumps(family, theta))
    if len(parts) == 1:
        return values, rows
    return np.concatenate([v for v, _ in parts], axis=-1), np.concatenate([r for _, r in parts], axis=-2)


def _soft_beside_lumps(family: shapes.Family, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lumps-apart rule between each lump and the soft region: tissue softer inside a lump is no soft region
    beside one (a stiff ring was one disc with a soft region in its middle: `lumps`, where no model on offer
    draws a ring and the scan is to say so)."""
    soft = family.soft_slice.start
    return _discs_apart(family, theta, tuple(family.lump_slice(j).start for j in range(family.k)), (soft,) * family.k)


def _soft_off_tissue(family: shapes.Family, theta: np.ndarray, priors: Priors) -> tuple[np.ndarray, np.ndarray]:
    """How far a soft region's 50 % boundary reaches past the tissue's edge along x and y (0 within it), in
    OVERLAP_MM. Tissue softer in one place has tissue around it; softer past the edge it is as much the soft
    side of a stiff region as a soft region (the half-stiff map, a smooth stiff region over half the tissue,
    was read as a disc of soft tissue over its soft half: `none`)."""
    region = theta[..., family.soft_slice]
    radius = np.exp(region[..., 2])
    half = np.asarray(priors.size_mm, dtype=float) / 2.0
    excess = np.abs(region[..., 0:2]) + radius[..., None] - half  # (..., 2)
    past = excess > 0
    rows = np.zeros(theta.shape[:-1] + (2, family.size))
    start = family.soft_slice.start
    rows[..., 0, start] = np.sign(region[..., 0])
    rows[..., 1, start + 1] = np.sign(region[..., 1])
    rows[..., :, start + 2] = radius[..., None]
    return np.where(past, excess, 0.0) / OVERLAP_MM, rows * past[..., None] / OVERLAP_MM


def _overlaps(family: shapes.Family, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far each pair of lumps' centres sit inside half their summed radii (0 when apart), in OVERLAP_MM."""
    return _discs_apart(family, theta, *_overlap_starts(family.k, family.per_lump))


@functools.lru_cache(maxsize=None)
def _overlap_starts(k: int, per_lump: int) -> tuple[tuple, tuple]:
    """The offsets in θ of each pair's two lumps (j < m), made once per layout: every fit step asks."""
    j, m = _pairs(k)
    starts = [BACKGROUND + i * per_lump for i in range(k)]
    return tuple(starts[i] for i in j.tolist()), tuple(starts[i] for i in m.tolist())


def _discs_apart(family: shapes.Family, theta: np.ndarray, first: tuple, second: tuple) -> tuple[np.ndarray, np.ndarray]:
    """For each pair of discs (the offsets in θ of their [cx, cy, log R], as tuples), how far their centres sit
    inside half their summed radii (0 when apart), in OVERLAP_MM, and its Jacobian (S parameter vectors at once
    too)."""
    first, second, first_columns, second_columns = _disc_columns(first, second)
    lead, pairs = theta.shape[:-1], len(first)
    # one gather of both discs' [cx, cy, log R] (every fit step comes here): the same values as six
    a, b = theta[..., first_columns], theta[..., second_columns]
    dx, dy = a[..., 0:pairs] - b[..., 0:pairs], a[..., pairs:2 * pairs] - b[..., pairs:2 * pairs]
    d = np.hypot(dx, dy) + 1e-9
    ra, rb = np.exp(a[..., 2 * pairs:]), np.exp(b[..., 2 * pairs:])
    excess = 0.5 * (ra + rb) - d
    inside = excess > 0
    if not inside.any():  # discs apart, as nearly always: nothing to push
        return np.zeros(lead + (pairs,)), np.zeros(lead + (pairs, family.size))
    rows = np.zeros(lead + (pairs, family.size))
    pair = np.arange(pairs)
    for start, radius, sign in ((first, ra, 1.0), (second, rb, -1.0)):
        rows[..., pair, start] = -sign * dx / d
        rows[..., pair, start + 1] = -sign * dy / d
        rows[..., pair, start + 2] = 0.5 * radius
    return np.where(inside, excess, 0.0) / OVERLAP_MM, rows * inside[..., None] / OVERLAP_MM


@functools.lru_cache(maxsize=None)
def _background_rows(size: int) -> np.ndarray:
    """The background prior's Jacobian: constant, made once per parameter count (read-only)."""
    rows = np.zeros((3, size))
    rows[[0, 1, 2], [0, 1, 2]] = 1.0 / np.array([LEVEL_SD, SLOPE_SD, SLOPE_SD])
    rows.flags.writeable = False
    return rows


@functools.lru_cache(maxsize=None)
def _disc_columns(first: tuple, second: tuple) -> tuple[np.ndarray, ...]:
    """The offsets as arrays, and the columns [cx of each disc, then cy of each, then log R of each] of the first
    discs and of the second: made once per layout (read-only)."""
    out = []
    for starts in (first, second):
        starts = np.array(starts, dtype=int)
        out.append(starts)
    out += [np.concatenate([s, s + 1, s + 2]) for s in out]
    for array in out:
        array.flags.writeable = False
    return tuple(out)


@functools.lru_cache(maxsize=256)
def _background_rows_for(size: int, lead: tuple) -> np.ndarray:
    """_background_rows broadcast to `lead` parameter vectors (read-only): made once per shape, not per fit step."""
    return np.broadcast_to(_background_rows(size), lead + (3, size))


@functools.lru_cache(maxsize=None)
def _pairs(k: int) -> tuple[np.ndarray, np.ndarray]:
    """The index pairs (j < m) of k lumps, made once per k: the overlap rule runs at every fit step."""
    return np.triu_indices(k, 1)


def fit(family: shapes.Family, obs: Observations, priors: Priors, starts: list[np.ndarray],
        noise_floor: float, noise_sd: float | None = None, max_iter: int = 60, give_up: bool = True) -> Fit | None:
    """The mode of the most evidence among those `starts` lead to, with σ_w re-estimated. `give_up`: a start
    still HOPELESS nats above one before it after GIVE_UP_AFTER steps is dropped (the time it saves; but a
    warm start in a poor mode is low at once, and a fresh one on its way to a far better mode can lag it).

    Modes are compared by evidence, not by height: two configurations can fit the readings
    equally well while one is a narrow coincidence of parameters and the other is what the
    readings say whatever the details, and the second holds far more posterior mass."""
    noise = max(noise_sd or noise_floor, noise_floor)
    starts = np.array(starts, dtype=float)
    los, his = priors.branch_bounds(family, starts)
    thetas, costs, used = levenberg_marquardt_many(
        lambda many: stacked(family, many, obs, priors, noise), _inside(starts, los, his),
        los, his, COST_TOLERANCE, max_iter, (GIVE_UP_AFTER, HOPELESS) if give_up else None)
    calls = int(used.sum())
    best, modes = None, []
    for theta, cost, lowest in zip(thetas, costs, np.minimum.accumulate(np.where(np.isfinite(costs), costs, np.inf))):
        if not cost <= lowest + HOPELESS:  # far below a start before it (or undefined): not a mode worth weighing
            continue
        mode = _evidence(family, theta, obs, priors, noise, noise_floor)
        modes.append(mode)
        if best is None or mode.log_evidence > best.log_evidence:
            best = mode
    if best is None:
        return None
    alternatives = _alternatives(best, modes)
    theta = best.theta
    lo, hi = priors.branch_bounds(family, theta)  # (tails that ended on the Hill profile go on as the other branch)
    for _ in range(2):  # σ_w from the residuals, then the fit again at that σ_w
        f, _ = shapes.evaluate(family, theta, obs.xy, jacobian=False)
        exact = obs.exact
        new = noise_sd_ml(obs.y[exact] - f[exact], obs.sd[exact], noise_floor)
        if abs(math.log(new / noise)) < 0.05:
            break
        noise = new
        theta, _, used = _solve(family, obs, priors, theta, lo, hi, noise, max_iter=max_iter)
        calls += used
    return replace(_evidence(family, theta, obs, priors, noise, noise_floor),
                   work=calls * (CALL_OVERHEAD + obs.n * family.size), alternatives=alternatives)


def _alternatives(best: Fit, modes: list[Fit]) -> tuple:
    """The modes as high as the chosen one (within RIDGE_NATS) and more than 1 sd from it by its curvature:
    the posterior is a ridge there, wider than the Laplace covariance at any one point of it says."""
    precision = np.linalg.pinv(best.cov)
    return tuple(mode.theta for mode in modes if mode.log_posterior >= best.log_posterior - RIDGE_NATS
                 and float((mode.theta - best.theta) @ precision @ (mode.theta - best.theta)) > 1.0)


def _inside(theta: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    return np.clip(theta, lo + 1e-6 * span, hi - 1e-6 * span)


def stacked(family, theta, obs, priors, noise):
    """Residuals whose ½|r|² is −log posterior up to a constant (readings, then priors), and their Jacobian;
    for S parameter vectors (theta S × size) at once, S of each."""
    f, jac = shapes.evaluate_many(family, np.atleast_2d(theta), obs.xy)
    r, jr = residuals(f, jac, obs.y, obs.sd, obs.kind, noise)
    pr, pj = prior_residuals(family, np.atleast_2d(theta), priors)
    r, jac = np.concatenate([r, pr], axis=-1), np.concatenate([jr, pj], axis=-2)
    return (r, jac) if theta.ndim == 2 else (r[0], jac[0])


def _solve(family, obs, priors, theta0, lo, hi, noise, max_iter: int = 60):
    return levenberg_marquardt(lambda theta: stacked(family, theta, obs, priors, noise), theta0, lo, hi,
                               COST_TOLERANCE, max_iter=max_iter)


def _log_posterior(family, theta, obs, priors, noise) -> float:
    f, _ = shapes.evaluate(family, theta, obs.xy, jacobian=False)
    r, _ = residuals(f, None, obs.y, obs.sd, obs.kind, noise)
    pr, _ = prior_residuals(family, theta, priors)
    return (log_likelihood(r, obs.sd, obs.kind, noise) - 0.5 * float(pr @ pr)
            + priors.log_density(family, theta))


def neg_log_posterior(family, theta, obs, priors, noise) -> float:
    """−log p(θ | readings) up to a constant (posterior.py checks the Laplace covariance with it)."""
    return -_log_posterior(family, theta, obs, priors, noise)


def _evidence(family, theta, obs, priors, noise, noise_floor) -> Fit:
    r, jac = stacked(family, theta, obs, priors, noise)
    hessian = jac.T @ jac + np.diag(priors.precision(family, theta))
    sign, logdet = np.linalg.slogdet(hessian)
    if sign <= 0:
        hessian += np.eye(family.size) * 1e-9 * np.trace(hessian)
        sign, logdet = np.linalg.slogdet(hessian)
    post = _log_posterior(family, theta, obs, priors, noise) - 0.5 * _gaussian_prior_norm(family)
    cov = np.linalg.pinv(hessian)
    return Fit(family, theta, cov, noise, post, _log_z(family, post, logdet),
               supported(family, theta, obs, noise_floor), obs.n, logdet)


def _log_z(family, log_posterior: float, log_det: float) -> float:
    return log_posterior + 0.5 * family.size * math.log(2.0 * math.pi) - 0.5 * log_det + math.lgamma(family.k + 1)


def assimilated(fit: Fit, obs: Observations, priors: Priors) -> Fit:
    """The fit brought up to all readings by one Kalman step each (the Laplace posterior updated with
    the reading's linearisation: what a refit would do, for O(d²) a reading), its evidence by each
    reading's predictive density. A refit now and then corrects what linearising misses."""
    theta, cov = fit.theta.copy(), fit.cov.copy()
    log_z, log_det = fit.log_evidence, fit.log_det
    lo, hi = priors.branch_bounds(fit.family, fit.theta)
    for i in range(fit.n, obs.n):
        if obs.kind[i] != EXACT:
            continue
        f, jac = shapes.evaluate(fit.family, theta, obs.xy[i:i + 1])
        g = jac[0]
        noise_var = obs.sd[i] ** 2 + fit.noise_sd**2
        spread = cov @ g
        total = float(g @ spread) + noise_var
        innovation = obs.y[i] - float(f[0])
        theta = np.minimum(np.maximum(theta + spread * innovation / total, lo), hi)  # np.clip's wrapper costs more
        cov -= np.outer(spread, spread) / total
        log_z -= 0.5 * (innovation**2 / total + math.log(2.0 * math.pi * total))
        log_det += math.log(total / noise_var)
    return replace(fit, theta=theta, cov=cov, log_evidence=log_z, log_det=log_det, n=obs.n)


def refreshed(fit: Fit, obs: Observations, priors: Priors) -> Fit:
    """The evidence of a fit at its parameters on all readings so far, without refitting: the height
    on the new readings, the curvature grown as it does (∝ readings) since the fit."""
    family = fit.family
    post = _log_posterior(family, fit.theta, obs, priors, fit.noise_sd) - 0.5 * _gaussian_prior_norm(family)
    log_det = fit.log_det + family.size * math.log(obs.n / max(fit.n, 1))
    return replace(fit, log_posterior=post, log_evidence=_log_z(family, post, log_det))


def loo_log_density(fit: Fit, obs: Observations) -> np.ndarray:
    """Each exact reading's log density under the fit to the others, by the linearised leave-one-out of a
    least-squares fit: with leverage h_i = J_i Σ J_iᵀ / s_i² (Σ the fit's posterior covariance, s_i² the
    reading's own variance and σ_w²), the reading left out is missed by e_i / (1 − h_i) at variance
    s_i² / (1 − h_i). Comparable with the GP map's (gp.IncrementalGP.loo_log_density): both are what a
    model foresaw of readings it had not seen, the yardstick when none of them explains the readings."""
    exact = obs.exact
    f, jac = shapes.evaluate(fit.family, fit.theta, obs.xy[exact])
    var = obs.sd[exact] ** 2 + fit.noise_sd**2
    # a reading that alone decides a parameter has leverage 1: its left-out prediction is the prior's, capped
    leverage = np.minimum(np.einsum("ij,jk,ik->i", jac, fit.cov, jac) / var, MAX_LEVERAGE)
    return gaussian_log_density((obs.y[exact] - f) / (1.0 - leverage), var / (1.0 - leverage))


def _gaussian_prior_norm(family) -> float:
    """2·Σ log(σ√(2π)) of the background's Gaussian priors (their normalising constants)."""
    return 2.0 * (math.log(LEVEL_SD) + 2.0 * math.log(SLOPE_SD) + 1.5 * math.log(2.0 * math.pi))


def supported(family: shapes.Family, theta: np.ndarray, obs: Observations, noise: float) -> bool:
    """Every lump is felt at some reading: it is the lump felt most there, and taking it away changes
    an exact reading's prediction by SUPPORT_SIGMA of its noise at the floor (`noise`; not the fit's own
    σ_w, which an unexplained lump elsewhere inflates), or leaves a lower bound ('too stiff') that far
    above the prediction: a lump whose core readings all hit the force limit is felt there. A soft region
    likewise: taking it away raises some exact reading's prediction that far."""
    return not unfelt(family, theta, obs, noise) and (not family.soft or _soft_felt(family, theta, obs, noise))


def _soft_felt(family: shapes.Family, theta: np.ndarray, obs: Observations, noise: float) -> bool:
    exact = obs.exact
    dip = shapes.soft_dip(family, theta, obs.xy[exact])
    return bool(np.any(dip >= SUPPORT_SIGMA * np.sqrt(obs.sd[exact] ** 2 + noise**2)))


def apart(family: shapes.Family, theta: np.ndarray) -> bool:
    """No two lumps share more than SHARED_AREA of the smaller one's area (inside their 50 % boundaries):
    discs or ellipses laid over one another to tile a stiff region are one region of a shape no lump of
    the family makes (the free-form map's to describe), not k lumps. Lumps that merely touch, or whose
    blurred edges overlap a little, are apart (two 5 mm discs 7 mm apart share 19 %)."""
    return all(shared <= SHARED_AREA for _, _, shared in _shared_areas(family, theta))


def regions(family: shapes.Family, theta: np.ndarray) -> list[list[int]]:
    """The fit's lumps gathered into connected stiff regions, each a list of lump indices in order: lumps whose
    50 % boundaries overlap at all are one region. A lump is what a surgeon would cut out, a connected stiff
    region; two circles laid across a rounded rectangle are one region of that shape (they were counted two,
    at weight 1.000), while lumps whose boundaries stay apart, however close, are two."""
    return _components(family.k, [(j, m) for j, m, shared in _shared_areas(family, theta) if shared > 0.0])


def region_counts(family: shapes.Family, theta: np.ndarray, cov: np.ndarray) -> dict[int, float]:
    """The posterior of the fit's count of connected regions (`regions`) over its parameters' posterior
    N(theta, cov), not at the mode alone: two lumps whose boundaries nearly meet are one region or two by
    less than their boundaries' sds (a triangle read as a disc and a small one in its corner, 0.45 mm apart,
    was counted two at weight 1.000). Pairs whose boundaries are surely apart or surely overlapping (by
    SURE_SDS sds of their centres and sizes) keep their mode's answer; the rest are drawn COUNT_DRAWS times
    (a fixed seed: the same readings give the same answer) and the counts of the draws tallied."""
    k = family.k
    if k < 2:
        return {k: 1.0}
    lumps = shapes.lumps_of(family, theta)
    ellipse = family.kind == "ellipses"
    axes = [shapes.axes_and_angle(lump, ellipse)[:2] for lump in lumps]
    var = np.maximum(np.diag(cov), 0.0)
    # each lump's reach moves by its centre's sd and its size's (log R's sd times its longest axis)
    reach_var = [float(var[s][:2].sum()) + (major * math.sqrt(var[s][2])) ** 2
                 for s, (major, _) in zip(map(family.lump_slice, range(k)), axes)]
    unsure, linked = [], []
    for j, m in zip(*_pairs(k)):
        spread = SURE_SDS * math.sqrt(reach_var[j] + reach_var[m])
        distance = math.dist(lumps[j][:2], lumps[m][:2])
        if distance - axes[j][0] - axes[m][0] > spread:
            continue  # apart even along their longest axes
        if distance - axes[j][1] - axes[m][1] < -spread:
            linked.append((j, m))  # overlapping even along their shortest axes
        else:
            unsure.append((j, m))
    if not unsure:
        return {len(_components(k, linked)): 1.0}
    draws = _draws(theta, cov)
    tally: dict[int, float] = {}
    for sample in draws:
        sampled = shapes.lumps_of(family, sample)
        edges = linked + [(j, m) for j, m in unsure if _shared_area(sampled[j], sampled[m], ellipse) > 0.0]
        count = len(_components(k, edges))
        tally[count] = tally.get(count, 0.0) + 1.0 / len(draws)
    return tally


def _draws(theta: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """COUNT_DRAWS parameter vectors from N(theta, cov) (cov symmetrised, its negative eigenvalues dropped)."""
    values, vectors = np.linalg.eigh((cov + cov.T) / 2.0)
    root = vectors * np.sqrt(np.maximum(values, 0.0))
    z = np.random.default_rng(0).standard_normal((COUNT_DRAWS, len(theta)))
    return theta + z @ root.T


def _components(k: int, edges: list[tuple[int, int]]) -> list[list[int]]:
    """The connected components of k lumps joined by `edges`, each a list of indices in order."""
    parent = list(range(k))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for j, m in edges:
        parent[root(m)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in range(k):
        groups.setdefault(root(i), []).append(i)
    return sorted(groups.values())


def _shared_areas(family: shapes.Family, theta: np.ndarray) -> list[tuple[int, int, float]]:
    """(j, m, the share of the smaller lump's area inside the other's 50 % boundary) for each pair j < m."""
    if family.k < 2:
        return []
    ellipse = family.kind == "ellipses"
    lumps = shapes.lumps_of(family, theta)
    return [(int(j), int(m), _shared_area(lumps[j], lumps[m], ellipse)) for j, m in zip(*_pairs(family.k))]


def _shared_area(a: np.ndarray, b: np.ndarray, ellipse: bool) -> float:
    """The share of the smaller lump's area inside the other's 50 % boundary."""
    small, other = sorted((a, b), key=lambda params: params[2])
    major, minor, angle = shapes.axes_and_angle(small, ellipse)
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    ex, ey = major * _UNIT_DISC[:, 0], minor * _UNIT_DISC[:, 1]
    points = np.column_stack([small[0] + c * ex - s * ey, small[1] + s * ex + c * ey])
    return float((shapes.log_rho2(other, points, ellipse, derivatives=False)[0] < 0.0).mean())


def _sunflower(n: int) -> np.ndarray:
    """n points spread evenly over the unit disc (Vogel's spiral): equal areas, so a fraction of them is a
    fraction of the area."""
    i = np.arange(n) + 0.5
    r, t = np.sqrt(i / n), i * math.pi * (3.0 - math.sqrt(5.0))
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


_UNIT_DISC = _sunflower(256)


def unfelt(family: shapes.Family, theta: np.ndarray, obs: Observations, noise: float) -> list[int]:
    """The lumps no reading feels (see `supported`)."""
    if family.k == 0:
        return []
    usable = obs.kind >= 0  # exact readings and lower bounds
    heights = shapes.heights_of(family, theta, obs.xy)[usable]
    total = np.sqrt(obs.sd[usable] ** 2 + noise**2)
    top = np.log1p(heights.max(axis=1))
    felt = np.argmax(heights, axis=1)
    # a bound is felt by how far it would lie above the prediction without the lump, y − (f − top + without)
    slack = np.zeros(len(top))
    bound = obs.kind[usable] == AT_LEAST
    if bound.any():
        f, _ = shapes.evaluate(family, theta, obs.xy[usable][bound], jacobian=False)
        slack[bound] = obs.y[usable][bound] - f
    out = []
    for j in range(family.k):
        others = np.delete(heights, j, axis=1)
        without = np.log1p(others.max(axis=1)) if others.shape[1] else np.zeros(len(top))
        if not np.any(((top - without + slack) >= SUPPORT_SIGMA * total) & (felt == j)):
            out.append(j)
    return out
