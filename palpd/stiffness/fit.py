"""Fitting one model to one palpation: parameters, standard errors, residual, samples used."""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from palpd.stiffness.models import LINEAR_OFFSET, Model, initial_guess
from palpd.stiffness.samples import FitRejected, Samples, check_rise, prepare

BOUND_TOL = 1e-6  # a nonlinear model's parameter this close to its bound (scaled units) sits on it
# A press the force limit stops short of the reference indentation is read there along its own fitted curve
# if it reached 1/REACH of the way (the slope's sd carries the curve's parameters'); else at REACH times its
# deepest sample. A stiff lump in hardening tissue (exponent 2) stopped at 1.63 of 2 mm: read at the deepest
# sample, it came out 0.82 times the lump and the reported radius 0.53-0.67 mm large (IoU 0.84-0.87); read at
# 2 mm, 0.03 mm. Lumps 10 and 20 times the tissue, stopped at 1.15 and 0.82 mm: 0.37-0.43 and 0.98-1.09 mm
# large with REACH 1.5, 0.04 and 0.48 with 2 (the 54 shipped runs and 16 random scenes the same either way).
# Far beyond the data a curve is a guess (a power fit read 30 times beyond a 0.06 mm press).
REACH = 2.0


@dataclass(frozen=True)
class ModelFit:
    model: str
    params: dict[str, float]  # physical values, units in the names
    se: dict[str, float]  # their standard errors
    residual_rms_n: float
    samples: int
    rss_scaled: float  # residual sum of squares on the scaled forces, for the information criteria
    stiffness_n_per_mm: float  # dF/dx at the reference indentation
    stiffness_se_n_per_mm: float
    reference_depth_mm: float

    def as_dict(self) -> dict:
        return {"model": self.model, "params": self.params, "se": self.se, "residual_rms_n": self.residual_rms_n,
                "samples": self.samples, "stiffness_n_per_mm": self.stiffness_n_per_mm,
                "stiffness_se_n_per_mm": self.stiffness_se_n_per_mm, "reference_depth_mm": self.reference_depth_mm}


def fit_model(model: Model, samples: Samples, reference_depth_mm: float) -> ModelFit:
    d, f, rate = samples.scaled()
    reference_depth_mm = min(reference_depth_mm, REACH * float(samples.depth_mm.max()))
    if model.needs_rate and rate is None:
        raise FitRejected(f"model {model.name} needs the indentation rate", "bad_shape")
    theta = _solve_linear(model, d, f, rate) if model.linear else _solve_nonlinear(model, d, f, rate)
    residual = f - model.predict(theta, d, rate)
    rss = float(residual @ residual)
    cov = _covariance(model, theta, d, rate, rss) * _serial_inflation(residual)
    scales = (samples.depth_scale_mm, samples.force_scale_n, samples.rate_scale_mm_s)

    def physical(t):
        return model.physical(t, *scales)

    def stiffness(t):
        return float(model.tangent(physical(t), reference_depth_mm))

    params = physical(theta)
    _check_reference_in_data(model, params, samples, reference_depth_mm)
    jac_params = _numeric_jacobian(physical, theta)
    se = np.sqrt(np.maximum(np.diag(jac_params @ cov @ jac_params.T), 0.0))
    grad_k = _numeric_jacobian(lambda t: np.array([stiffness(t)]), theta)
    k_ref, k_se = stiffness(theta), math.sqrt(max(float((grad_k @ cov @ grad_k.T)[0, 0]), 0.0))
    if not (math.isfinite(k_ref) and math.isfinite(k_se) and np.all(np.isfinite(params))):
        raise FitRejected(f"model {model.name} gave no finite stiffness", "not_converged")
    return ModelFit(model.name, _named(model, params), _named(model, se),
                    math.sqrt(rss / d.size) * samples.force_scale_n, samples.n, rss, k_ref, k_se, reference_depth_mm)


def _check_reference_in_data(model: Model, params: np.ndarray, samples: Samples, reference_depth_mm: float) -> None:
    """A model with an onset reads its tangent at the reference indentation; where its onset puts the first
    sample already deeper than that, the tangent would be read where it has no data (soft damped tissue whose
    press slowed: an exponential put its onset 5.2 mm before the contact the hinge found and read 0.0008 ±
    0.0002 N/mm on 0.12, its amplitude and onset trading with nothing in between to tell them apart)."""
    if "delta_mm" not in model.params:
        return
    first_mm = float(samples.depth_mm.min()) + float(params[model.params.index("delta_mm")])
    if first_mm > reference_depth_mm:
        raise FitRejected(f"model {model.name} puts its first sample {first_mm:.2f} mm in, past the "
                          f"{reference_depth_mm:g} mm reference indentation", "not_converged")


def load_solvers() -> None:
    """Import the fits' scipy now. They import it at the first fit, so that a daemon that never palpates is
    ready in half the CPU; a scan or probe calls this before it turns the motors on, because on the wall clock
    the first fit happens while the servo loop holds the arm, and ~0.5 s of imports beside that 1 kHz loop on
    a busy host is CPU it does not need to share."""
    import scipy.optimize  # noqa: F401
    import scipy.special  # noqa: F401


def _named(model: Model, values) -> dict[str, float]:
    return {name: float(v) for name, v in zip(model.params, values)}


def _solve_linear(model: Model, d, f, rate) -> np.ndarray:
    design = model.predict.design(d, rate)
    theta, *_ = np.linalg.lstsq(design, f, rcond=None)
    return theta


def _solve_nonlinear(model: Model, d, f, rate) -> np.ndarray:
    # Here, not at the top: scipy.optimize costs ~0.5 s of CPU to import, and a daemon imports this module
    # at start-up (for its scans) whether or not it ever palpates.
    from scipy.optimize import least_squares

    lower, upper = (np.array(b, dtype=float) for b in model.bounds)
    best, best_cost = None, math.inf
    for start in model.starts:
        x0 = np.clip(initial_guess(model, start, d, f), lower + 1e-9, upper - 1e-9)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            result = least_squares(lambda t: model.predict(t, d, rate) - f, x0, bounds=(lower, upper),
                                   x_scale="jac", max_nfev=200)
        if np.all(np.isfinite(result.x)) and result.cost < best_cost:
            best, best_cost = result.x, result.cost
    if best is None:
        raise FitRejected(f"model {model.name} did not converge", "not_converged")
    pinned = [name for name, value, lo, hi in zip(model.params, best, lower, upper)
              if math.isclose(value, lo, abs_tol=BOUND_TOL * (1.0 + abs(lo)))
              or math.isclose(value, hi, abs_tol=BOUND_TOL * (1.0 + abs(hi)))]
    if pinned:
        # the likelihood still rises past the box: no optimum inside, so no curvature to read an sd from (a
        # chattering press on soft damped tissue had the power law's exponent at its bound of 3)
        raise FitRejected(f"model {model.name} ran to the edge of its parameters ({', '.join(pinned)})", "not_converged")
    return best


def _covariance(model: Model, theta, d, rate, rss: float) -> np.ndarray:
    jac = model.predict.design(d, rate) if model.linear else _numeric_jacobian(lambda t: model.predict(t, d, rate), theta)
    dof = max(d.size - theta.size, 1)
    return np.linalg.pinv(jac.T @ jac) * (rss / dof)


def _serial_inflation(residual: np.ndarray) -> float:
    """How much wider the parameters' variance is when neighbouring residuals move together (AR(1): (1 + ρ) /
    (1 - ρ), ρ the lag-one autocorrelation, never below 1). A sensor's white noise leaves ρ ≈ 0; a press that
    chatters on a stiff spot, or a model that misses the trace's shape, does not, and the plain least-squares
    sd then trusts 126 samples as if independent: 10.6 ± 0.30 N/mm read on a 12 N/mm lump (ρ = 0.71)."""
    if residual.size < 3:
        return 1.0
    denominator = float(residual @ residual)
    rho = float(residual[1:] @ residual[:-1]) / denominator if denominator > 0 else 0.0
    rho = min(max(rho, 0.0), 0.95)
    return (1.0 + rho) / (1.0 - rho)


def _numeric_jacobian(func, theta: np.ndarray) -> np.ndarray:
    theta = np.asarray(theta, dtype=float)
    base = np.atleast_1d(func(theta))
    jac = np.empty((base.size, theta.size))
    for i in range(theta.size):
        step = 1e-6 * max(abs(theta[i]), 1e-3)
        bumped = theta.copy()
        bumped[i] += step
        jac[:, i] = (np.atleast_1d(func(bumped)) - base) / step
    return jac


@dataclass(frozen=True, slots=True)
class LinearFit:
    """The foundation's straight-line fit, kept for its callers."""

    stiffness_n_per_mm: float
    intercept_n: float
    stiffness_se_n_per_mm: float
    residual_rms_n: float
    samples: int


def fit_linear(depth_mm, force_n) -> LinearFit:
    """Least-squares line force = k * depth + c; k is the stiffness (the seed paper's §3.1)."""
    samples = prepare(depth_mm, force_n)
    check_rise(samples)
    fit = fit_model(LINEAR_OFFSET, samples, 0.0)
    return LinearFit(fit.params["k_n_per_mm"], fit.params["c_n"], fit.se["k_n_per_mm"], fit.residual_rms_n, fit.samples)
