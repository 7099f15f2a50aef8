"""Force–displacement models of one palpation, in the order of their complexity.

Fits run on samples scaled to order one (depth / D, force / F, rate / V), so
stiffness from 1e-4 to 1e3 N/mm and indentation from 1 µm to 30 mm all look
alike to the solver; `physical` maps the scaled parameters back to units.
`x` is the true indentation: the measured depth (from the detected contact)
plus the model's contact offset δ, since contact is detected only once the
force has reached a threshold.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Model:
    name: str
    params: tuple[str, ...]  # physical parameter names, units in the name
    linear: bool  # linear in its parameters: solved exactly, no iterations
    needs_rate: bool
    predict: Callable  # (theta_scaled, d, rate) -> force, all scaled
    physical: Callable  # (theta_scaled, D, F, V) -> physical parameters
    tangent: Callable  # (physical params, x_ref_mm) -> dF/dx at the reference indentation, N/mm
    starts: tuple[dict, ...] = ()  # initial guesses for the nonlinear ones
    bounds: tuple[tuple[float, ...], tuple[float, ...]] | None = None

    @property
    def size(self) -> int:
        return len(self.params)


def _design_linear(d, rate):
    return d[:, None]


def _design_offset(d, rate):
    return np.column_stack([d, np.ones_like(d)])


def _design_kelvin_voigt(d, rate):
    return np.column_stack([d, rate, np.ones_like(d)])


def _indentation(d, delta):
    return np.maximum(d + delta, 0.0)


def _hunt_crossley(theta, d, rate):
    k, n, b, delta = theta
    power = _indentation(d, delta) ** n
    return k * power + b * power * rate


def _power(theta, d, rate):
    k, n, delta = theta
    return k * _indentation(d, delta) ** n


def _exponential(theta, d, rate):
    a, beta, delta = theta
    return a * np.expm1(beta * _indentation(d, delta))


def _linear_predict(design):
    def predict(theta, d, rate):
        return design(d, rate) @ np.asarray(theta)

    predict.design = design  # the solver reads the design matrix from here
    return predict


LINEAR = Model(
    "linear", ("k_n_per_mm",), True, False, _linear_predict(_design_linear),
    lambda t, D, F, V: np.array([t[0] * F / D]), lambda p, x: p[0],
)
LINEAR_OFFSET = Model(
    "linear-offset", ("k_n_per_mm", "c_n"), True, False, _linear_predict(_design_offset),
    lambda t, D, F, V: np.array([t[0] * F / D, t[1] * F]), lambda p, x: p[0],
)
KELVIN_VOIGT = Model(
    "kelvin-voigt", ("k_n_per_mm", "b_n_s_per_mm", "c_n"), True, True, _linear_predict(_design_kelvin_voigt),
    lambda t, D, F, V: np.array([t[0] * F / D, t[1] * F / V, t[2] * F]), lambda p, x: p[0],
)
HUNT_CROSSLEY = Model(
    "hunt-crossley", ("k_n_per_mm_n", "n", "b_n_s_per_mm_n1", "delta_mm"), False, True, _hunt_crossley,
    lambda t, D, F, V: np.array([t[0] * F / D ** t[1], t[1], t[2] * F / (D ** t[1] * V), t[3] * D]),
    lambda p, x: p[0] * p[1] * max(x + 0.0, 1e-12) ** (p[1] - 1.0),
    starts=({"n": 1.0}, {"n": 1.5}, {"n": 2.2}),
    bounds=((0.0, 0.5, -np.inf, -0.5), (np.inf, 3.0, np.inf, 1.0)),
)
POWER = Model(  # Hunt–Crossley without damping, for traces that carry no rate
    "power", ("k_n_per_mm_n", "n", "delta_mm"), False, False, _power,
    lambda t, D, F, V: np.array([t[0] * F / D ** t[1], t[1], t[2] * D]),
    lambda p, x: p[0] * p[1] * max(x, 1e-12) ** (p[1] - 1.0),
    starts=({"n": 1.0}, {"n": 1.5}, {"n": 2.2}),
    bounds=((0.0, 0.5, -0.5), (np.inf, 3.0, 1.0)),
)
EXPONENTIAL = Model(
    "exponential", ("a_n", "beta_per_mm", "delta_mm"), False, False, _exponential,
    lambda t, D, F, V: np.array([t[0] * F, t[1] / D, t[2] * D]),
    lambda p, x: p[0] * p[1] * np.exp(min(p[1] * x, 700.0)),
    starts=({"beta": 0.3}, {"beta": 1.5}),
    bounds=((0.0, 1e-3, -0.5), (np.inf, 50.0, 1.0)),
)

MODELS = {m.name: m for m in (LINEAR, LINEAR_OFFSET, KELVIN_VOIGT, POWER, EXPONENTIAL, HUNT_CROSSLEY)}


def candidates(has_rate: bool) -> list[Model]:
    """The models a trace can support, simplest first."""
    return [m for m in MODELS.values() if has_rate or not m.needs_rate]


def initial_guess(model: Model, start: dict, d: np.ndarray, f: np.ndarray) -> np.ndarray:
    """A start whose amplitude already matches the data, so the solver only refines the shape."""
    delta = 0.02
    if model is EXPONENTIAL:
        shape = np.expm1(start["beta"] * _indentation(d, delta))
        return np.array([_amplitude(shape, f), start["beta"], delta])
    shape = _indentation(d, delta) ** start["n"]
    amplitude = _amplitude(shape, f)
    return np.array([amplitude, start["n"], 0.0, delta] if model is HUNT_CROSSLEY else [amplitude, start["n"], delta])


def _amplitude(shape: np.ndarray, f: np.ndarray) -> float:
    denominator = float(shape @ shape)
    return max(float(shape @ f) / denominator, 1e-6) if denominator > 0 else 1.0
