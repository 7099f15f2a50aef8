"""Choosing the model a palpation's data asks for, by AICc or BIC, and the one comparable number.

The simplest model wins unless a richer one is clearly better: among models
whose criterion lies within CLEARLY_BETTER of the best, the one with the
fewest parameters is chosen. The stiffness reported is the chosen model's
dF/dx at the reference indentation, with its standard error (the learner's
observation noise).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from palpd.stiffness.fit import ModelFit, fit_model
from palpd.stiffness.models import MODELS, candidates
from palpd.stiffness.samples import FitRejected, check_rise, prepare

CRITERIA = ("aicc", "bic")
CLEARLY_BETTER = 2.0  # Burnham & Anderson: a difference below 2 is no real support
NOT_EXCLUDED = 10.0  # Kass & Raftery: below 10 the evidence against a model is not very strong; its reading counts
SELECT = "select"
CURVATURE_P = 1e-3  # a curved model is tried only when a straight line is this unlikely to leave such curvature


@dataclass(frozen=True)
class StiffnessResult:
    chosen: ModelFit
    criterion: str
    scores: dict[str, float]  # criterion value of every model tried (lower is better)

    @property
    def stiffness_n_per_mm(self) -> float:
        return self.chosen.stiffness_n_per_mm

    @property
    def stiffness_se_n_per_mm(self) -> float:
        return self.chosen.stiffness_se_n_per_mm

    @property
    def model(self) -> str:
        return self.chosen.model

    @property
    def samples(self) -> int:
        return self.chosen.samples


def information_criterion(fit: ModelFit, parameters: int, criterion: str) -> float:
    return _criterion(fit.rss_scaled, fit.samples, parameters, criterion)


def _criterion(rss: float, n: int, parameters: int, criterion: str) -> float:
    p = parameters + 1  # + 1: the noise variance is estimated too
    log_likelihood_term = n * math.log(max(rss / n, 1e-300))
    if criterion == "bic":
        return log_likelihood_term + p * math.log(n)
    correction = 2.0 * p * (p + 1) / (n - p - 1) if n - p - 1 > 0 else math.inf
    return log_likelihood_term + 2.0 * p + correction


def fit_stiffness(depth_mm, force_n, rate_mm_s=None, saturated=None, model: str = SELECT,
                  criterion: str = "bic", reference_depth_mm: float = 2.0) -> StiffnessResult:
    """Fit one palpation with the named model, or select among all it supports. Raises FitRejected."""
    if criterion not in CRITERIA:
        raise ValueError(f"unknown criterion {criterion!r}; choose from {', '.join(CRITERIA)}")
    samples = prepare(depth_mm, force_n, rate_mm_s, saturated)
    check_rise(samples)
    if model != SELECT:
        if model not in MODELS:
            raise ValueError(f"unknown stiffness model {model!r}; choose from {SELECT}, {', '.join(MODELS)}")
        fit = fit_model(MODELS[model], samples, reference_depth_mm)
        return StiffnessResult(fit, criterion, {fit.model: information_criterion(fit, MODELS[model].size, criterion)})
    return _select(samples, criterion, reference_depth_mm)


def _select(samples, criterion: str, reference_depth_mm: float) -> StiffnessResult:
    fits, scores = [], {}
    curved = _clearly_curved(samples, criterion)
    for candidate in candidates(samples.rate_mm_s is not None):
        if candidate.name == "linear" and samples.n > 3:
            continue  # through the contact point: but that point is itself estimated, and its error would be k's
        if not (candidate.linear or curved):
            continue  # a curved model cannot win where even a parabola does no better than a line
        if candidate.size >= samples.n - 1:
            continue  # not enough samples to tell this model's parameters apart
        try:
            fit = fit_model(candidate, samples, reference_depth_mm)
        except FitRejected:
            continue
        fits.append((candidate.size, fit))
        scores[fit.model] = information_criterion(fit, candidate.size, criterion)
    if not fits:
        raise FitRejected("no stiffness model could be fitted", "not_converged")
    best = min(scores.values())
    plausible = [(size, fit) for size, fit in fits if scores[fit.model] <= best + CLEARLY_BETTER]
    rivals = [fit for _, fit in fits if scores[fit.model] <= best + NOT_EXCLUDED]
    chosen = _with_model_spread(min(plausible, key=lambda pair: pair[0])[1], rivals)
    if chosen.stiffness_n_per_mm <= 0:
        raise FitRejected(f"model {chosen.model} gives no positive stiffness", "no_rise")
    return StiffnessResult(chosen, criterion, scores)


def _with_model_spread(chosen: ModelFit, plausible: list[ModelFit]) -> ModelFit:
    """The chosen fit, its stiffness's standard error widened to cover every model not excluded: when the data
    cannot tell a power law from an exponential, either may be the right one, its tangent differs from the
    chosen one's, and it is known only to its own standard error. Each rival's offset is combined with the
    larger of the two errors: soft curved tissue under 0.1 N of noise chose an exponential (BIC 2.3 better)
    that read 0.122 ± 0.007 N/mm where the power law it could not exclude read 0.119 ± 0.012 and the truth
    was 0.091 (the two trade the contact point for curvature differently; the offset alone added 0.003)."""
    se = chosen.stiffness_se_n_per_mm
    widest = max(math.hypot(max(se, fit.stiffness_se_n_per_mm), fit.stiffness_n_per_mm - chosen.stiffness_n_per_mm)
                 for fit in plausible)
    return replace(chosen, stiffness_se_n_per_mm=max(se, widest))


def _clearly_curved(samples, criterion: str) -> bool:
    """Whether a parabola beats a straight line by the same margin selection asks of any richer model.

    A cheap linear screen: the curved models need iterative fits (most of a palpation's CPU time),
    and on a straight trace they could not be chosen anyway.
    """
    d, f, _ = samples.scaled()
    n = samples.n
    if n < 5:
        return True
    rss = []
    for columns in ((np.ones_like(d), d), (np.ones_like(d), d, d * d)):
        design = np.column_stack(columns)
        solution, *_ = np.linalg.lstsq(design, f, rcond=None)
        residual = f - design @ solution
        rss.append(float(residual @ residual))
    by_criterion = _criterion(rss[1], n, 3, criterion) < _criterion(rss[0], n, 2, criterion) - CLEARLY_BETTER
    return by_criterion and _curvature_p(rss[0], rss[1], n) < CURVATURE_P


def _curvature_p(rss_line: float, rss_parabola: float, n: int) -> float:
    """The exact F-test of the parabola's one extra term: an information criterion's asymptotics do not hold
    for a dozen samples, where noise alone bends a trace often enough to pass BIC by the margin."""
    if rss_parabola <= 0.0:
        return 0.0 if rss_line > 0.0 else 1.0
    from scipy.special import fdtrc  # here: scipy.special costs ~0.2 s to import, a daemon that never fits

    f_stat = (rss_line - rss_parabola) / (rss_parabola / (n - 3))
    return float(fdtrc(1, n - 3, max(f_stat, 0.0)))
