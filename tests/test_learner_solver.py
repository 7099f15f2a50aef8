"""The least-squares solver: starts that step together end where each would alone, and the give-up rule
is the one of starts run one after another."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from palpd.learner.solver import levenberg_marquardt, levenberg_marquardt_many

LO, HI = np.array([-5.0, -5.0]), np.array([5.0, 30.0])


def rosenbrock(xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A curved valley (minimum 0 at (1, 1)) that takes Levenberg–Marquardt tens of steps from afar."""
    r = np.stack([10.0 * (xs[:, 1] - xs[:, 0] ** 2), 1.0 - xs[:, 0]], axis=1)
    jac = np.zeros((len(xs), 2, 2))
    jac[:, 0, 0], jac[:, 0, 1], jac[:, 1, 0] = -20.0 * xs[:, 0], 10.0, -1.0
    return r, jac


def alone(start, steps: int = 200) -> tuple[np.ndarray, float, int]:
    return levenberg_marquardt(lambda x: tuple(a[0] for a in rosenbrock(x[None])), np.array(start), LO, HI, 1e-12, steps)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(-4.9, 4.9), st.floats(-4.9, 29.9)), min_size=1, max_size=6))
def test_starts_stepping_together_end_where_each_would_alone(starts):
    x, cost, calls = levenberg_marquardt_many(rosenbrock, np.array(starts), LO, HI, 1e-12, 200)
    for i, start in enumerate(starts):
        x1, cost1, calls1 = alone(start)
        assert np.allclose(x[i], x1, atol=1e-6) and abs(cost[i] - cost1) <= 1e-9
        assert calls[i] == calls1  # the same steps, each start by its own damping


def test_a_start_still_far_above_an_earlier_ones_end_is_given_up_with_its_cost_then():
    near, far = (-1.2, 1.0), (-4.5, -4.0)
    # the far start, after 2 steps, is still > 1 above where the near one ends (0): given up, as it would
    # be run after it; its cost is reported as it stood then
    x, cost, calls = levenberg_marquardt_many(rosenbrock, np.array([near, far]), LO, HI, 1e-12, 200, (2, 1.0))
    assert cost[0] < 1e-12 and cost[1] > 1.0 and abs(cost[1] - alone(far, steps=2)[1]) <= 1e-9
    # first in line, the same start has nothing to be judged against: it runs to the minimum, and the
    # near one, still 3.8 above that after its 2 steps, is given up in its turn
    x, cost, calls = levenberg_marquardt_many(rosenbrock, np.array([far, near]), LO, HI, 1e-12, 200, (2, 1.0))
    assert cost[0] < 1e-12 and np.allclose(x[0], alone(far)[0]) and calls[0] == alone(far)[2]
    assert abs(cost[1] - alone(near, steps=2)[1]) <= 1e-9 and cost[1] > 1.0
