"""A small Levenberg–Marquardt least-squares solver with box bounds.

The fits here have 3 to ~40 parameters and tens to hundreds of residuals, with
an analytic Jacobian: a general solver's per-call overhead would dominate.
Marquardt's scaled damping, steps projected onto the box.
"""
from __future__ import annotations

import numpy as np


def levenberg_marquardt(fun, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, tolerance: float,
                        max_iter: int = 60, give_up: tuple[int, float] | None = None) -> tuple[np.ndarray, float, int]:
    """Minimise ½|r(x)|² within the box [lo, hi]; fun(x) returns (r, Jacobian). Done when an
    accepted step gains less than `tolerance` (the cost's units) or barely moves. `give_up`
    (iterations, cost): stop early a start still above that cost after that many iterations.
    Returns the point, its cost and how many times `fun` was called."""
    x = x0.copy()
    r, jac = fun(x)
    calls = 1
    cost = 0.5 * float(r @ r)
    damping = 1e-3
    for iteration in range(max_iter):
        if give_up is not None and iteration == give_up[0] and cost > give_up[1]:
            break
        a, g = jac.T @ jac, jac.T @ r
        scale = np.maximum(np.diag(a), 1e-12 * max(float(np.max(np.diag(a))), 1e-300))
        try:
            step = np.linalg.solve(a + damping * np.diag(scale), -g)
        except np.linalg.LinAlgError:
            damping *= 10.0
            continue
        trial = np.clip(x + step, lo, hi)
        r_new, jac_new = fun(trial)
        calls += 1
        new_cost = 0.5 * float(r_new @ r_new)
        if np.isfinite(new_cost) and new_cost < cost:
            done = cost - new_cost <= tolerance or np.max(np.abs(trial - x)) < 1e-9
            x, r, jac, cost = trial, r_new, jac_new, new_cost
            damping = max(damping / 3.0, 1e-9)
            if done:
                break
        else:
            damping *= 4.0
            if damping > 1e10:
                break
    return x, cost, calls
