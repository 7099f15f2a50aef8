"""The chosen fit's covariance, checked against the posterior itself along its widest directions.

The Laplace covariance (evidence.py) is the inverse Gauss–Newton curvature at
the mode: the posterior of a model linear in its parameters. Where the model
is far from linear that can be wrong by an order of magnitude. A deep lump
with the heaviest tails the family allows (edge sharpness at its floor, power
tails) is the case in point: background level, contrast, tail shape and radius
trade off to first order, so the curvature is nearly flat along that direction
and the radius sd comes out 1.4 mm, while one step of 1 sd along it raises
−log posterior by thousands of nats instead of ½, and the profile likelihood
pins the radius to about 0.1 mm.

So, as INLA does to explore a Laplace posterior (Rue, Martino & Chopin 2009),
the covariance is rescaled along each of its eigen-directions that carries a
reported quantity's variance: on each side, the step at which −log posterior
has actually risen by ½ (a few evaluations, no gradients), never past the
prior box; the direction's variance becomes the mean of the two sides'
squares. A direction that is as the curvature says keeps its variance; one
where the posterior is steeper narrows; one where it is flatter widens (at
most MAX_STRETCH).
"""
from __future__ import annotations

import math

import numpy as np

from palpd.learner.describe import quantities
from palpd.learner.evidence import COST_TOLERANCE, Fit, Priors, neg_log_posterior, stacked
from palpd.learner.observations import EXACT
from palpd.learner.solver import levenberg_marquardt_many

MAX_STRETCH = 2.0  # a direction's sd grows at most this much beyond the curvature's
MIN_SHARE = 0.01  # directions carrying less than this share of every reported variance are kept as they are
ITERATIONS = 4  # secant steps towards the ½-nat point on each side
EVIDENCE_ITERATIONS = 8  # for the evidence, whose every direction counts (a plateau and its cliff)
TINY_SHARE = 1e-12  # of the curvature's width: a direction with no room at all
CLOSE_ENOUGH = 0.1  # relative: the ½-nat point found
ON_EDGE = 1e-4  # of a prior's width: a parameter this close to the box's edge sits on it
PROFILE_STEPS = np.array([0.1, 0.25, 0.5, 0.8, 1.2])  # log radius offsets at which a radius's profile is read
PROFILE_ITERATIONS = 40  # the refit at each step (warm, from the step before)
PROFILE_SHARPER = (3.0, 9.0)  # edge sharpness factors of the profile's other starts


def checked_cov(fit: Fit, obs, priors: Priors) -> np.ndarray:
    """The fit's covariance with its quantity-carrying directions rescaled to the posterior's own ½-nat points."""
    rows = quantities(fit, priors.size_mm)
    if len(rows) == 0:
        return fit.cov
    lo, hi = priors.branch_bounds(fit.family, fit.theta)
    directions = _directions(fit.cov, fit.theta, lo, hi)
    carried = (rows @ directions) ** 2
    share = carried / np.maximum(carried.sum(axis=1, keepdims=True), 1e-300)
    objective = _objective(fit, obs, priors)
    base = objective(fit.theta)
    for j in np.flatnonzero((share >= MIN_SHARE).any(axis=0)):
        sides = [_half_nat_point(objective, base, fit.theta, sign * directions[:, j], lo, hi) for sign in (1.0, -1.0)]
        directions[:, j] *= math.sqrt(0.5 * (sides[0] ** 2 + sides[1] ** 2))
    return directions @ directions.T


def log_volume_ratio(fit: Fit, obs, priors: Priors) -> float:
    """log(posterior volume measured / Laplace's), what the fit's Laplace log evidence is to be
    corrected by (≤ 0): along every direction of its covariance, the mean of the two sides' ½-nat
    points (never wider than the curvature says, never past the prior box) scales its width.

    Laplace takes a direction the readings barely touch to be as wide as its prior: a lump that
    explains one reading on a plateau of its profile seems free to move anywhere on the tissue,
    while a few millimetres on it no longer covers that reading or is felt where the tissue is soft.
    Counted as free, six such lumps on ten readings out-weighed the plain tissue by nats they never
    had (a soft region read as four lumps)."""
    lo, hi = priors.branch_bounds(fit.family, fit.theta)
    directions = _directions(fit.cov, fit.theta, lo, hi, each_edge_alone=True)
    objective = _objective(fit, obs, priors)
    base = objective(fit.theta)
    log_volume = 0.0
    for j in np.flatnonzero(np.any(directions != 0.0, axis=0)):
        sides = [_half_nat_point(objective, base, fit.theta, sign * directions[:, j], lo, hi, 1.0,
                                 EVIDENCE_ITERATIONS) for sign in (1.0, -1.0)]
        log_volume += math.log(max(0.5 * (sides[0] + sides[1]), TINY_SHARE))
    return log_volume


def _directions(cov: np.ndarray, theta: np.ndarray, lo, hi, each_edge_alone: bool = False) -> np.ndarray:
    """Columns d_j with Σ d_j d_jᵀ = cov: the eigen-directions of the covariance given the parameters
    that sit on the prior box's edge, then those parameters' own directions (each moving the others
    as the posterior correlates them). A parameter on the edge is moved only by its own directions,
    so a direction that hardly touches it is not cut short by the edge.

    `each_edge_alone` (for a volume): each edge parameter's own direction moves it alone (the free ones
    following), by its sd given the others: still a 1-sd step by the curvature, so a posterior as
    Laplace has it measures a width of 1 along it. The eigen-directions of several edge parameters
    mix their signs, and a mix moves one of them out of the box whichever way it goes: measured as no
    room at all, that cost four lumps each on its tail's edge 55 nats of evidence they never owed."""
    span = hi - lo
    edge = np.isfinite(span) & (np.minimum(theta - lo, hi - theta) <= ON_EDGE * np.where(np.isfinite(span), span, 1.0))
    free = ~edge
    precision = np.linalg.pinv(cov)
    given = np.linalg.pinv(precision[np.ix_(free, free)])
    columns = [_scaled_eigenvectors(given, free)]
    if edge.any():
        block = cov[np.ix_(edge, edge)]
        if each_edge_alone:
            own = np.zeros((len(theta), int(edge.sum())))
            own[edge] = np.diag(1.0 / np.sqrt(np.maximum(np.diag(np.linalg.pinv(block)), 1e-300)))
        else:
            own = _scaled_eigenvectors(block, edge)
        own[free] = -given @ precision[np.ix_(free, edge)] @ own[edge]
        columns.append(own)
    return np.hstack(columns)


def _scaled_eigenvectors(cov: np.ndarray, where: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
    out = np.zeros((len(where), len(values)))
    out[where] = vectors * np.sqrt(np.maximum(values, 0.0))
    return out


def _objective(fit: Fit, obs, priors: Priors):
    """−log posterior, with the uniform priors' stand-in curvature the Laplace covariance also holds."""
    precision = priors.precision(fit.family, fit.theta)

    def objective(theta: np.ndarray) -> float:
        # a trial point far out along a direction may leave the shape's domain (a radius through zero):
        # its value is then not finite, which the callers read as "risen past", never as a warning
        with np.errstate(all="ignore"):
            return neg_log_posterior(fit.family, theta, obs, priors, fit.noise_sd) + 0.5 * float(
                precision @ (theta - fit.theta) ** 2)
    return objective


def _half_nat_point(objective, base: float, theta: np.ndarray, step: np.ndarray, lo, hi,
                    widest: float = MAX_STRETCH, iterations: int = ITERATIONS) -> float:
    """t (in units of `step`, a 1-sd move by the curvature) where the objective has risen by ½,
    never beyond `widest` nor the prior box along this side (the posterior holds no mass past it).
    Secant steps on the quadratic through the mode, kept inside the bracket of steps known to rise
    less and more than ½ (halved geometrically when a step leaves it): a plateau that ends in a
    cliff (a lump sliding off the one reading it explains) is neither jumped over nor taken for flat."""
    limit = min(widest, _room(theta, step, lo, hi))
    below, above = 0.0, math.inf
    t = min(1.0, limit)
    for _ in range(iterations):
        if t <= 0.0:
            return 0.0
        with np.errstate(all="ignore"):  # a step holding a non-finite entry gives a non-finite rise: "past"
            rise = objective(theta + t * step) - base
        if math.isfinite(rise) and rise <= 0.5:
            below = t
            if t >= limit:
                return limit
        else:
            above = t
        new = min(t / math.sqrt(2.0 * rise), limit) if math.isfinite(rise) and rise > 0.0 else limit
        if not below < new < above:
            new = math.sqrt(below * above) if below > 0.0 else 0.25 * above
        if abs(new - t) <= CLOSE_ENOUGH * t:
            return new
        t = new
    return math.sqrt(below * above) if below > 0.0 and math.isfinite(above) else t


def _room(theta: np.ndarray, step: np.ndarray, lo, hi) -> float:
    """How many steps fit before the prior box is left."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # a step of ~1e-308 has room without end
        up = np.where(step > 0, (hi - theta) / step, np.inf)
        down = np.where(step < 0, (lo - theta) / step, np.inf)
    return float(max(0.0, np.nanmin(np.minimum(up, down))))


def profiled_spread(fit: Fit, obs, priors: Priors, cov: np.ndarray) -> np.ndarray:
    """Where readings are censored, the spread along each lump's radius profile that `cov` misses.

    A lump read only as "too stiff" inside and on its far tails outside has no exact reading across its
    edge: its radius trades with its contrast and edge along a curved ridge of the posterior, which steps
    straight along the covariance's directions (checked_cov) leave at once. A 200 N/mm lump of 8 mm in
    0.5 N/mm tissue was reported 3.53 ± 0.23 mm and the scan stopped. So each lump's log radius is held at
    steps either side of the mode and everything else refitted, each step from where the last one ended
    (one batch of starts per step); where the profile has risen by ½ on each side, the refitted point less
    the mode is a spread along the ridge, added where it reaches further than `cov` says (a profile as
    narrow as cov adds nothing)."""
    spread = np.zeros_like(cov)
    if fit.family.k == 0 or bool(np.all(obs.kind == EXACT)):
        return spread
    lo, hi = priors.branch_bounds(fit.family, fit.theta)
    base = neg_log_posterior(fit.family, fit.theta, obs, priors, fit.noise_sd)
    shapes_tried = len(PROFILE_SHARPER) + 1
    for j in range(fit.family.k):
        part = fit.family.lump_slice(j)
        at, tail, sharpness = part.start + 2, part.stop - 3, part.stop - 2  # log radius, λ, log s
        # each side traced outwards, every step's refit starting where the last one ended (a ridge is
        # followed, not jumped onto), and from there with Hill tails and a sharper edge (along the
        # ridge, a wider lump has a sharper edge)
        ends = []
        for sign in (-1.0, 1.0):
            here, points, rises = fit.theta, [], []
            for offset in PROFILE_STEPS:
                starts = np.repeat(here[None, :], shapes_tried, axis=0)
                starts[:, at] = fit.theta[at] + sign * offset
                for row, factor in enumerate(PROFILE_SHARPER, start=1):
                    starts[row, tail] = 0.0  # Hill tails (where the two tail branches meet)
                    starts[row, sharpness] += math.log(factor)
                starts = np.clip(starts, lo, hi)
                low, high = lo.copy(), hi.copy()
                low[at] = high[at] = starts[0, at]
                with np.errstate(all="ignore"):
                    refits, _, _ = levenberg_marquardt_many(
                        lambda many: stacked(fit.family, many, obs, priors, fit.noise_sd), starts, low, high,
                        COST_TOLERANCE, PROFILE_ITERATIONS)
                    rise = np.array([neg_log_posterior(fit.family, t, obs, priors, fit.noise_sd) - base
                                     for t in refits])
                rise = np.where(np.isfinite(rise), rise, np.inf)
                here = refits[int(np.argmin(rise))]
                points.append(here)
                rises.append(float(rise.min()))
                if rises[-1] > 0.5:
                    break
            ends.append(_half_nat_end(np.array(points), np.array(rises), fit.theta))
        reach = 0.5 * sum(float(d[at]) ** 2 for d in ends)
        if reach > cov[at, at]:
            spread += (1.0 - cov[at, at] / reach) * 0.5 * sum(np.outer(d, d) for d in ends)
    return spread


def _half_nat_end(points: np.ndarray, rises: np.ndarray, mode: np.ndarray) -> np.ndarray:
    """Along one side of a profile (points in order away from the mode), the point where the rise crosses ½
    (between the last point below and the first above, linearly; the mode is the first point below), less
    the mode; the farthest point if the profile never rises that far."""
    before, rise_before = mode, 0.0
    for point, rise in zip(points, rises):
        if not (math.isfinite(rise) and rise <= 0.5):
            share = (0.5 - rise_before) / (rise - rise_before) if math.isfinite(rise) and rise > rise_before else 0.0
            return before + share * (point - before) - mode
        before, rise_before = point, max(rise, 0.0)
    return before - mode
