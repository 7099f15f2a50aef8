"""The learner's parts: the GP's one-block refit, the evidence's choice on fixed readings, the layering."""
import math
import subprocess
import sys

import numpy as np
import pytest

from palpd import metrics
from palpd.learner.gp import Hyper, IncrementalGP
from palpd.learner.hypotheses import Hypotheses
from palpd.learner.observations import Observations


def grid(side=21):
    axis = np.linspace(-30.0, 30.0, side)
    gx, gy = np.meshgrid(axis, axis)
    return np.column_stack([gx.ravel(), gy.ravel()])


def test_a_one_block_refit_equals_the_row_by_row_posterior_and_survives_duplicate_points():
    rng = np.random.default_rng(0)
    xy = rng.uniform(-30, 30, (40, 2))
    y = np.log(0.12 + 0.5 * (np.hypot(*(xy - 5.0).T) < 8))
    hyper = Hyper(np.log(0.12), 0.5, 4.0, 1e-4)
    rows, read_each_time = IncrementalGP(grid(), hyper), IncrementalGP(grid(), hyper)
    for p, v in zip(xy, y):
        rows.add(p, v, 1e-4)
        read_each_time.add(p, v, 1e-4)
        read_each_time.var  # the grid's rows one at a time, where `rows` makes them in one block when asked
    assert read_each_time.mean == pytest.approx(rows.mean, abs=1e-5)
    block = IncrementalGP(grid(), hyper)
    block.xy, block.y, block.noise_var = rows.xy, rows.y, rows.noise_var
    block.refit(hyper)
    assert block.mean == pytest.approx(rows.mean, abs=1e-5) and block.var == pytest.approx(rows.var, abs=1e-5)
    assert block.log_marginal_likelihood() == pytest.approx(rows.log_marginal_likelihood(), rel=1e-6)
    same = IncrementalGP(grid(), Hyper(0.0, 1.0, 4.0, 0.0))  # the same spot, no noise: a singular block
    for _ in range(5):
        same.add((1.0, 1.0), 0.3, 0.0)
    same.refit(Hyper(0.0, 1.0, 5.0, 0.0))
    assert np.all(np.isfinite(same.mean)) and np.all(np.isfinite(same.std()))


def readings(k_at, points):
    obs = Observations()
    for p in points:
        obs.add(p, "fit", k_at(p), 0.0004)
    return obs


def lattice(step=6.0):
    axis = np.arange(-27.0, 27.1, step)
    return [(x, y) for x in axis for y in axis]


def test_the_evidence_picks_one_lump_not_two_two_not_one_and_none_on_flat_tissue():
    def lumps_at(*centres):
        return lambda p: 0.12 + max([0.68 / (1 + (math.dist(p, c) / 7.0) ** 8) for c in centres] + [0.0])

    for k_at, chosen in [(lumps_at((5.0, 5.0)), "circles:1"), (lumps_at((-12.0, -10.0), (12.0, 12.0)), "circles:2"),
                         (lambda p: 0.12, "none")]:
        obs = readings(k_at, lattice())
        hypotheses = Hypotheses((60.0, 60.0), 0.3, 0.01)
        hypotheses.update(obs, [], math.log(0.12))
        assert hypotheses.choice(None, obs).chosen == chosen, (chosen, hypotheses.choice(None, obs))


def test_map_truth_is_the_half_height_region_and_iou_compares_polygons(tmp_path):
    axis = np.arange(-30.0, 30.1, 1.0)
    rows = ["x_mm,y_mm,stiffness_n_per_mm"]
    for x in axis:
        for y in axis:
            rows.append(f"{x},{y},{0.12 + 0.5 * math.exp(-((x - 2) ** 2 + y**2) / (2 * 6.0**2)):.5f}")
    path = tmp_path / "bump.csv"
    path.write_text("\n".join(rows) + "\n")
    (region,) = metrics.map_regions(path, (60.0, 60.0), 0.3)
    assert region["center_mm"] == pytest.approx([2.0, 0.0], abs=0.1)
    assert region["radius_mm"] == pytest.approx(6.0 * math.sqrt(2 * math.log(2)), abs=0.2)
    disc = [[2 + region["radius_mm"] * math.cos(t), region["radius_mm"] * math.sin(t)]
            for t in np.linspace(0, 2 * math.pi, 73)]
    assert metrics.iou(disc, region) > 0.97
    assert metrics.iou(disc, {"center_mm": [12.0, 0.0], "radius_mm": region["radius_mm"]}) < 0.3


def test_the_learner_imports_nothing_above_it():
    code = ("import sys, palpd.learner, palpd.learner.service; "
            "print(sorted(m for m in sys.modules if m.startswith('palpd.') and not m.startswith('palpd.learner')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = set(eval(out))  # noqa: S307 (our own print of a list of names)
    assert not loaded & {"palpd.scan", "palpd.dataset", "palpd.bench", "palpd.daemon", "palpd.commands"}, loaded
