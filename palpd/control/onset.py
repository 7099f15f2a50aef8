"""Where contact really began, found from the whole trace rather than from where a threshold fired.

A threshold fires only once the pressed force has risen clear of the noise: at 0.3 N of noise that is
millimetres into the tissue, and on 0.005 N/mm tissue it may be centimetres. The trace before and after that
moment holds the answer: flat (the zero) until the surface, then rising. A two-segment fit (a hinge: constant,
then a straight rise from z0) over the approach and the loading to the deepest point finds z0 by least
squares, every candidate hinge at once (and a hinge rising as u^1.5 and u², for curved tissue). Before that, each tip reading is moved to its force sample's instant
(the tip reading answering the last command is about a servo period older than the force), so loading and
unloading do not part by a lag that would pass for damping.

Runs on the host after the palpation, never in the servo tick.
"""
from __future__ import annotations

import numpy as np

CANDIDATES = 256  # hinge positions tried in the coarse pass; the best one's neighbours are then all tried
EXPONENTS = (1.0, 1.5, 2.0)
MIN_RISE_T = 3.0  # the rise must stand this many standard errors clear of flat, or the detected point stands
# Onsets whose hinge fits the trace within this many noise variances of the best are as plausible as the best
# (about two standard errors for one parameter): their span is how well the trace places the onset.
PLAUSIBLE_RSS_UNITS = 4.0


def refine(segment, refit_onset: bool = True) -> bool:
    """Replace the segment's contact point, loading and unloading traces by the refitted ones (in place);
    False when the trace shows no rise (the contact point stays where the threshold fired). Without
    refit_onset (a damped model, whose own contact offset is fitted with it: a hinge assumes an elastic
    rise) the threshold's contact point stays, the traces are only aligned."""
    raw = np.asarray(segment.samples, dtype=float).reshape(-1, 5)
    if len(raw) < 8:
        return False
    t, x, y, z, f = raw.T
    if segment.force_lead_s:
        z = np.interp(t + segment.force_lead_s, t, z)
    detected = segment.detected_at
    peak = detected + int(np.argmin(z[detected:]))  # the deepest point: the depth is nearly noise-free
    # The hinge is fitted over the approach and the first half of the press: a curved or damped tissue's
    # force bends (or follows the speed) deeper, which would drag a hinge's onset with it.
    halfway = detected + int(np.argmax(z[detected:peak + 1] <= (z[detected] + z[peak]) / 2.0))
    onset, zero_n, spread_mm = hinge(z[:halfway + 1], f[:halfway + 1], detected) if refit_onset else (detected, 0.0, 0.0)
    if onset is None:
        return False
    d, pressed = z[onset] - z, f - zero_n
    segment.contact_z_mm = float(z[onset])
    segment.onset_spread_mm = spread_mm
    segment.baseline_n += zero_n
    segment.depth_mm, segment.force_n = d[onset:peak + 1].tolist(), pressed[onset:peak + 1].tolist()
    segment.unload_depth_mm, segment.unload_force_n = d[peak + 1:].tolist(), pressed[peak + 1:].tolist()
    segment.xy_mm = (float(x[onset:].mean()), float(y[onset:].mean()))
    segment.peak_force_n = float(pressed[peak])
    return True


def hinge(z: np.ndarray, f: np.ndarray, fallback: int) -> tuple[int | None, float, float]:
    """(index of the onset, the zero force before it, the span in mm of the onsets as plausible as it):
    least squares of f = c + k·max(z[j] − z, 0)ⁿ over every j, for n of 1, 1.5 and 2 (a curved tissue's rise
    bends a straight hinge's onset deeper). With too few samples, the fallback; with no significant rise, None."""
    n = z.size
    if n < 6:
        return min(fallback, n - 1), 0.0, 0.0
    fits = [_best_onset(z, f, power) for power in EXPONENTS]
    rss, onset, rises, zero_n, spread_mm = min(fits)
    return (onset, zero_n, spread_mm) if rises else (None, 0.0, 0.0)


def _best_onset(z, f, power: float) -> tuple[float, int, bool, float, float]:
    n = z.size
    coarse = np.unique(np.linspace(0, n - 1, min(n, CANDIDATES)).astype(int))
    coarse_rss = _rss(z, f, coarse, power)[0]
    best = coarse[np.argmin(coarse_rss)]
    step = max(1, n // CANDIDATES)
    fine = np.arange(max(best - step, 0), min(best + step, n - 1) + 1)
    rss, slope, se, intercept = _rss(z, f, fine, power)
    i = int(np.argmin(rss))
    # A faint rise at the end of a long flat trace can sit anywhere along it: the noise, not the tissue,
    # then decides where the hinge bends, and the slope after it is the noise's too.
    plausible = z[coarse[coarse_rss <= rss[i] * (1.0 + PLAUSIBLE_RSS_UNITS / max(n - 3, 1))]]
    spread_mm = float(plausible.max() - plausible.min()) if plausible.size else 0.0
    return float(rss[i]), int(fine[i]), bool(slope[i] > MIN_RISE_T * se[i]), float(intercept[i]), spread_mm


def _rss(z, f, candidates, power: float):
    """Residual sum of squares, slope, its se and intercept of the hinge at each candidate onset."""
    u = np.maximum(z[candidates][:, None] - z[None, :], 0.0) ** power  # indentation if contact began there
    n = z.size
    su, suu, suf = u.sum(axis=1), (u * u).sum(axis=1), u @ f
    sf, sff = f.sum(), f @ f
    sxx = suu - su * su / n
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = np.where(sxx > 0, (suf - su * sf / n) / sxx, 0.0)
        intercept = (sf - slope * su) / n
        rss = np.maximum(sff - sf * sf / n - slope * slope * sxx, 0.0)
        se = np.sqrt(rss / max(n - 2, 1) / np.where(sxx > 0, sxx, np.inf))
    return np.where(sxx > 0, rss, np.inf), slope, se, intercept
