"""The hypotheses about a scene and their posterior weights: none, k circles, k ellipses, free-form.

Each count from `none` up may also hold a soft region (none+soft:1, circles:K+soft:1, shapes.py),
tried while the likeliest count misses readings below it more than any above (`_soft_wanted`):
tissue softer in one place is no lump, and lumps could only mimic it by standing for the tissue
around it (a soft disc was read as a stiff half-disc beside it: undetermined at the budget, 38
times the noise floor).

Each update refits the parametric hypotheses from several starts: where it was
last time (warm), from the one with one lump fewer plus a lump at the reading
it explains worst, from the one with one lump more without each of its lumps,
from the free-form map's regions, and (for ellipses) from
the circles stretched along each region's long axis. Counts grow while the
evidence still rises (one beyond the best is always tried). The free-form GP
level set is a candidate when its map holds a region backed by a stiff reading.
Weights are the evidences normalised over the supported candidates (equal
prior odds): the simplest adequate hypothesis wins unless the data ask for more.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from palpd.learner import evidence, posterior, shapes
from palpd.learner.evidence import Fit, Priors
from palpd.learner.observations import EXACT, Observations

MAX_LUMPS = 6
RESTART_EVERY = 4
RESIZE = (0.6, 1.6)
LIGHT_ITERATIONS = 12  # a refit spread over many readings takes at most this many steps (it starts warm)
CONTENDER_WEIGHT = 1e-3  # a hypothesis this likely gets fresh starts as soon as a reading surprises it
START_SHARPNESS = 6.0
# σ_w this far over the floor: the profile may miss what the readings show (an estimate from n readings has a
# relative sd of about 1/√(2n), 0.16 at 20: half again the floor is 3 of those)
PROFILE_MISFIT = 1.5
STRAINED_TAIL = 0.05  # a lump's λ this near the top of its range: tails as thin as never-ending ones can be
COMPACT_START = -0.5  # λ of a start whose tails end (at ρ² = 4 with s = 2, as a cone of the same half-height)
ELLIPSE_START_STRETCH = 0.4  # log axis ratio an ellipse start is given along a region's long axis
NEGLIGIBLE_NATS = 7.0  # a hypothesis whose Laplace evidence (an upper bound of its checked one) is this far
#                       below the best checked one weighs under 1e-3 (< CONTENDER_WEIGHT): not worth checking
RECHECK_GROWTH = 4 / 3  # a volume check holds for its mode (within 1 sd) until the readings grow this much
COUNT_SHARE = 1e-3  # a hypothesis with less of the choice than this cannot move the count's mass past 0.999


@dataclass(frozen=True)
class Region:
    """A region of the free-form map: a start for parametric fits."""
    center_mm: tuple[float, float]
    radius_mm: float          # equal-area radius
    stretch: tuple[float, float]  # (e1, e2) of its second moments, as in shapes
    contrast: float           # a = peak / tissue − 1


@dataclass
class Choice:
    chosen: str
    weight: float  # its share among the hypotheses whose lumps are apart (what may be chosen)
    runner_up: str | None  # the next of those
    weights: dict[str, float]  # every supported hypothesis's, apart or not: the rivals
    counts: dict = field(default_factory=dict)  # posterior of the lump count (int)
    shares: dict = field(default_factory=dict)  # each hypothesis that may be chosen (lumps apart): its share
    regions: dict = field(default_factory=dict)  # each hypothesis's count of connected stiff regions (k > 1, free-form)

    def as_dict(self) -> dict:
        return {"chosen": self.chosen, "weight": round(self.weight, 4), "runner_up": self.runner_up}

    def count_of(self, name: str | None):
        """The lump count a hypothesis claims: its connected stiff regions (evidence.regions: lumps whose
        boundaries overlap are one; the free-form map's backed regions, lumps.py), else its family's K, 0 for
        `none` with or without a soft region; None for no hypothesis."""
        return self.regions[name] if name in self.regions else lumps_claimed(name)

    @property
    def count_weight(self) -> float:
        """The posterior mass of the chosen hypothesis's count: all the hypotheses that agree on it, each by its
        share of draws that do (evidence.region_counts)."""
        return self.counts.get(self.count_of(self.chosen), self.weight)


def lumps_claimed(name: str | None):
    """The lumps a hypothesis's name says it draws (shapes.Family.name): K, 0 for `none` with or without a
    soft region, "free-form" for the map; None for no hypothesis."""
    if not name or name == "free-form":
        return name or None
    lumps = name.split("+")[0]
    return 0 if lumps == "none" else int(lumps.split(":")[1])


class Hypotheses:
    def __init__(self, size_mm, min_contrast: float, noise_floor: float) -> None:
        self.size_mm = tuple(size_mm)
        self.min_contrast = min_contrast
        self.noise_floor = noise_floor
        self.fits: dict[str, Fit] = {}
        self.raw: dict[str, Fit] = {}  # each checked fit as refitted: its Laplace covariance (where to probe)
        self.weights: dict[str, float] = {}  # of the last choice: who is worth a fresh look when surprised
        self.unfelt_centre: np.ndarray | None = None  # of the last choice (_unfelt_centre)
        self.volumes: dict[str, _Volume] = {}  # each hypothesis's last volume check (posterior.log_volume_ratio)

    def priors(self, obs: Observations) -> Priors:
        return Priors(self.size_mm, self.min_contrast, float(np.median(obs.y)))

    def update(self, obs: Observations, regions: list[Region], tissue_log: float, thorough: bool = False) -> None:
        """Refit every parametric hypothesis worth trying on the readings so far (`thorough`: each from
        fresh starts too, whenever they were last restarted, and every start run to its end)."""
        for _ in self.refits(obs, regions, tissue_log, thorough=thorough):
            pass

    def refits(self, obs: Observations, regions: list[Region], tissue_log: float, max_starts: int | None = None,
               thorough: bool = False):
        """A pass over the hypotheses, one refit per step (a generator yielding each step's work, so that
        a pass can be spread over updates): none; k circles while the last leaves a reading
        unexplained; ellipses for the best count (and one fewer: an elongated lump can look like two
        circles), one ellipse, and the free-form map's count of regions (or like three or more: a 10 × 4 mm
        lump read along its axis was three circles, and ellipse:1 was never fitted)."""
        priors = self.priors(obs)
        self.tissue_log = tissue_log
        before = dict(self.fits)  # as the readings before these left them (a surprise can pull a refit astray)
        seen = ["none"]
        self.fits["none"] = self._fit(shapes.Family("circles", 0, priors.scale_mm), obs, priors, list, max_starts)
        yield self.fits["none"].work
        best_k = 0
        for k in range(1, MAX_LUMPS + 1):  # one lump more while the last fit leaves a reading unexplained
            prev = self.fits[self._name_of(k - 1)]
            if not self._unexplained(prev, obs).any():
                break
            family = shapes.Family("circles", k, priors.scale_mm)
            # a reading that surprised a likely fit of k − 1 lumps may be a lump more: that fit as it was,
            # plus a lump there, is a start for k (its refit is pulled towards a compromise by that reading)
            was = before.get(prev.name)
            surprised = was if self._surprised_contender(was, obs) else None
            fewer = [prev] + ([surprised] if surprised is not None and k > 1 else [])
            more = _closer(before.get(f"circles:{k + 1}"), before.get(family.name))
            fit = self._fit(family, obs, priors, lambda: self._circle_starts(fewer, obs, regions, k, priors, more),
                            max_starts, fresh=surprised is not None, thorough=thorough)
            if fit is None:
                break
            self.fits[fit.name] = fit
            seen.append(fit.name)
            if fit.supported and self._beats(fit.name, self._name_of(best_k), obs):
                best_k = k
            yield fit.work
        counts = set(range(max(1, best_k - 1 if best_k <= 2 else best_k), best_k + 1))
        if best_k:  # n circles in a row along an elongated lump are one ellipse (or as many as the map's regions)
            counts |= {1} | ({len(regions)} if 1 <= len(regions) < best_k else set())
        for k in sorted(counts):
            circles = self.fits.get(f"circles:{k}")
            if circles is not None and circles.supported:
                family = shapes.Family("ellipses", k, priors.scale_mm)
                fit = self._fit(family, obs, priors, lambda: self._ellipse_starts(circles, regions), max_starts,
                                thorough=thorough)
                if fit is not None:
                    self.fits[fit.name] = fit
                    seen.append(fit.name)
                yield 0 if fit is None else fit.work
        # tissue softer in one place: tried while the likeliest count of lumps apart leaves readings unexplained
        # below it, or a soft region was in the running (five circles tiling the tissue around a soft disc beside a
        # lump explain every reading, but are no count of lumps: `apart`), with one lump more while the last
        # leaves a reading unexplained above it (two lumps beside a soft disc: circles:2 explained the readings no
        # better than circles:1, and a count stopped there left circles:2+soft:1 untried)
        if self._soft_wanted(best_k, obs):
            fewer = None
            for k in range(0, MAX_LUMPS + 1):  # past the count without one: lumps beside a soft region misfit alike
                base = self.fits.get(self._name_of(k))
                if base is None and fewer is None:
                    break
                fit = self._soft_fit(shapes.Family("circles", k, priors.scale_mm, soft=1), base, fewer, obs, priors,
                                     max_starts, thorough)
                if fit is None:
                    break
                self.fits[fit.name] = fit
                seen.append(fit.name)
                yield fit.work
                if not self._unexplained(fit, obs).any():
                    break
                fewer = fit
        self.fits = {name: self.fits[name] for name in seen}

    def assimilate(self, obs: Observations) -> None:
        """Every hypothesis takes the readings since its fit by a Kalman step each (see evidence.py)."""
        priors = self.priors(obs)
        for name, old in list(self.fits.items()):
            self.fits[name] = evidence.assimilated(old, obs, priors)

    def checked(self, name: str, obs: Observations) -> Fit | None:
        """The fit of `name` with its covariance checked against the posterior (posterior.py): once per
        refit, then carried along by the Kalman steps; None for the free-form map."""
        fit = self.fits.get(name)
        if fit is not None and fit.family.k and not fit.checked:
            self.raw[name] = fit
            priors = self.priors(obs)
            cov = posterior.checked_cov(fit, obs, priors) + _ridge_spread(fit)
            cov = cov + posterior.profiled_spread(fit, obs, priors, cov)
            fit = self.fits[name] = replace(fit, cov=cov, checked=True)
        return fit

    def laplace(self, name: str) -> Fit | None:
        """The fit of `name` with its Laplace covariance, whether or not it has been checked since: what the
        rivals are compared by (each the same way, whichever of them was asked for), and where to probe."""
        fit = self.fits.get(name)
        return self.raw.get(name, fit) if fit is not None and fit.checked else fit

    @staticmethod
    def _name_of(k: int) -> str:
        return "none" if k == 0 else f"circles:{k}"

    def _fit(self, family, obs, priors, new_starts, max_starts: int | None = None, fresh: bool = False,
             thorough: bool = False) -> Fit | None:
        """Refit from where the hypothesis was; from fresh starts too when it is new, when the readings
        since surprised it (or the count one fewer: they may ask for one lump more), or every
        RESTART_EVERY readings (a warm start can sit in a poor optimum). `thorough`: fresh starts, and none
        given up for lagging the warm one (evidence.fit)."""
        old = self.fits.get(family.name)
        starts = [] if old is None else [old.theta]
        contender = self.weights.get(family.name, 0.0) >= CONTENDER_WEIGHT
        warm_only = not (old is None or obs.n % RESTART_EVERY == 0 or fresh or thorough
                         or self._surprised_contender(old, obs))
        if not warm_only:
            starts += new_starts()
            if old is not None and family.k:  # (`none` has no lump to reshape or resize)
                starts += [_reshaped(old)] + (_resized(old) if contender else [])
                if self._profile_strained(old):
                    starts.append(_other_tails(old))
        starts = starts[:max_starts]
        iterations = LIGHT_ITERATIONS if max_starts is not None else 60
        if family.size == shapes.BACKGROUND_PARAMS:
            starts = [np.array([priors.level, 0.0, 0.0])] + starts
        if not starts:
            return None
        # (thorough: at the noise floor, not the last fit's σ_w: a poor mode's inflated σ_w flattens the cost,
        # and fresh starts stop short of a better mode; σ_w is then re-estimated from the residuals)
        noise_sd = None if old is None or thorough else old.noise_sd
        fit = evidence.fit(family, obs, priors, starts, self.noise_floor, noise_sd, iterations, give_up=not thorough)
        # a warm start alone finds no other mode: the ridge the last fresh starts found is still the one known
        return replace(fit, alternatives=old.alternatives) if warm_only and fit is not None else fit

    def _soft_wanted(self, best_k: int, obs: Observations) -> bool:
        """A soft region is worth a fit: one was in the running, or the likeliest count of lumps apart misses a
        reading below it (by more than SUPPORT_SIGMA), further in stiffness than it misses any above it. (Any
        fit of too few lumps leaves the tissue's readings below it, pulled up by a lump's; what only a soft
        region explains lies further below than any lump lies above: `none` over a lump and a few readings of
        tissue had a soft region tried from the fourth reading on, and the scans took other courses. Further
        in stiffness, not in sds: soft tissue is read as a small force against the sensor's noise, with a
        wide sd; soft-3-0's cyst read 34 sds below `none` and its lump 62 above, 5x softer and 2x stiffer,
        the soft region was never tried and the scan ended `undetermined`.)"""
        if any(w >= CONTENDER_WEIGHT for name, w in self.weights.items() if "+soft" in name):
            return True
        counts = [self.fits.get(self._name_of(k)) for k in range(best_k + 1)]
        apart = [fit for fit in counts if fit is not None and fit.supported
                 and evidence.apart(fit.family, fit.theta)] or [self.fits["none"]]
        fit = max(apart, key=lambda fit: fit.log_evidence)
        z, f = self._misses(fit, obs)
        missed = np.abs(z) > evidence.SUPPORT_SIGMA
        deepest = float(np.max(np.where((obs.kind == EXACT) & missed & (z < 0), f - obs.y, 0.0)))
        highest = float(np.max(np.where((obs.kind >= 0) & missed & (z > 0), obs.y - f, 0.0)))
        return deepest > highest

    def _soft_fit(self, family: shapes.Family, base: Fit | None, fewer: Fit | None, obs: Observations,
                  priors: Priors, max_starts: int | None, thorough: bool) -> Fit | None:
        """k circles on a background with a soft region (shapes.py), from `base` (the fit of k circles, if any)
        with a soft region added, and from `fewer` (the soft fit of one lump fewer) with a lump at each reading
        it explains worst from above."""
        def starts():
            out = self._soft_starts(base, obs) if base is not None else []
            if fewer is not None:
                cut = fewer.family.soft_slice
                out += [np.concatenate([fewer.theta[:cut.start], lump, fewer.theta[cut]])
                        for lump in self._new_lumps(fewer, obs)]
            return out
        return self._fit(family, obs, priors, starts, max_starts, fresh=family.name not in self.fits, thorough=thorough)

    def _soft_starts(self, base: Fit, obs: Observations) -> list[np.ndarray]:
        """`base` with a soft region at the reading it explains worst from below, and with its background at
        the level of the stiffer readings away from its lumps and a soft region over those below that; each
        region reaching most of the way to the nearest reading it leaves alone."""
        exact = obs.kind == EXACT
        below = self._unexplained(base, obs, below=True)
        away = exact & (shapes.heights_of(base.family, base.theta, obs.xy).max(axis=1, initial=0.0) < 0.05)
        level = float(np.quantile(obs.y[away], 0.75)) if away.any() else float(base.theta[0])
        soft = away & (obs.y < level - math.log1p(self.min_contrast))
        starts = []
        if below.any():
            _, f = self._misses(base, obs)
            worst = int(np.argmin(np.where(below, obs.y - f, np.inf)))  # the deepest in log stiffness
            starts.append(self._with_soft(base.theta, obs, obs.xy[worst], f[worst] - obs.y[worst], ~below))
        if soft.any():
            raised = base.theta.copy()
            raised[0] = level
            starts.append(self._with_soft(raised, obs, obs.xy[soft].mean(axis=0),
                                          level - float(np.median(obs.y[soft])), ~soft))
        return starts

    def _with_soft(self, theta: np.ndarray, obs: Observations, xy, depth: float, alone: np.ndarray) -> np.ndarray:
        """θ with a soft region at xy, `depth` lower in log stiffness, reaching most of the way to the nearest
        reading `alone` marks (one it leaves as it is)."""
        reach = _nearest(xy, obs.xy[alone]) if alone.any() else 0.25 * max(self.size_mm)
        region = shapes.make_lump(xy, max(0.7 * reach, 0.6), START_SHARPNESS, max(math.expm1(depth), 1.2 * self.min_contrast))
        return np.concatenate([theta, region])

    def _profile_strained(self, fit: Fit) -> bool:
        """Whether a fit's lump profiles may belong on the other tail branch (shapes.py): it misses its
        readings (σ_w over PROFILE_MISFIT times the floor), or a lump's tails are as thin as tails that
        never end can be (the mode may lie beyond, among tails that end)."""
        if fit.noise_sd > PROFILE_MISFIT * self.noise_floor:
            return True
        for j in range(fit.family.k):
            tail = fit.theta[fit.family.lump_slice(j).stop - 3]
            if tail >= shapes.TAIL_RANGE[1] - STRAINED_TAIL:
                return True
        return False

    def _surprised_contender(self, old: Fit | None, obs: Observations) -> bool:
        return old is not None and self.weights.get(old.name, 0.0) >= CONTENDER_WEIGHT and self._surprised(old, obs)

    def _surprised(self, old: Fit, obs: Observations) -> bool:
        f, _ = shapes.evaluate(old.family, old.theta, obs.xy[old.n:], jacobian=False)
        total = np.sqrt(obs.sd[old.n:] ** 2 + max(old.noise_sd, self.noise_floor) ** 2)
        return bool(np.any(np.abs(obs.y[old.n:] - f) > evidence.SUPPORT_SIGMA * total))

    # -- starts -----------------------------------------------------------------------------------
    def _circle_starts(self, fewer: list[Fit], obs, regions, k, priors, more: Fit | None = None) -> list[np.ndarray]:
        """One lump more than each fit of k − 1 (refitted now, and as it was before: a reading that
        surprised it pulls its refit towards a compromise, while the old fit plus a lump there explains
        it), one lump fewer than a fit of k + 1 that explained the readings closer (_dropped), k-means
        groups of the stiff readings, and the free-form regions."""
        base = np.array([self.tissue_log, 0.0, 0.0])
        starts = [np.concatenate([fit.theta if k > 1 else base, lump]) for fit in fewer
                  for lump in self._new_lumps(fit, obs)]
        if more is not None:
            starts += _dropped(more)
        ellipses = self.fits.get(f"ellipse:{k - 1}")
        if ellipses is not None:
            starts += _split(ellipses)
        clustered = self._stiff_clusters(obs, k)
        if clustered:
            starts += [np.concatenate([base, *lumps]) for lumps in clustered]
        if len(regions) >= k:
            lumps = [_region_lump(r, ellipse=False) for r in sorted(regions, key=lambda r: -r.radius_mm)[:k]]
            starts.append(np.concatenate([base, *lumps]))
        return starts

    def _stiff_clusters(self, obs: Observations, k: int) -> list[list[np.ndarray]]:
        """k lumps over the readings clearly above the tissue, grouped by k-means: each over its group's
        centroid, reaching most of the way to the nearest soft reading."""
        excess = obs.y - self.tissue_log
        stiff = (excess > math.log1p(self.min_contrast)) & (obs.kind >= 0)
        if np.count_nonzero(stiff) < k:
            return []
        points = obs.xy[stiff]
        labels = _kmeans(points, k)
        lumps = []
        for j in range(k):
            group = points[labels == j]
            if len(group) == 0:
                return []
            centre = group.mean(axis=0)
            inner = float(np.max(np.hypot(*(group - centre).T)))
            outer = _nearest(centre, obs.xy[~stiff]) if (~stiff).any() else inner + 0.25 * max(self.size_mm)
            contrast = max(math.expm1(float(np.median(excess[stiff][labels == j]))), self.min_contrast * 1.2)
            lumps.append((centre, max(0.5 * (inner + outer), inner, 0.6), contrast))
        return [[shapes.make_lump(c, 0.85 * r, START_SHARPNESS, a) for c, r, a in lumps]]

    def _excess(self, fit: Fit, obs: Observations) -> tuple[np.ndarray, np.ndarray]:
        """Each exact reading above the fit, in units of its noise at the floor (0 for a bound), and the
        fit's prediction."""
        z, f = self._misses(fit, obs)
        return np.where(obs.kind == EXACT, z, 0.0), f

    def _unexplained(self, fit: Fit, obs: Observations, below: bool = False) -> np.ndarray:
        """The readings above the fit by more than SUPPORT_SIGMA at the noise floor, exact or lower bounds
        ('too stiff'): a lump read only at the force limit is one more lump to try (`none` beside it was
        left alone, and chosen at weight 1.0 over 91 readings, 6 of them 'at least 5x the tissue').
        `below`: the exact readings that far below it (a soft region to try)."""
        z, _ = self._misses(fit, obs)
        if below:
            return np.where(obs.kind == EXACT, -z, 0.0) > evidence.SUPPORT_SIGMA
        return np.where(obs.kind >= 0, z, 0.0) > evidence.SUPPORT_SIGMA

    def _misses(self, fit: Fit, obs: Observations) -> tuple[np.ndarray, np.ndarray]:
        """How far each reading lies above the fit, in sds of its noise at the floor (the fit's own σ_w may have
        swallowed what it misses), and the fit's prediction."""
        f, _ = shapes.evaluate(fit.family, fit.theta, obs.xy, jacobian=False)
        return (obs.y - f) / np.sqrt(obs.sd**2 + self.noise_floor**2), f

    def _new_lumps(self, fit: Fit, obs: Observations) -> list[np.ndarray]:
        """A lump at each of the two readings the fit explains worst, reaching most of the way to the
        nearest reading it does explain."""
        excess, f = self._excess(fit, obs)
        explained = np.abs(excess) < evidence.SUPPORT_SIGMA
        lumps, used = [], []
        for i in np.argsort(-excess)[:4]:
            if excess[i] <= evidence.SUPPORT_SIGMA or any(math.dist(obs.xy[i], u) < 3.0 for u in used):
                continue
            used.append(obs.xy[i])
            reach = _nearest(obs.xy[i], obs.xy[explained]) if explained.any() else 0.25 * max(self.size_mm)
            contrast = max(math.expm1(obs.y[i] - f[i]), self.min_contrast * 1.2)
            lumps.append(shapes.make_lump(obs.xy[i], max(0.7 * reach, 0.6), START_SHARPNESS, contrast))
            if len(used) == 2:
                break
        return lumps

    def _ellipse_starts(self, circles: Fit, regions: list[Region]) -> list[np.ndarray]:
        """The circles as they are and stretched like the free-form regions; for one lump, also along x and y."""
        k, theta = circles.family.k, circles.theta
        lumps = [theta[circles.family.lump_slice(j)] for j in range(k)]
        stretches = [[(0.0, 0.0)] * k]
        if regions:
            stretches.append([min(regions, key=lambda r: math.dist(r.center_mm, l[:2])).stretch for l in lumps])
        if k == 1:
            stretches += [[(ELLIPSE_START_STRETCH, 0.0)], [(-ELLIPSE_START_STRETCH, 0.0)]]
        starts = [np.concatenate([theta[:3], *[_stretched(l, st) for l, st in zip(lumps, stretch)]])
                  for stretch in stretches]
        if len(regions) == k:
            starts.append(np.concatenate([theta[:3], *[_region_lump(r, ellipse=True) for r in regions]]))
        return starts

    # -- the choice -------------------------------------------------------------------------------
    def choice(self, free_form_log_evidence: float | None, obs: Observations, free_form_regions: int = 0,
               free_form_counts: dict[int, float] | None = None) -> Choice:
        """Posterior weights of the supported hypotheses (and the free-form map's, when it has a region: it
        claims as many lumps as it has `free_form_regions`), each parametric one's evidence checked against its
        posterior (posterior.py) from the most likely down, until the rest could not weigh anything whatever
        their check says.

        The chosen one is the most likely whose lumps are apart (evidence.apart), its weight its share
        among those: lumps laid over one another to tile a stiff region are no count of lumps (a stiff
        quadrant was chosen as two circles, one inside the other, and two thirds of the tissue as three
        long ellipses at 0.98). Such a fit stays among the weights, a rival the next readings tell apart
        from the chosen one (decision.py): where it predicts unlike the chosen model, a reading is worth
        taking (two touching lumps read around but not between were first two overlapping circles)."""
        candidates = {name: fit.log_evidence for name, fit in self.fits.items() if fit.supported}
        best = -math.inf
        if free_form_log_evidence is not None:
            candidates["free-form"] = best = free_form_log_evidence
        for name in sorted(candidates, key=lambda m: -candidates[m]):
            if name == "free-form" or candidates[name] < best - NEGLIGIBLE_NATS:
                continue
            candidates[name] = self._evidence_checked(name, obs).log_evidence
            best = max(best, candidates[name])
        names = sorted(candidates, key=lambda m: -candidates[m])
        weights = shares_among({m: candidates[m] for m in names})
        self.weights = weights
        separate = [m for m in names if m == "free-form" or evidence.apart(self.fits[m].family, self.fits[m].theta)]
        chosen = separate[0]
        self.unfelt_centre = self._unfelt_centre(candidates[chosen], obs)
        # The posterior of the count sums every hypothesis that claims as many lumps, the free-form map too: a
        # band across the tissue, read as one ellipse and as the map's one region by turns, had each reading
        # "change the count" and ended `undetermined` at the budget, its boundary at IoU 0.96.
        regions = {m: len(evidence.regions(self.fits[m].family, self.fits[m].theta)) for m in names
                   if m != "free-form" and self.fits[m].family.k > 1}
        if "free-form" in candidates:
            regions["free-form"] = free_form_regions
        share = sum(weights[m] for m in separate)
        # their shares among themselves; from their own evidences when, behind lumps laid over one another
        # thousands of nats ahead, their weights all underflowed to 0 (the division failed: shares_among)
        shares = {m: weights[m] / share for m in separate} if share > 0.0 else \
            shares_among({m: candidates[m] for m in separate})
        choice = Choice(chosen, shares[chosen], separate[1] if len(separate) > 1 else None, weights, {}, shares,
                        regions)
        for m in separate:
            # each hypothesis's count over its parameters' posterior: lumps whose boundaries nearly meet may be
            # one region or two (evidence.region_counts); one too unlikely to move the count, at its mode
            fit = self.fits.get(m)  # None for the free-form map, whose regions are its own (`free_form_counts`)
            if fit is None:
                spread = free_form_counts if free_form_counts and shares[m] >= COUNT_SHARE else {choice.count_of(m): 1.0}
            else:
                spread = evidence.region_counts(fit.family, fit.theta, fit.cov) \
                    if m in regions and shares[m] >= COUNT_SHARE else {choice.count_of(m): 1.0}
            for count, p in spread.items():
                choice.counts[count] = choice.counts.get(count, 0.0) + shares[m] * p
        return choice

    def _unfelt_centre(self, chosen_log_evidence: float, obs: Observations) -> np.ndarray | None:
        """The centre of a lump no reading feels yet, in a hypothesis the evidence prefers to the chosen
        one (checked): the readings ask for that lump, and one reading over it says whether it is there."""
        for name, fit in sorted(self.fits.items(), key=lambda kv: -kv[1].log_evidence):
            if fit.log_evidence <= chosen_log_evidence:
                return None
            if fit.supported or self._evidence_checked(name, obs).log_evidence <= chosen_log_evidence:
                continue
            fit = self.fits[name]
            unfelt = evidence.unfelt(fit.family, fit.theta, obs, self.noise_floor)
            if unfelt:  # the check may have moved the fit to where every lump is felt: nothing to look for
                return fit.theta[fit.family.lump_slice(unfelt[0])][:2]
        return None

    def _beats(self, name: str, best: str, obs: Observations) -> bool:
        """`name` has more evidence than `best`, both checked (Laplace first: it bounds the checked one)."""
        if self.fits[name].log_evidence <= self._evidence_checked(best, obs).log_evidence:
            return False
        return self._evidence_checked(name, obs).log_evidence > self.fits[best].log_evidence

    def _evidence_checked(self, name: str, obs: Observations) -> Fit:
        """The fit with its evidence checked (once per refit; Kalman steps carry it along). A refit
        that stayed within 1 sd of the mode last checked keeps that check's correction until the
        readings have grown by RECHECK_GROWTH. Linear in its parameters, `none` is its Laplace
        approximation exactly; one lump is left as Laplace has it (docs/learner.md says why)."""
        fit = self.fits[name]
        if fit.family.k < 2 or fit.evidence_checked:
            return fit
        last = self.volumes.get(name)
        if last is None or not last.holds_for(fit):
            last = self.volumes[name] = _Volume(fit.theta, np.linalg.pinv(fit.cov), fit.n,
                                                posterior.log_volume_ratio(fit, obs, self.priors(obs)))
        fit = self.fits[name] = replace(fit, log_evidence=fit.log_evidence + last.log_ratio, evidence_checked=True)
        return fit


@dataclass(frozen=True)
class _Volume:
    """A volume check: the mode it was made at, that mode's precision, the readings then, its result."""
    theta: np.ndarray
    precision: np.ndarray
    n: int
    log_ratio: float

    def holds_for(self, fit: Fit) -> bool:
        if fit.theta.shape != self.theta.shape or fit.n > RECHECK_GROWTH * self.n:
            return False
        moved = fit.theta - self.theta
        return float(moved @ self.precision @ moved) <= 1.0


def _ridge_spread(fit: Fit) -> np.ndarray:
    """The spread of the modes as likely as the fit (its alternatives, lumps matched to the fit's by their
    centres): what its covariance misses along a ridge of the posterior. The check of the covariance steps
    straight along its own directions, and a curved ridge leaves a straight step: a lump whose core readings
    all hit the force limit was reported 6.07 ± 0.29 mm in radius, while a mode as high lay at 9.0 mm, the
    truth (a narrower, much stiffer lump with a softer edge feels the same at the edge readings)."""
    spread = np.zeros_like(fit.cov)
    for other in fit.alternatives:
        d = _matched(fit, other) - fit.theta
        spread += np.outer(d, d) / len(fit.alternatives)
    return spread


def _matched(fit: Fit, other: np.ndarray) -> np.ndarray:
    """`other` with its lumps in the order of the fit's nearest ones (lumps are interchangeable)."""
    family = fit.family
    if family.k < 2:
        return other
    out, free = other.copy(), list(range(family.k))
    for j in range(family.k):
        mine = fit.theta[family.lump_slice(j)][:2]
        nearest = min(free, key=lambda m: math.dist(mine, other[family.lump_slice(m)][:2]))
        free.remove(nearest)
        out[family.lump_slice(j)] = other[family.lump_slice(nearest)]
    return out


def _kmeans(points: np.ndarray, k: int) -> np.ndarray:
    """Labels of k groups (k-means++, seeded: the same readings always group the same way)."""
    if k == 1:
        return np.zeros(len(points), dtype=int)
    import warnings

    from scipy.cluster.vq import kmeans2

    distinct, spot = np.unique(points, axis=0, return_inverse=True)
    if len(distinct) <= k:  # a group per spot (k-means++ divides by zero when every spot is already a centre)
        return spot.ravel()
    # An empty group only means fewer starts; scipy warns of it on stderr, a line no user can act on (it
    # leaked into `palpd bench calibration`'s table).
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="One of the clusters is empty", category=UserWarning)
        _, labels = kmeans2(points, k, minit="++", seed=0)
    return labels


def _resized(fit: Fit) -> list[np.ndarray]:
    """The fit with one lump at a time made smaller or larger: a way out of a mode that grew one lump
    over two real ones, or shrank one to fit a neighbour's edge."""
    out = []
    for j in range(fit.family.k):
        for factor in RESIZE:
            theta = fit.theta.copy()
            theta[fit.family.lump_slice(j).start + 2] += math.log(factor)
            out.append(theta)
    return out


def shares_among(log_evidences: dict[str, float]) -> dict[str, float]:
    """Each hypothesis's posterior share among these, from their log evidences (equal priors), computed from
    the likeliest of them: weights taken over a larger set first could all underflow to 0 here (a sliding
    raster's ~1300 readings of a stiff lump put thousands of nats between lumps laid over one another and
    those apart, and the shares of those apart were 0 / 0)."""
    top = max(log_evidences.values())
    raw = {m: math.exp(v - top) for m, v in log_evidences.items()}
    total = sum(raw.values())
    return {m: v / total for m, v in raw.items()}


def _closer(more: Fit | None, fit: Fit | None) -> Fit | None:
    """The fit of one lump more, when it explained the readings closer than this count's fit (a smaller σ_w)."""
    if more is None or more.family.kind != "circles":
        return None
    return more if fit is None or more.noise_sd < fit.noise_sd else None


def _dropped(more: Fit) -> list[np.ndarray]:
    """The fit of k + 1 lumps without each of its lumps in turn: counts are built up one lump at a time,
    and a first lump grown over two real ones stays in every count's fit built on it (three touching lumps
    read as a measured map: one circle over two of them, and three circles that kept it, its σ_w 6x the
    floor, while four fitted to the floor, the fourth a sliver beside one of the three)."""
    family, theta = more.family, more.theta
    lumps = [theta[family.lump_slice(j)] for j in range(family.k)]
    return [np.concatenate([theta[:3], *lumps[:j], *lumps[j + 1:]]) for j in range(family.k)]


def _split(ellipses: Fit) -> list[np.ndarray]:
    """Circles one more than the ellipses, each ellipse in turn split in two along its major axis (the
    others made round): two round lumps side by side fit one ellipse, and no other start need find them
    (touching lumps: k-means grouped the stiff readings as one faint reading against the rest, and two
    circles started from one lump plus another at the worst-explained reading ended 7-9 nats below the two
    that fit)."""
    k = ellipses.family.k
    lumps = [ellipses.theta[ellipses.family.lump_slice(j)] for j in range(k)]
    rounds = [np.concatenate([p[:2], [p[2]], p[5:]]) for p in lumps]  # the equal-area circle of each
    out = []
    for j, p in enumerate(lumps):
        major, minor, angle_deg = shapes.axes_and_angle(p, True)
        if major <= 1.2 * minor:
            continue  # nearly round: one lump, not two
        along = (major - minor) * np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
        halves = [np.concatenate([p[:2] + side * along, [math.log(minor)], p[5:]]) for side in (-1.0, 1.0)]
        out.append(np.concatenate([ellipses.theta[:3], *rounds[:j], *halves, *rounds[j + 1:]]))
    return out


def _reshaped(fit: Fit) -> np.ndarray:
    """The fit with every lump's edge and tails as a fresh start has them: a way out of a mode where one
    lump's edge bent to stand in for a neighbour (touching lumps: the third took Gaussian tails and a 2.4
    sharpness, 48 nats below its true power-law edge, which a fourth, false lump then made up for)."""
    theta = fit.theta.copy()
    for j in range(fit.family.k):
        start = fit.family.lump_slice(j).stop - 3  # [.., λ, log s, log a]
        theta[start:start + 2] = (0.0, math.log(START_SHARPNESS))
    return theta


def _other_tails(fit: Fit) -> np.ndarray:
    """The fit with every lump's tails on the other branch (shapes.py): ending at a finite distance if
    they fall off for ever, and the reverse. A fit stays on the branch it starts on, and a cone or a
    plateau with a ramp, fitted with tails that never end, draws its half-height 1-2 mm too far out."""
    theta = fit.theta.copy()
    for j in range(fit.family.k):
        start = fit.family.lump_slice(j).stop - 3  # [.., λ, log s, log a]
        compact = theta[start] < 0.0
        theta[start:start + 2] = (0.5, math.log(START_SHARPNESS)) if compact else (COMPACT_START, math.log(2.0))
    return theta


def _nearest(point: np.ndarray, others: np.ndarray) -> float:
    return float(np.min(np.hypot(others[:, 0] - point[0], others[:, 1] - point[1])))


def _region_lump(region: Region, ellipse: bool) -> np.ndarray:
    return shapes.make_lump(region.center_mm, max(region.radius_mm, 0.6), START_SHARPNESS,
                            max(region.contrast, 0.31), region.stretch if ellipse else None)


def _stretched(circle: np.ndarray, stretch) -> np.ndarray:
    return np.concatenate([circle[:3], stretch, circle[3:]])
