"""The online learner: stiffness points in, P(lump) map, lumps and the next probe out.

Usable embedded (palpd scan --strategy active, through ActivePlanner) and as its
own process (palpd learner). One observe() is an O(n·G) update of the GP on
the candidate grid; hyperparameters are refitted only while there are few
points, when the data has grown by `refit_growth`, or when the contrast test
changes its mind (a lump appears in the data).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

from palpd.estimate import LumpEstimate
from palpd.learner import acquisition
from palpd.learner.gp import Hyper, IncrementalGP, fit_hyper
from palpd.learner.lumps import Map, find_lumps
from palpd.learner.threshold import Levels, levels, lump_points, supervised_levels, tau_field

EARLY_REFIT_POINTS = 20  # below this a refit costs next to nothing and the kernel still moves a lot


class Learner:
    def __init__(self, size_mm: tuple[float, float], settings, min_contrast: float = 0.3, seed: int = 0,
                 travel_mm_per_palpation: float = 100.0, supervised_tau_n_per_mm: float | None = None) -> None:
        self.settings = settings
        self.supervised_tau_n_per_mm = supervised_tau_n_per_mm  # None: τ from the data (unsupervised)
        self.min_contrast = min_contrast
        self.travel_mm_per_palpation = travel_mm_per_palpation
        half_w, half_h = size_mm[0] / 2.0, size_mm[1] / 2.0
        self.xs = np.linspace(-half_w, half_w, settings.grid_points)
        self.ys = np.linspace(-half_h, half_h, settings.grid_points)
        gx, gy = np.meshgrid(self.xs, self.ys)
        self.grid_xy = np.column_stack([gx.ravel(), gy.ravel()])
        self.cell_area_mm2 = float((self.xs[1] - self.xs[0]) * (self.ys[1] - self.ys[0]))
        low, high = settings.length_scale_mm
        self.gp = IncrementalGP(self.grid_xy, Hyper(0.0, 1.0, math.sqrt(low * high), 1e-6))
        self.design = acquisition.initial_design(size_mm, settings.initial_points, seed)
        self.blocked = np.zeros(len(self.grid_xy), dtype=bool)
        self.probed: list[tuple[float, float]] = []
        self.levels: Levels | None = None
        self._fitted_at = 0
        self._tau = self._p = None

    # -- learning -------------------------------------------------------------------------------
    def observe(self, xy_mm, stiffness_n_per_mm: float | None, sd_n_per_mm: float = 0.0) -> None:
        """One palpation's result; a palpation without a stiffness still counts and blocks its spot."""
        xy = (float(xy_mm[0]), float(xy_mm[1]))
        self.probed.append(xy)
        acquisition.block_near(self.blocked, self.grid_xy, xy, self.settings.min_spacing_mm)
        if stiffness_n_per_mm is None or not math.isfinite(stiffness_n_per_mm) or stiffness_n_per_mm <= 0:
            return
        sd = sd_n_per_mm if math.isfinite(sd_n_per_mm) and sd_n_per_mm > 0 else 0.0
        self.gp.add(xy, stiffness_n_per_mm, sd * sd)
        new_levels = self._levels()
        if self._refit_pays(new_levels):
            self._refit(new_levels)
        self.levels = new_levels
        self._update_map()

    def _levels(self) -> Levels:
        if self.supervised_tau_n_per_mm is None:
            return levels(self.gp.y, self.min_contrast)
        return supervised_levels(self.gp.y, np.sqrt(self.gp.noise_var), self.supervised_tau_n_per_mm)

    def _refit_pays(self, new: Levels) -> bool:
        n = self.gp.n
        return (n <= EARLY_REFIT_POINTS or n >= self.settings.refit_growth * self._fitted_at
                or self.levels is None or new.contrast != self.levels.contrast)

    def _refit(self, lv: Levels) -> None:
        gp = self.gp
        floor = max(lv.tau_n_per_mm - lv.tissue_n_per_mm, 1e-6)
        hyper = fit_hyper(gp.xy, gp.y, gp.noise_var, lv.tissue_n_per_mm, gp.hyper,
                          self.settings.length_scale_mm, floor) if gp.n >= 3 else \
            Hyper(lv.tissue_n_per_mm, floor**2, gp.hyper.length_mm, 1e-6 * floor**2)
        gp.refit(hyper)
        self._fitted_at = gp.n

    def _update_map(self) -> None:
        shape = (len(self.ys), len(self.xs))
        mean = self.gp.mean.reshape(shape)
        reach_cells = 2.0 * self.gp.hyper.length_mm / (self.xs[1] - self.xs[0])
        self._tau = tau_field(mean, self.levels, reach_cells, self._cells_of(self.gp.xy), self.gp.y).ravel()
        self._p = ndtr((self.gp.mean - self._tau) / self.gp.std())

    def _cells_of(self, xy: np.ndarray) -> np.ndarray:
        """(row, col) of the grid cell nearest each point."""
        step_x, step_y = self.xs[1] - self.xs[0], self.ys[1] - self.ys[0]
        cols = np.clip(np.rint((xy[:, 0] - self.xs[0]) / step_x).astype(int), 0, len(self.xs) - 1)
        rows = np.clip(np.rint((xy[:, 1] - self.ys[0]) / step_y).astype(int), 0, len(self.ys) - 1)
        return np.column_stack([rows, cols])

    # -- answers --------------------------------------------------------------------------------
    @property
    def points(self) -> int:
        return len(self.probed)

    def p_lump(self) -> np.ndarray | None:
        """P(lump) on the grid, shape (len(ys), len(xs)); None before the first stiffness."""
        return None if self._p is None else self._p.reshape(len(self.ys), len(self.xs))

    def ambiguous_area_mm2(self) -> float | None:
        if self._p is None:
            return None
        c = self.settings.confidence
        return float(np.count_nonzero((self._p > 1.0 - c) & (self._p < c))) * self.cell_area_mm2

    def next_probe(self, max_palpations: int | None = None) -> tuple[float, float] | None:
        """Where to palpate next, or None when the map is sure enough (or the budget is spent)."""
        budget = self.settings.max_palpations if max_palpations is None else max_palpations
        if self.points >= budget:
            return None
        if self.points < len(self.design):
            return self.design[self.points]
        if self._p is None or self._sure_enough():
            return None
        score = acquisition.straddle(self.gp.mean, self.gp.std(), self._tau, self.settings.confidence)
        here = self.probed[-1] if self.probed else None
        return acquisition.best_candidate(score, self.grid_xy, self.blocked, here, self.travel_mm_per_palpation)

    @property
    def grid_area_mm2(self) -> float:
        return self.cell_area_mm2 * len(self.grid_xy)

    def _sure_enough(self) -> bool:
        return self.ambiguous_area_mm2() <= self.settings.max_ambiguous_fraction * self.grid_area_mm2

    def lumps(self) -> list[LumpEstimate]:
        if self.levels is None or not self.levels.contrast:
            return []
        shape = (len(self.ys), len(self.xs))
        grid_map = Map(self.xs, self.ys, self.gp.mean.reshape(shape), self.gp.std().reshape(shape),
                       self._tau.reshape(shape), self.gp.hyper.length_mm)
        stiff = lump_points(self.gp.y, np.sqrt(self.gp.noise_var), self.levels)
        return find_lumps(grid_map, self.gp.xy[stiff])
