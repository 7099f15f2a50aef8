"""A small Levenberg–Marquardt least-squares solver with box bounds, run from many starts at once.

The fits here have 3 to ~40 parameters and tens to hundreds of residuals, with
an analytic Jacobian: a general solver's per-call overhead would dominate.
Marquardt's scaled damping, steps projected onto the box. A fit tries up to
eight starts, and on a few dozen readings each step's cost is numpy's call
overhead, not arithmetic: the starts step together, each by its own damping,
their residuals evaluated in one batch (an ellipse's eight starts: 13–19 ms of CPU instead of 32–41).
"""
from __future__ import annotations

import numpy as np


def levenberg_marquardt(fun, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, tolerance: float,
                        max_iter: int = 60) -> tuple[np.ndarray, float, int]:
    """One start: minimise ½|r(x)|² within [lo, hi]; fun(x) returns (r, Jacobian).
    Returns the point, its cost and how many times `fun` was called."""
    x, cost, calls = levenberg_marquardt_many(lambda xs: tuple(a[None] for a in fun(xs[0])), x0[None, :],
                                              lo, hi, tolerance, max_iter)
    return x[0], float(cost[0]), int(calls[0])


def levenberg_marquardt_many(fun, starts: np.ndarray, lo: np.ndarray, hi: np.ndarray, tolerance: float,
                             max_iter: int = 60, give_up: tuple[int, float] | None = None):
    """Minimise ½|r(x)|² within the box [lo, hi] (d, or S × d: one per start) from each row of `starts`
    (S × d); fun(xs) returns the residuals and Jacobians of the rows of xs (s × m, s × m × d). A start is
    done when an accepted step gains less than `tolerance` (the cost's units) or barely moves. `give_up` (iterations, margin): a
    start whose cost after that many iterations is more than `margin` above the final cost of a start
    before it is dropped, its cost reported as it was then: the starts are in order of preference, and
    they end as if run one after another (only faster). Returns the points (S × d), their costs and how
    many times each was evaluated."""
    x = np.array(starts, dtype=float)
    r, jac = fun(x)
    count = len(x)
    calls = np.ones(count, dtype=int)
    cost = 0.5 * np.einsum("sm,sm->s", r, r)
    damping = np.full(count, 1e-3)
    active = np.ones(count, dtype=bool)
    hopeless = None if give_up is None else _Hopeless(count, give_up)
    index = np.arange(x.shape[1])  # the diagonal's (each step's numpy calls are its cost: none made twice)
    for iteration in range(max_iter):
        if hopeless is not None:
            hopeless.judge(iteration, cost, active)
        live = np.flatnonzero(active)
        if live.size == 0:
            break
        j, res = jac[live], r[live]
        jt = j.transpose(0, 2, 1)
        a, g = jt @ j, (jt @ res[:, :, None])[:, :, 0]
        diagonal = a.diagonal(axis1=1, axis2=2)
        scale = np.maximum(diagonal, 1e-12 * np.maximum(diagonal.max(axis=1), 1e-300)[:, None])
        damped = a.copy()
        damped[:, index, index] += damping[live, None] * scale
        step, solved = _solve_each(damped, -g)
        if solved is not None:  # some system was singular: more damping for those, the rest step
            damping[live[~solved]] *= 10.0
            live, step = live[solved], step[solved]
            if live.size == 0:
                continue
        trial = np.minimum(np.maximum(x[live] + step, _of(lo, live)), _of(hi, live))  # np.clip, without its wrapper
        r_new, jac_new = fun(trial)
        calls[live] += 1
        new_cost = 0.5 * np.einsum("sm,sm->s", r_new, r_new)
        better = np.isfinite(new_cost) & (new_cost < cost[live])
        moved = np.abs(trial - x[live]).max(axis=1)
        done = better & ((cost[live] - new_cost <= tolerance) | (moved < 1e-9))
        took = live[better]
        x[took], r[took], jac[took], cost[took] = trial[better], r_new[better], jac_new[better], new_cost[better]
        damping[took] = np.maximum(damping[took] / 3.0, 1e-9)
        worse = live[~better]
        damping[worse] *= 4.0
        active[live[done]] = False
        active[worse[damping[worse] > 1e10]] = False
    if hopeless is not None:
        active[:] = False  # out of iterations: every start ends here
        hopeless.judge(max_iter, cost, active)
    return x, cost, calls


class _Hopeless:
    """The give-up rule of starts run one after another, applied to starts that step together: start i is
    judged by its cost after `after` iterations against the final costs of the starts before it, once
    those have all ended (until then it runs on)."""

    def __init__(self, count: int, give_up: tuple[int, float]) -> None:
        self.after, self.margin = give_up
        self.cost_then = np.full(count, np.nan)  # nan: ended before the check (never given up)
        self.judged = 0  # starts before this one are judged

    def judge(self, iteration: int, cost: np.ndarray, active: np.ndarray) -> None:
        if iteration == self.after:
            self.cost_then[active] = cost[active]
        while self.judged < len(cost):
            i = self.judged
            if active[:i].any() or (active[i] and iteration < self.after):
                return  # a start before it still runs, or its check is still to come
            if i > 0 and self.cost_then[i] > np.min(cost[:i]) + self.margin:
                active[i] = False
                cost[i] = self.cost_then[i]
            self.judged += 1


def _of(box: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """A box's bounds for those starts: one box for all (d), or one per start (S × d)."""
    return box[rows] if box.ndim == 2 else box


def _solve_each(matrices: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Each system's solution and whether it had one (a singular one gets more damping, as for one start);
    None for "all had one", the common case, which then costs no mask."""
    try:
        return np.linalg.solve(matrices, rhs[:, :, None])[:, :, 0], None
    except np.linalg.LinAlgError:
        out, solved = np.zeros_like(rhs), np.ones(len(rhs), dtype=bool)
        for i in range(len(rhs)):
            try:
                out[i] = np.linalg.solve(matrices[i], rhs[i])
            except np.linalg.LinAlgError:
                solved[i] = False
        return out, solved
