"""What the learner answers from its hypotheses: the lumps, the verdict, when to stop, where next.

The stop rule is `Decision.decided`, and its docstring states it: the count is decided, the boundary is
known to the user's tolerance, and the readings are explained. Never on no evidence: with fewer usable
readings than the simplest lump model has parameters the learner keeps palpating, and a budget spent
before the rule holds is the verdict `undetermined`, never "no lump".
"""
from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import ndtr

from palpd.estimate import LumpEstimate
from palpd.learner import acquisition, coverage, describe, shapes
from palpd.learner.evidence import ADEQUATE_NOISE, SUPPORT_SIGMA, Fit, loo_log_density
from palpd.learner.hypotheses import lumps_claimed
from palpd.learner.likelihood import texture_sd
from palpd.learner.lumps import find_lumps
from palpd.learner.observations import AT_LEAST
from palpd.learner.priors import MAX_RADIUS_FRACTION, MIN_RADIUS_MM
from palpd.learner.threshold import surely_above

MIN_READINGS = shapes.Family("circles", 1, 1.0).size  # the simplest lump model's parameter count
MIN_WEIGHT = 0.01  # hypotheses below this weight are left out of the disagreement
MAX_RIVALS = 4
CENTRE_REACH = 0.5  # `none` waits for a palpation this share of its reach (none_reach_mm) from the tissue's centre
CANDIDATE_STRIDE_MM = 1.0  # probes are chosen on a lattice at least this fine
NEGLIGIBLE_NATS = 1e-3  # a reading the rivals disagree about by less than this tells them apart by nothing
DECISIVE_WEIGHT = 1e-6  # a rival this far below the choice (14 nats) is left to the evidence alone (_decisive_spot)
PREDICTED_SIGMA = 3.0  # never stop right after a reading the chosen fit did not predict within this many sd
AREA_STEP_MM = 2.0  # the free-form map's next probe: its misclassified area scored on a lattice this fine...
AREA_CELLS = 1024  # ...or coarser, to at most this many cells (a 60 mm tissue's is 31 × 31; pairs go as its square)
DOUBT = 1e-3  # ...over the cells whose min(P, 1 − P) is above this


class Decision:
    """Mixed into Learner: needs choice, hypotheses, obs, gp, settings, grid and probe bookkeeping."""

    def chosen_fit(self) -> Fit | None:
        """The chosen parametric fit, its covariance checked against the posterior (posterior.py):
        what is reported, what the stop rule reads and what the next probe is to shrink."""
        return None if self.choice is None else self.hypotheses.checked(self.choice.chosen, self.obs)

    def model(self) -> dict | None:
        """{chosen, weight, runner_up, drawn_by, unfelt_radius_mm, undecided, boundary_doubt} of the scan report
        and the estimate event, and soft_regions when the chosen model has one."""
        if self.choice is None:
            return None
        soft = describe.soft_regions_of(self.chosen_fit())
        error = self.expected_boundary_error_mm()
        return self.choice.as_dict() | {"drawn_by": self.drawn_by(),
                                        "count_weight": round(self.choice.count_weight, 4),
                                        "expected_boundary_error_mm": None if error is None else round(error, 3),
                                        "unfelt_area_mm2": round(self.unfelt_area_mm2(), 1),
                                        "unfelt_radius_mm": round(self.unfelt_radius_mm(), 1),
                                        "undecided": self.undecided(),
                                        "boundary_doubt": self.boundary_doubt()} | ({"soft_regions": soft} if soft else {})

    def boundary_doubt(self) -> str | None:
        """Why (b) of the stop rule does not hold, the boundary not known to the user's tolerance (None once it
        is, or with no boundary): what a verdict reached at the budget leaves open of what was asked, which the
        count's verdict alone does not say."""
        if self.choice is None or self._boundary_known():
            return None
        error = self.expected_boundary_error_mm()
        tolerance = self.settings.tolerance_mm
        if error is not None and error > tolerance:
            return f"the boundary's expected error is {error:.2f} mm, over the {tolerance:g} mm asked"
        return "a lump's centre, edge or top holds no reading yet: its boundary is not pinned down"

    def expected_boundary_error_mm(self) -> float | None:
        """The reported boundary's expected error in mm: the posterior expected misclassified area over the
        tissue, divided by the boundary's length (None without a lump): ∫ min(P, 1 − P) dA, P the P(lump)
        averaged over the hypotheses, plus the expected area of lumps no reading has felt yet
        (`unfelt_area_mm2`), which no hypothesis draws and every one leaves out. So the figure is what the
        user's tolerance (`tolerance_mm`) speaks of, and a tighter one reads the holes between the readings
        too, where a smaller lump could lie."""
        parts = self._boundary_error_parts()
        return None if parts is None else (parts[0] + parts[1]) / parts[2]

    def _boundary_error_parts(self) -> tuple[float, float, float] | None:
        """(the misclassified area the hypotheses expect, the unfelt lumps' expected area, the reported
        boundary's length), None without a lump."""
        if "error" not in self._cache:
            lumps = self.lumps()
            half = np.asarray(self.size_mm) / 2.0
            length = sum(_perimeter_mm(np.asarray(lump.boundary_mm), half) for lump in lumps)
            if self.choice is None or length <= 0.0:
                self._cache["error"] = None
            else:
                p = self.averaged_p_lump()
                self._cache["error"] = (float(np.minimum(p, 1.0 - p).sum() * self.cell_area_mm2),
                                        self.unfelt_area_mm2(), length)
        return self._cache["error"]

    def unfelt_area_mm2(self) -> float:
        """The expected area of lumps no reading has felt, under the priors' radius range and the settings'
        expected count of lumps (coverage.Readings.unfelt_area_mm2); once an update (the report and (b) ask)."""
        if "unfelt" not in self._cache:
            self._cache["unfelt"] = self.coverage.unfelt_area_mm2(self.settings.expected_lumps, self._unfelt_radii())
        return self._cache["unfelt"]

    def _unfelt_radii(self) -> tuple[float, float]:
        return MIN_RADIUS_MM, MAX_RADIUS_FRACTION * max(self.size_mm)

    def _unfelt_hole(self) -> tuple[float, float] | None:
        """Where one reading takes most off the area unfelt lumps could take (coverage.best_unfelt_spot), when
        that area is what keeps the boundary error above the tolerance, not the drawn boundary's doubt (the
        score's to shrink). next_probe asks it last, once all else holds: asked first, it sent a cone's scan
        to the tissue's edges before a reading on its top, and the fit settled 1.7 mm too wide."""
        parts = self._boundary_error_parts()
        if parts is None:
            return None
        drawn, unfelt, length = parts
        tolerance = self.settings.tolerance_mm
        if drawn / length > tolerance or (drawn + unfelt) / length <= tolerance:
            return None
        return self.coverage.best_unfelt_spot(self.settings.expected_lumps, self._unfelt_radii())

    def undecided(self) -> str | None:
        """Why the verdict does not stand yet (None once it does), in the order `_count_made` asks:
        what an `undetermined` verdict tells the user beyond "the budget ran out". A choice that is
        confident but explains the readings no better than the tissue's texture allows (`_adequate`) is
        the case where more palpations or a lower confidence would not settle it, and so it is named."""
        if self.choice is None:
            return "no stiffness reading yet"
        if not self._enough_spots():
            return f"{self.coverage.spots} readings at distinct spots; a choice rests on at least {MIN_READINGS}"
        chosen, weight = self.choice.chosen, self.choice.weight
        if not self._adequate():
            return (f"{chosen}, the likeliest, misses its readings by {self._chosen_noise_sd() / self.noise_floor:.1f}x "
                    f"their noise floor, more than the tissue's texture accounts for: no hypothesis on offer "
                    f"explains them (a shape, edge profile or background the models do not draw)")
        count = self.choice.count_of(chosen)
        if self.choice.count_weight < self.settings.confidence:
            runner_up = f"; runner-up {self.choice.runner_up}" if self.choice.runner_up else ""
            return (f"{chosen} weighs {weight:.3f} and its count of lumps {self.choice.count_weight:.3f}, under the "
                    f"confidence asked for ({self.settings.confidence:g}){runner_up}")
        if count != self._count_before:
            return f"the count became {chosen} on the newest reading"
        return self._count_doubt()

    def unfelt_radius_mm(self) -> float:
        """What the count claim leaves open: a lump whose disc holds no reading is felt by none (a sharp edge is
        felt only inside it), and the largest such disc has the radius of the farthest spot's distance from
        every reading (on the coverage cells, model.COVERAGE_STEP_MM apart). "k lumps" means none other larger."""
        return float(self.coverage.distance_mm.max())

    def lumps(self) -> list[LumpEstimate]:
        if "lumps" not in self._cache:
            self._cache["lumps"] = self._lumps()
        return self._cache["lumps"]

    def _lumps(self) -> list[LumpEstimate]:
        if self.choice is None:
            return []
        if self.drawn_by() == "free-form":
            return self._map_lumps()
        if self._no_lump_chosen():
            return []
        fit = self.chosen_fit()
        if fit is not None:
            tau = self.supervised_tau_n_per_mm
            parts = self._parts() if tau is None else describe.parts_of(fit, tau, self.size_mm)
            if tau is not None:
                parts = [(j, lump) for j, lump in parts if self._past_tau(lump)]
            return describe.regions_of(fit, parts, self.size_mm)
        return self._map_lumps()

    def drawn_by(self) -> str | None:
        """The hypothesis whose lumps are reported: the chosen one, unless it fails the predictive check
        (`_adequate`) and the free-form map, drawing a region, foresees the readings better. Once no
        hypothesis explains the readings, their posterior weights only say which is least wrong (the
        evidence concentrates on one however poor), so which picture to trust is asked of what each
        foresaw of readings it had not seen: the summed leave-one-out log density of the exact readings
        (the M-open yardstick of Bernardo & Smith, Yao et al. 2018's pseudo-BMA, here a choice: the two
        differ by nats). A C shape drawn as an ellipse foresees its spine no better than the map does; a
        half-plane drawn as an ellipse whose edge profile misses the readings still foresees them better
        than a smooth map that blurs the step, and stays drawn. The verdict is `undetermined` either way
        (`undecided` says why). Where the map draws nothing (no reading surely stiff), the chosen fit's
        lumps are all there is."""
        if self.choice is None:
            return None
        chosen = self.choice.chosen
        if chosen == "free-form" or self._adequate() or not self._map_lumps():
            return chosen
        if "drawn by" not in self._cache:
            fit = self.chosen_fit()
            map_score = float(self.gp.loo_log_density()[self.obs.exact].sum())
            fit_score = -math.inf if fit is None else float(loo_log_density(fit, self.obs).sum())
            self._cache["drawn by"] = "free-form" if map_score > fit_score else chosen
        return self._cache["drawn by"]

    def _map_lumps(self) -> list[LumpEstimate]:
        """The free-form map's regions backed by a surely stiff reading (lumps.find_lumps), once an update."""
        if "map lumps" not in self._cache:
            self._cache["map lumps"] = find_lumps(self.free_form_map(), self._stiff_readings()[0])
        return self._cache["map lumps"]

    def _parts(self) -> list[tuple[int, LumpEstimate]]:
        """Every lump of the chosen parametric fit as reported (describe.parts_of, no τ), once an update: the
        lumps reported and the spots that pin them down (`_unpinned`) both read them."""
        if "parts" not in self._cache:
            self._cache["parts"] = describe.parts_of(self.chosen_fit(), None, self.size_mm)
        return self._cache["parts"]

    def _past_tau(self, lump: LumpEstimate) -> bool:
        """Supervised: a lump is one only where a reading inside it is surely above the learned τ."""
        exact = self.obs.exact
        k = np.exp(self.obs.y[exact])
        sure = surely_above(k, k * self.obs.sd[exact], self.supervised_tau_n_per_mm)
        inside = np.hypot(*(self.obs.xy[exact] - np.asarray(lump.center_mm)).T) <= lump.radius_mm
        return bool(np.any(sure & inside))

    def decided(self) -> bool:
        """The stop rule. Stop when all three hold:

        (a) The count is decided. The posterior mass of the lump count, summed over every hypothesis that
            claims it, each over its own parameters' posterior (lumps that nearly meet may be one region or
            two: evidence.region_counts; hypotheses.Choice.count_weight), is at least `confidence`, on enough readings at
            distinct spots, and the newest reading did not just change it (`_count_made`). That mass is
            over the lumps the hypotheses draw, so it speaks for the count only where a lump would have
            been felt: no lump could hide where nothing was read, no reading hints at a lump no hypothesis
            has, no rival's lump holds no reading, and no one reading could overturn the count
            (`_count_doubt`, stopping); beside lumps found together, where lumps come together, the mass is
            taken times the chance that no lump as small lies unfelt there (`_satellites_in_doubt`).
        (b) The boundary is known to the tolerance: the expected boundary error, the posterior expected
            misclassified area ∫ min(P, 1 − P) dA with P(lump) averaged over the hypotheses by their
            weight, plus the expected area of lumps no reading has felt (their prior: `expected_lumps`,
            `unfelt_area_mm2`), divided by the reported boundary's length, is at most `tolerance_mm`
            (`expected_boundary_error_mm`; no boundary, nothing to bound). A lump's posterior is believed
            once readings lie on it: its centre, its edge where its sd exceeds the tolerance, and its top
            (`_unpinned`).
        (c) The readings are explained (the posterior predictive check, the one guard against every model
            being wrong): the chosen hypothesis explains the readings to their noise or the tissue's texture
            (`_adequate`), predicted the newest within PREDICTED_SIGMA sd, and the newest reading (and the
            one before) moved what is reported no further than its sds and the tolerance allowed
            (`_settled`). When no hypothesis passes, the scan goes on, and a budget spent ends
            `undetermined` with the reason (`undecided`).

        The shape that draws the count (a circle or an ellipse) need not be decided: its doubt is in P, so in
        (b). Looser tolerance or confidence stops sooner; tighter reads on.
        """
        return self._holds_now() and self._count_doubt(stopping=True) is None

    def _holds_now(self, unfelt: bool = True) -> bool:
        """The stop rule but for the count checks only a stop asks (`_count_doubt(stopping=True)`: an
        unexplored spot, which next_probe fills before it asks this; a hole beside lumps found together and a
        rival's decisive spot, which weigh the whole grid, so they are looked for once all else holds).
        Without `unfelt`, (b) leaves out the unfelt lumps' area: what the holes between the readings are
        read for, last (`_unfelt_hole`)."""
        return self._count_made() and self._count_doubt() is None and self._boundary_known(unfelt) \
            and self._readings_explained()

    def _boundary_known(self, unfelt: bool = True) -> bool:
        """(b) of the stop rule (without `unfelt`: but for the unfelt lumps' area)."""
        if self._unpinned() is not None:
            return False
        parts = self._boundary_error_parts()
        return parts is None or (parts[0] + (parts[1] if unfelt else 0.0)) / parts[2] <= self.settings.tolerance_mm

    def _readings_explained(self) -> bool:
        """(c) of the stop rule."""
        return self._adequate() and abs(self.surprise_sd) <= PREDICTED_SIGMA and self._settled()

    def _settled(self) -> bool:
        """The newest reading moved no reported centre coordinate or radius (axis) by more than a posterior
        that was right could let it. In a Gaussian posterior a reading z sd from its prediction moves any
        quantity by at most |z| of that quantity's sd before it (their correlation is at most 1), so a
        larger move says the sds before it were narrower than the readings bear out: a smooth lump read
        at a few spots on its edge, whose profile the family only approximates, moved its centre by
        3 sd on a reading it had predicted within 1 sd, and stopped there 0.6-0.8 mm off with a reported
        sd of 0.2 mm. Nor by more than the user's tolerance: an answer one reading just moved further than
        that is not yet known to it, whatever its sd now says (a broad Gaussian rise had its radius go
        8.5 -> 11.3 mm on its 13th reading, within 1 sd before, and stopped there at 0.30 mm sd, 0.71 mm
        off). A model that just changed (another count or shape) has not settled either. Nor has one the
        reading before moved further than that: a posterior one reading just showed too narrow is believed
        again only once the next reading bears it out and the one after that does too (cone-lump, seed 0:
        a centre moved 4.5 sd on its 14th reading, 1 sd on its 15th, and the scan stopped there 1.2 mm off
        at a stated 0.12 mm; a reading later its tails ended and it was right)."""
        fit = self.chosen_fit()
        if fit is None or fit.family.k == 0:
            return True  # the free-form map or `none`: no centre or radius reported from parameters
        return self._settled_before and self._chosen_moved_within_sds()

    def _chosen_moved_within_sds(self) -> bool:
        """`_moved_within_sds` of the chosen fit, once an update: the stop rule asks it, and the next reading
        asks it again of the same two fits (whether the reading before it settled the estimate)."""
        if "moved" not in self._cache:
            self._cache["moved"] = self._moved_within_sds(self.chosen_fit())
        return self._cache["moved"]

    def _moved_within_sds(self, fit: Fit | None) -> bool:
        """The newest reading moved no reported centre coordinate or radius of `fit` (the chosen fit after
        it) beyond what the sds before it allowed, nor beyond the tolerance, and the model is the one before
        it (`_settled`). True without a lump model: nothing is reported from parameters."""
        if fit is None or fit.family.k == 0:
            return True
        before = self._fit_before
        if before is None or before.family.k != fit.family.k:
            return False
        if before.family != fit.family:  # another shape of the same count: its lumps moved within the tolerance
            return _moved_within(_discs(before), _discs(fit), self.settings.tolerance_mm)
        rows = describe.quantities(before, self.size_mm)
        moved = np.abs(rows @ (fit.theta - before.theta))
        sd_before = np.sqrt(np.maximum(shapes.row_variances(rows, before.cov), 0.0))
        return bool(np.all(moved <= max(1.0, abs(self.surprise_sd)) * sd_before)
                    and np.all(moved <= self.settings.tolerance_mm))

    def _unexplored(self) -> tuple[float, float] | None:
        """The spot farthest from every reading, when it is farther than `coverage_mm` (`none_reach_mm`,
        `none_coverage_mm` or wider on a larger tissue (design.none_reach), while the choice is `none`: "no
        lump" claims the whole tissue, and a sharp-edged lump is felt only within its radius): a lump there
        whose felt footprint is narrower could not have shown yet.

        `none` also waits for a palpation near the tissue's centre, where a user places what they came to
        examine: the covering lattice of a square has its widest hole there (60 x 60 mm: 11 mm from
        every point), and a 5 mm lump 2 mm deep centred on the tissue was `none` at 17 palpations while
        a raster scan found it. One palpation more on plain tissue (18); no scan with a lump in the
        tables changed its count."""
        reach = self.settings.coverage_mm
        if self.choice is None or not self._no_lump_chosen():
            return self.coverage.farthest_beyond(reach)
        unexplored = self.coverage.farthest_beyond(self._none_reach_mm())
        if unexplored is None and self._centre_unprobed():
            return 0.0, 0.0
        return unexplored

    def _none_reach_mm(self) -> float:
        """How far from every reading `none` rules lumps out: the none reach, at most `coverage_mm`."""
        return min(self.settings.coverage_mm, self.none_reach_mm)

    def _centre_unprobed(self) -> bool:
        reach = CENTRE_REACH * self.none_reach_mm
        return bool(self.probed) and min(math.hypot(x, y) for x, y in self.probed) > reach

    def _satellite_hole(self) -> np.ndarray | None:
        """Once the chosen model has CLUSTER_LUMPS lumps or more: the middle of the widest hole between palpations
        beside them wider than `satellite_reach` of a lump's radius (coverage.satellite_holes), or None. A
        single lump is left to `coverage_mm`: a closer look around every lump would cost most scans 5-10
        palpations (the median is a single-lump scan)."""
        return self._satellite_holes()[0]

    def _satellite_holes(self) -> tuple[np.ndarray | None, float]:
        """(the satellite hole or None, the share of the cells beside the lumps in a hole), once an update."""
        if "satellite" not in self._cache:
            fit, reach = self.chosen_fit(), self.settings.satellite_reach
            self._cache["satellite"] = (None, 0.0) if fit is None or fit.family.k < coverage.CLUSTER_LUMPS or reach <= 0 \
                else coverage.satellite_holes(_discs(fit), self.coverage, reach, self.settings.min_spacing_mm)
        return self._cache["satellite"]

    def _satellites_in_doubt(self) -> bool:
        """(a) of the stop rule beside lumps found together: the count's posterior mass, times the chance that no
        lump as small as the smallest found lies unfelt beside them, is under `confidence`. Lumps found together
        come together, so the unfelt lumps' prior (`expected_lumps`) is placed beside each of the k found ones
        rather than anywhere on the tissue: the expected number unfelt is λ = k · expected_lumps · the share of
        the cells beside them in a hole (coverage.satellite_holes), none of them with probability e^(−λ).
        Before, any such hole kept the scan reading: two-lumps read on from its 26th palpation to its 35th,
        across most of the tissue, at any tolerance or confidence."""
        hole, share = self._satellite_holes()
        if hole is None:
            return False
        unfelt = self.chosen_fit().family.k * self.settings.expected_lumps * share
        return self.choice.count_weight * math.exp(-unfelt) < self.settings.confidence

    def _covering_spot(self, unexplored: tuple[float, float]) -> tuple[float, float]:
        """The covering lattice's point nearest an unexplored spot (its own cell's: within the `none` reach of
        it): the lattice covers the tissue with the fewest readings. The spot itself if a probe was made at
        that point, or if the spot is the tissue's centre and the point farther from it than CENTRE_REACH."""
        near = self.lattice[np.argmin(np.hypot(*(self.lattice - np.asarray(unexplored)).T))]
        if unexplored == (0.0, 0.0) and math.hypot(*near) > CENTRE_REACH * self.none_reach_mm:
            return unexplored
        if min(math.dist(near, probe) for probe in self.probed) < self.settings.min_spacing_mm:
            return unexplored
        return float(near[0]), float(near[1])

    def _hidden_lump(self) -> np.ndarray | None:
        """Where readings above the chosen model hint together at a lump no hypothesis has (coverage.py), or None."""
        if "hidden" not in self._cache:
            fit = self.chosen_fit()
            self._cache["hidden"] = None if fit is None else coverage.hidden_lump_spot(
                self._excess_over(fit), self.obs.xy[self.obs.exact], self.coverage, self.none_reach_mm)
        return self._cache["hidden"]

    def _surprise_of_last(self) -> float:
        """How many sd the newest reading lies from the chosen fit's prediction there, made before it (its
        parameters' checked variance, the reading's own and the fit's σ_w): a fit whose sds are honest
        predicts its next reading; one that does not is not pinned, however narrow its Laplace sd."""
        fit = None if self.choice is None else self.chosen_fit()
        if fit is None or not self.obs.exact[-1]:
            return 0.0
        mean, var, _ = acquisition.moments(fit, self.obs.xy[-1:])
        noise = self.obs.sd[-1] ** 2 + max(fit.noise_sd, self.noise_floor) ** 2
        return float((self.obs.y[-1] - mean[0]) / math.sqrt(var[0] + noise))

    def _excess_over(self, fit: Fit) -> np.ndarray:
        """Each exact reading's excess over the fit, in units of its own noise and the fit's σ_w (never below the floor)."""
        exact = self.obs.exact
        f, _ = shapes.evaluate(fit.family, fit.theta, self.obs.xy[exact], jacobian=False)
        return (self.obs.y[exact] - f) / np.sqrt(self.obs.sd[exact] ** 2 + max(fit.noise_sd, self.noise_floor) ** 2)

    def _rivals_unread_lump(self) -> np.ndarray | None:
        """Where a rival hypothesis (weight at least MIN_WEIGHT) has a lump that overlaps no chosen lump and
        holds no palpation: the choice rests on the evidence's Occam factor alone there, and one reading
        over that lump's centre tells the two apart. (Two lumps, one felt only on a flank: one long ellipse
        won at 0.97 over the right two circles, whose second centre no reading came within 8 mm of.)"""
        if "rival" not in self._cache:
            self._cache["rival"] = self._find_rivals_unread_lump()
        return self._cache["rival"]

    def _decisive_spot(self) -> np.ndarray | None:
        if "decisive" not in self._cache:
            self._cache["decisive"] = self._find_decisive_spot()
        return self._cache["decisive"]

    def _find_decisive_spot(self) -> np.ndarray | None:
        """The unprobed spot where a rival (weight at least DECISIVE_WEIGHT) that explains the readings to
        their precision and the chosen fit predict so differently that one reading could overturn the odds
        between them (½z² above their log odds, z the difference over both predictions' sd and the noise),
        or None. Fit to the same readings, the two differ only where none was taken, and only the Occam
        factor parts them: two touching lumps read around but not between were one ellipse at 0.9999, over
        two circles that fitted as well and predicted a third of its stiffness at the waist."""
        chosen = self.choice.chosen
        if chosen == "free-form" or chosen not in self.hypotheses.fits:
            return None
        cells = self._candidates()
        cells = cells[~self.blocked[cells]]
        if not len(cells):
            return None
        mean, var = self._moments(self.hypotheses.laplace(chosen), cells)
        noise, best, spot = self._noise_var(), 0.0, None
        adequate_sd = max(ADEQUATE_NOISE * self.noise_floor, self._texture_sd())
        for name, weight in self.choice.weights.items():
            fit = self.hypotheses.laplace(name) if name != chosen else None
            if fit is None or weight < DECISIVE_WEIGHT or fit.noise_sd > adequate_sd:
                continue
            if lumps_claimed(name) == lumps_claimed(chosen):
                continue  # another shape of as many lumps: its doubt is in P, what the tolerance bounds
            # (as many drawn, not as many regions: two overlapping circles beside one ellipse over a lump and a
            # neighbour's edge are one region now, two lumps once a reading where they disagree parts them)
            rival_mean, rival_var = self._moments(fit, cells)
            odds = math.log(self.choice.weights[chosen] / weight)  # both among every rival (hypotheses.Choice)
            overturn = 0.5 * (mean - rival_mean) ** 2 / (var + rival_var + noise) - odds
            i = int(np.argmax(overturn))
            if overturn[i] > best:
                best, spot = float(overturn[i]), self.grid_xy[cells[i]]
        return spot

    def _find_rivals_unread_lump(self) -> np.ndarray | None:
        if self.choice is None or self.choice.chosen == "free-form" or not self.probed:
            return None
        chosen = _discs(self.chosen_fit())
        probes = None  # made only when a rival's lump asks (it is a copy of every palpation so far)
        half = np.asarray(self.size_mm) / 2.0
        for name, weight in sorted(self.choice.weights.items(), key=lambda kv: -kv[1]):
            if name == self.choice.chosen or weight < MIN_WEIGHT or name not in self.hypotheses.fits:
                continue
            for centre, radius in _discs(self.hypotheses.fits[name]):
                if any(math.dist(centre, c) < r + radius for c, r in chosen):
                    continue  # it overlaps a chosen lump: another shape of that lump, pinned down by the rules below
                spot = np.clip(centre, -half, half)
                if math.dist(spot, centre) >= radius:
                    continue  # off the tissue
                probes = np.asarray(self.probed) if probes is None else probes
                if np.min(np.hypot(*(probes - spot).T)) >= max(radius, self.settings.min_spacing_mm):
                    return spot
        return None

    def _unpinned(self) -> np.ndarray | None:
        """Where a lump of the chosen parametric model still needs a reading to be pinned down, or None
        (once an update: the stop rule, the next probe and its score all ask)."""
        if "unpinned" not in self._cache:
            self._cache["unpinned"] = self._find_unpinned()
        return self._cache["unpinned"]

    def _find_unpinned(self) -> np.ndarray | None:
        fit = self.chosen_fit()
        if fit is None or fit.family.k == 0:
            return None
        readings = self.obs.xy[self.obs.kind >= 0]  # exact readings and lower bounds
        spacing = self.settings.min_spacing_mm
        centre = coverage.unconfirmed_centre(fit, readings, spacing)
        if centre is not None:
            return centre
        lumps = [lump for _, lump in self._parts()]  # every lump, in the fit's order (no τ filter)
        unsure = np.array([_sds(lump) > self.settings.tolerance_mm for lump in lumps])
        edge = coverage.uncovered_edge(fit, readings, self.size_mm, spacing, unsure)
        return edge if edge is not None else coverage.unread_top(fit, readings, spacing)

    def _unfelt(self) -> np.ndarray | None:
        """The centre of a lump that a hypothesis the evidence prefers needs and no reading felt
        (hypotheses.py), unless a probe was already made there."""
        centre = self.hypotheses.unfelt_centre
        if centre is None or not self.probed:
            return None
        probes = np.asarray(self.probed)
        near = np.hypot(probes[:, 0] - centre[0], probes[:, 1] - centre[1]) < self.settings.min_spacing_mm
        return None if near.any() else centre

    def verdict(self) -> str:
        """`lumps`, `none`, or `undetermined` when the evidence has not decided between them: the verdict
        claims a count of lumps, so it stands once the count is decided, whichever shape the hypotheses
        that agree on it draw (a 3 x 3 raster over one lump weighed circles:1 at 0.66 and ellipse:1 at 0.34:
        one lump, surely, its outline less so)."""
        if not self._count_made() or self._count_doubt() is not None:
            return "undetermined"
        return "none" if self._no_lump_chosen() else "lumps"

    def _count_doubt(self, stopping: bool = False) -> str | None:
        """Why readings not yet taken could still change the count, however its posterior weighs it now (the
        count half of the stop rule, (a)), or None. Asked of every verdict too, so that a scan whose points
        were fixed beforehand (raster, random) or whose budget ran out claims no count the active scan would
        have read on for. `stopping` (the stop rule) adds what the active scan still reads before it claims the
        count: a spot farther from every reading than a lump's felt footprint, a hole beside lumps found
        together that a lump could hide in, and a rival of another count that one reading could make the
        likelier. A verdict leaves those to the report's unfelt_radius_mm (no lump larger hides between the
        readings) and count_weight, but for "no lump": that claims the whole tissue, so a verdict of `none` too
        waits until no spot is farther from every reading than the `none` reach (a sliding scan of very soft
        tissue whose paths kept losing contact said "no lump" with a 41 mm lump left possible between its
        readings)."""
        if not stopping and self._no_lump_chosen() and self.coverage.farthest_beyond(self._none_reach_mm()) is not None:
            return (f"no lump among the readings, but a spot lies {self.unfelt_radius_mm():.1f} mm from every reading, "
                    f"farther than the {self._none_reach_mm():g} mm within which \"no lump\" rules lumps out")
        if self._hidden_lump() is not None:
            return "readings above the chosen model hint together at a lump no hypothesis has"
        if self._unfelt() is not None or self._rivals_unread_lump() is not None:
            return "a lump that a rival hypothesis draws holds no reading yet"
        if stopping and self._unexplored() is not None:
            return "a spot of the tissue is farther from every reading than a lump's felt footprint"
        if stopping and self._satellites_in_doubt():
            return "a hole beside the lumps found together could hide another"
        if stopping and self._decisive_spot() is not None:
            return "one reading could make a rival count the likelier"
        return None

    def _count_made(self) -> bool:
        """The count's posterior mass (every hypothesis that claims it) is at least `confidence` (`_confident`),
        the chosen fit is adequate, and the newest reading did not just change the count: four-lumps ended its
        budget on `circles:5` at weight 1.000 one reading after `circles:4` at 1.000, one lump false; weights
        that swing that far on one reading are the fits' own uncertainty, not the evidence's."""
        choice = self.choice
        if not self._confident():
            return False
        return self._adequate() and choice.count_of(choice.chosen) == self._count_before

    def _no_lump_chosen(self) -> bool:
        """The choice is a model without lumps: `none`, or none on a background with a soft region."""
        fit = self.chosen_fit()
        return fit is not None and fit.family.k == 0

    def _confident(self) -> bool:
        """Enough readings at distinct spots, and the chosen count weighs at least `confidence`."""
        return (self.choice is not None and self.choice.count_weight >= self.settings.confidence
                and self._enough_spots())

    def _enough_spots(self) -> bool:
        """MIN_READINGS readings at distinct spots (at least the probe spacing apart): the same spot
        read again and again is not evidence about the rest of the tissue."""
        return self.coverage.spots >= MIN_READINGS

    def _adequate(self) -> bool:
        """A parametric fit explains the readings to their precision, or leaves only the tissue's texture.
        The free-form map is the model of last resort: what it leaves is the tissue's own texture below its
        length scale (a measured map's GP needs 2-3x the readings' noise), which its sds carry, and nothing
        more flexible could explain it. Held to the same bar, the measured half-stiff map ended
        `undetermined` at the budget on seeds 3-6 with its boundary at IoU 0.99; exempt, they decide at
        34-40, and no other of 147 table runs changes.

        Texture: where neighbouring readings differ from each other as much as the fit's σ_w says they
        scatter, and every error alike (likelihood.texture_sd), what the fit leaves is the tissue's own
        spot-to-spot variation, which no model of lumps explains. A stiff half of an 80 x 40 mm map with
        5 % texture was fitted at σ_w 3.7-4x the floor by every hypothesis and ended `undetermined` at the
        budget, its boundary at IoU 0.97; `none` over four lumps left 1.3-5.3x what texture accounts for
        wherever it was confident (docs/learner.md, rule 2)."""
        if self.choice.chosen == "free-form":
            return True
        sigma = self._chosen_noise_sd()
        return sigma <= ADEQUATE_NOISE * self.noise_floor or sigma <= self._texture_sd()

    def _texture_sd(self) -> float:
        """The largest σ_w the tissue's texture accounts for, from the chosen fit's errors
        (likelihood.texture_sd, on at least MIN_READINGS neighbour pairs), and never more than a lump of the
        smallest contrast asked for (`min_contrast`) stands out by SUPPORT_SIGMA: texture larger than that would
        hide such a lump at every reading, so it explains nothing the user asked about. (Real readings of a
        phantom with a block 2.5x stiffer across two thirds of it, 13 of them 10 mm apart, had neighbours
        differing by 60x the floor; `none` missed them by 53x and was read as texture, `none` at weight 0.999.)"""
        if "texture" not in self._cache:
            fit, exact = self.chosen_fit(), self.obs.exact
            texture = 0.0
            if fit is not None:
                f, _ = shapes.evaluate(fit.family, fit.theta, self.obs.xy[exact], jacobian=False)
                texture = texture_sd(self.obs.xy[exact], self.obs.y[exact] - f, self.obs.sd[exact], MIN_READINGS)
            self._cache["texture"] = min(texture, math.log1p(self.min_contrast) / SUPPORT_SIGMA)
        return self._cache["texture"]

    def _chosen_noise_sd(self) -> float:
        fit = self.chosen_fit()
        return fit.noise_sd if fit is not None else math.sqrt(self.gp.hyper.white_var)

    # -- where next -------------------------------------------------------------------------------
    def next_probe(self, max_palpations: int | None = None) -> tuple[float, float] | None:
        """Where to palpate next, or None once the stop rule holds (or the budget is spent)."""
        budget = self.settings.max_palpations if max_palpations is None else max_palpations
        if self.points >= budget:
            return None
        if self.points < len(self.design):
            return self.design[self.points]
        if self.decided():
            return None
        chosen = self._confident()  # adequate or not: what it leaves unexplained may lie where nothing was read
        unexplored = self._unexplored() if chosen else None
        if unexplored is not None:  # all else is decided: look where nothing was read yet
            return self._covering_spot(unexplored)
        hidden = self._hidden_lump() if chosen else None
        if hidden is not None:  # readings hint at a lump no hypothesis has yet: look where it would be
            return float(hidden[0]), float(hidden[1])
        rival = self._rivals_unread_lump() if chosen else None
        if rival is not None:  # a rival's lump where nothing was read: one reading over it says if it is there
            return float(rival[0]), float(rival[1])
        stands = chosen and self._holds_now(unfelt=False)
        # lumps found together and a hole beside them a lump could hide in: asked once all else holds, or once the
        # chosen fit misses its readings (an unmodelled lump beside them is the likeliest cause: touching-lumps'
        # third lump, whose tail the two found misfit, was never read while the probes circled the two)
        satellite = self._satellite_hole() if (stands and self._satellites_in_doubt()) or (chosen and not self._adequate()) \
            else None
        if satellite is not None:
            return float(satellite[0]), float(satellite[1])
        decisive = self._decisive_spot() if stands else None
        if decisive is not None:  # all else holds: one reading where a rival as good disagrees most
            return float(decisive[0]), float(decisive[1])
        hole = self._unfelt_hole() if stands else None
        if hole is not None:  # all else holds but for lumps a hole between the readings could hide
            return hole
        cells, cells_xy = self._probe_cells
        score = self._score(cells, cells_xy)
        here = self.probed[-1] if self.probed else None
        best = acquisition.best_candidate(score, cells_xy, self.blocked[cells], here, self.travel_mm_per_palpation)
        return best if best is not None else self._farthest_from_probes()

    @functools.cached_property
    def _probe_cells(self) -> tuple[np.ndarray, np.ndarray]:
        """The cells a probe is chosen among (`_candidates`) and where they are: the grid is fixed, so once."""
        cells = self._candidates()
        return cells, self.grid_xy[cells]

    def _candidates(self, stride_mm: float = CANDIDATE_STRIDE_MM, every: tuple[int, int] = (1, 1)) -> np.ndarray:
        """The grid cells about `stride_mm` apart along x and along y (row-major); with `every`, every so many of
        them along each."""
        step_x, step_y = self._grid_steps(stride_mm)
        rows = np.arange(0, len(self.ys), step_y * every[1])
        cols = np.arange(0, len(self.xs), step_x * every[0])
        return (rows[:, None] * len(self.xs) + cols[None, :]).ravel()

    def _grid_steps(self, stride_mm: float) -> tuple[int, int]:
        """Grid cells per step along x and along y of a lattice `stride_mm` apart (never finer than the grid). The
        grid has as many points along each side, so its cells are as long as the tissue's sides are: one step for
        both, the x one, made the lattice of a tissue taller than wide coarse along y (3 x 140 mm: 4 x 4
        candidates, 47 mm apart along it; 20 x 100 mm: rows 5 mm apart) and of a wider one fine across."""
        return (max(1, int(stride_mm / (self.xs[1] - self.xs[0]))), max(1, int(stride_mm / (self.ys[1] - self.ys[0]))))

    def _noise_var(self) -> float:
        """A reading's noise variance as the scores weigh it: the readings' median one and the chosen fit's σ_w
        (once an update)."""
        if "noise var" not in self._cache:
            fit = self.chosen_fit()
            extra = fit.noise_sd if fit is not None else self.noise_floor
            self._cache["noise var"] = float(np.median(self.obs.sd**2)) + extra**2 if self.obs.n else extra**2
        return self._cache["noise var"]

    def _score(self, cells: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """What a reading at each cell (at xy) is worth (see acquisition.py for the why of each)."""
        if self.choice is None:
            return self.gp.var[cells]
        if self.choice.weight < self.settings.confidence:
            score = acquisition.disagreement(self._predictions(cells), self._noise_var())
            if score.max(initial=0.0) > NEGLIGIBLE_NATS:
                return score
            # the rivals predict alike everywhere: nested ones that coincide (an ellipse with equal axes is
            # the circle) are told apart only by pinning down what the larger one adds, around the lump, so
            # probe as for the chosen one; scored 0 everywhere, the probes went to the farthest spots instead
            # and spent the budget there (a low-contrast lump: 32 readings of plain tissue, weight stuck at 0.66)
        fit = self.chosen_fit()
        # the chosen parametric fit misses something: where the free-form map disagrees with it. (The free-form
        # map itself has nothing more flexible to be compared with: scored against itself every cell was 0 and
        # the probes went to the tissue's corners, its boundary left as unsure as it was.)
        if fit is not None and not self._adequate():
            return acquisition.misfit(self._moments(fit, cells), (self.gp.mean[cells], self.gp.var[cells]),
                                      self._noise_var())
        unfelt = self._unfelt()
        if unfelt is not None:  # over the lump a preferred hypothesis needs and no reading has felt
            return 1.0 / (1.0 + np.hypot(xy[:, 0] - unfelt[0], xy[:, 1] - unfelt[1]))
        if fit is not None and fit.family.k:
            target = self._unpinned()
            if target is not None:  # nearest the spot that pins the lump down
                return 1.0 / (1.0 + np.hypot(xy[:, 0] - target[0], xy[:, 1] - target[1]))
            score = np.zeros(len(xy))
            near = coverage.near_edges(fit, xy, self.settings.min_spacing_mm)  # where a centre or radius is read
            near_xy = xy[near]
            # where to probe by the Laplace covariance: its widest directions are where the posterior
            # is still unexplored (checked, they are narrow only along the line that was looked at)
            laplace = self.hypotheses.laplace(self.choice.chosen)
            gain = acquisition.boundary_gain(laplace, near_xy, self._noise_var(), self.size_mm)
            score[near] = gain * self._readable(laplace, near_xy)
            return score
        gain = self._free_form_area_gain(cells)
        if gain is not None:
            return gain
        tau = np.log(self.free_form_map().tau).ravel()[cells]
        return acquisition.straddle(self.gp.mean[cells], self.gp.std()[cells], tau, self.settings.confidence)

    def _free_form_area_gain(self, cells: np.ndarray) -> np.ndarray | None:
        """What a reading at each cell is expected to take off the free-form map's misclassified area
        ∫ min(P, 1 − P) dA (acquisition.misclassified_area_gain), the loss (b) of the stop rule reads; None
        where no cell is in doubt (P within DOUBT of 0 or 1 everywhere). Scored on the lattice AREA_STEP_MM
        apart, cells and candidates both; the cells between score 0. It replaces the variance a reading took off
        the drawn boundary's position: that left the doubt away from the boundary unread, and it was most of
        the loss (the measured half-stiff map: 197 of 219 mm² more than 4 mm from every reading, stated 3.6 mm
        against a true 0.38 mm at 40 palpations; 1.4 against 0.21 now)."""
        lattice, area = self._area_lattice
        var = self.gp.var[lattice]
        z = np.abs(self.gp.mean[lattice] - np.log(self.free_form_map().tau).ravel()[lattice]) / np.sqrt(
            np.maximum(var, 1e-300))
        doubt = ndtr(-z) > DOUBT
        if not doubt.any():
            return None
        open_ = np.flatnonzero(~self.blocked[lattice])
        candidates = lattice[open_]
        noise = float(np.median(self.obs.sd**2)) + self.gp.hyper.white_var
        cov = self.gp.lattice_covariance(lattice, open_, np.flatnonzero(doubt))
        gain = acquisition.misclassified_area_gain(cov, self.gp.var[candidates], noise, z[doubt], var[doubt], area,
                                                   overwrite_cov=True)
        score = np.zeros(len(cells))
        score[np.searchsorted(cells, candidates)] = gain  # the lattice is one of the candidate cells' (both row-major)
        return score

    @functools.cached_property
    def _area_lattice(self) -> tuple[np.ndarray, float]:
        """The cells about AREA_STEP_MM apart the free-form map's misclassified area is scored on (a sub-lattice of
        the candidate cells), and each one's area; coarser on a tissue where that would be more than AREA_CELLS
        cells: the score weighs every candidate against every cell in doubt, so its time and memory go as the
        cells' square (a 200 mm tissue at 2 mm: 14 641 cells, one score 42 s and 12 GB)."""
        (step_x, step_y), (area_x, area_y) = self._grid_steps(CANDIDATE_STRIDE_MM), self._grid_steps(AREA_STEP_MM)
        every = self._within(CANDIDATE_STRIDE_MM, (max(1, area_x // step_x), max(1, area_y // step_y)), AREA_CELLS)
        dx, dy = self.xs[1] - self.xs[0], self.ys[1] - self.ys[0]
        return self._candidates(every=every), float(step_x * every[0] * dx * step_y * every[1] * dy)

    def _within(self, stride_mm: float, every: tuple[int, int], cells: int) -> tuple[int, int]:
        """`every`, or coarser until the lattice `_candidates(stride_mm, every)` has at most `cells` cells: a step
        more at a time along the axis whose cells are closer; as close, along the one with more of them, or both
        (so a tissue turned a quarter has its lattice turned, and a square one a square lattice)."""
        step_x, step_y = self._grid_steps(stride_mm)
        along_x, along_y = every
        dx, dy = self.xs[1] - self.xs[0], self.ys[1] - self.ys[0]
        while (count_x := math.ceil(len(self.xs) / (step_x * along_x))) * \
                (count_y := math.ceil(len(self.ys) / (step_y * along_y))) > cells:
            apart_x, apart_y = step_x * along_x * dx, step_y * along_y * dy
            if math.isclose(apart_x, apart_y, rel_tol=1e-9):
                along_x, along_y = along_x + (count_x >= count_y), along_y + (count_y >= count_x)
            elif apart_x < apart_y:
                along_x += 1
            else:
                along_y += 1
        return along_x, along_y

    def _readable(self, fit: Fit, xy: np.ndarray) -> np.ndarray | float:
        """The chance a reading at each spot is a stiffness, not 'too stiff' again: the fit's predicted log
        stiffness below the force limit's bound (the median of the 'too stiff' bounds so far). A bound deep
        inside a lump says nothing about where its edge is: a lump read 'too stiff' inside drew probe after
        probe to its interior, each a bound again, while its radius stayed unread."""
        bounds = self.obs.y[self.obs.kind == AT_LEAST]
        if not len(bounds):
            return 1.0
        mean, var, _ = acquisition.moments(fit, xy)
        z = (float(np.median(bounds)) - mean) / np.sqrt(var + self._noise_var())
        return ndtr(z)

    def _moments(self, fit: Fit | None, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A hypothesis's predictive mean and variance at the cells (the free-form map's without a fit)."""
        if fit is None:
            return self.gp.mean[cells], self.gp.var[cells]
        mean, var, _ = acquisition.moments(fit, self.grid_xy[cells])
        return mean, var

    def _predictions(self, cells: np.ndarray) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """The leading rivals' predictions, each from its Laplace covariance (hypotheses.laplace)."""
        rivals = sorted(self.choice.weights.items(), key=lambda kv: -kv[1])[:MAX_RIVALS]
        return [(weight, *self._moments(self.hypotheses.laplace(name), cells)) for name, weight in rivals
                if weight >= MIN_WEIGHT]

    def _farthest_from_probes(self) -> tuple[float, float] | None:
        free = ~self.blocked
        if not free.any():
            return None
        probes = np.asarray(self.probed)
        cells = self.grid_xy[free]
        distance = np.min(np.hypot(cells[:, None, 0] - probes[None, :, 0], cells[:, None, 1] - probes[None, :, 1]), 1)
        best = cells[int(np.argmax(distance))]
        return float(best[0]), float(best[1])


def _discs(fit: Fit | None) -> list[tuple[np.ndarray, float]]:
    """Each lump of a parametric fit as (centre, radius: the equal-area one of an ellipse)."""
    return [] if fit is None else [(p[:2], math.exp(p[2])) for p in coverage.lump_params(fit)]


def _sds(lump: LumpEstimate) -> float:
    """The largest sd of what is reported: centre, radius, axes, and for a free-form region or a lump cut by the
    tissue's edge its boundary (such a lump's axes are the whole shape's, mostly off the tissue: none pinned)."""
    axes = () if lump.cut_by_edge else (lump.axes_sd_mm or ())
    sds = [lump.center_sd_mm, lump.radius_sd_mm, *axes]
    if lump.boundary_sd_mm is not None:
        sds.append(lump.boundary_sd_mm)
    return max(sds)


def _perimeter_mm(polygon: np.ndarray, half: np.ndarray | None = None) -> float:
    """The length of a closed polygon [[x, y], ...] (the last vertex joined to the first), less its stretches
    along the tissue's edge (given its half size): a lump cut by the edge is reported by its part on the
    tissue, whose outline runs along the edge where no boundary between lump and tissue is (counted, they
    made a cut lump's expected boundary error look 2-3x smaller than it was)."""
    if len(polygon) < 2:
        return 0.0
    following = np.roll(polygon, -1, axis=0)
    lengths = np.hypot(*(following - polygon).T)
    if half is not None:  # a side whose two ends lie on the same side of the tissue's edge runs along it
        on = np.abs(np.abs(polygon) - half) < 1e-6
        on_edge = (on & np.roll(on, -1, axis=0) & ((polygon > 0.0) == (following > 0.0))).any(axis=1)
        lengths = lengths[~on_edge]
    return float(lengths.sum())


def _moved_within(before: list, after: list, tolerance_mm: float) -> bool:
    """Each lump of `after` lies within the tolerance of one of `before`, centre and radius (lists of
    (centre, radius), as _discs gives them; the same count)."""
    return all(min(max(math.dist(c, c0), abs(r - r0)) for c0, r0 in before) <= tolerance_mm for c, r in after)
