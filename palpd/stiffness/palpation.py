"""The stiffness of one recorded palpation, as the settings ask for it.

Loading and unloading are fitted together when the model may carry damping:
at a constant indentation speed k·xⁿ and b·xⁿ·ẋ cannot be told apart on the
way in alone, while the way out (ẋ < 0) separates them. The rate comes from
the depth trace itself (a Savitzky–Golay derivative over ~15 ms), since the
encoder steps (~23 µm) make sample-to-sample differences useless.
"""
from __future__ import annotations

import math

import numpy as np

from palpd.stiffness.selection import SELECT, StiffnessResult, fit_stiffness
from palpd.stiffness.models import MODELS

RATE_WINDOW_S = 0.015
# A press fitted without a damping model reads k + b·v at its own speed v, which holds only while it presses at
# that speed: the stop's last tens of milliseconds, the tip braking at nearly constant depth, take a damped
# tissue's b·v away (0.0257 N/mm with 0.01 N·s/mm, pressed at ~7.5 mm/s, lost 1 N of its 2.5 N there, and a power
# law bent to fit it read 0.52 ± 0.018 N/mm where the press's own truth was 0.37). Those samples are left out
# when they lost force the depth does not explain (before_the_stop).
STOP_SPEED_FRACTION = 0.9
STOP_WINDOW_S = 0.04
BRAKING_SE = 3.0


def fit_palpation(record, stiffness_settings, rate_hz: float, rate_varies: bool = False) -> StiffnessResult:
    """Raises FitRejected with a named reason when the record gives no stiffness. rate_varies: the press
    swung its speed (palpation.speed_profile = "varying"); only then may selection weigh a damping model,
    which at one constant speed would buy itself out of the controller's start-up transient and any lag
    left between force and position, not out of the tissue."""
    s = stiffness_settings
    with_damping = MODELS[s.model].needs_rate if s.model != SELECT else rate_varies
    depth, force = list(record.depth_mm), list(record.force_n)
    reference_mm = s.reference_depth_mm
    if getattr(record, "stop_reason", "force") != "force" and depth:
        # Only a press the force limit stopped short is read along its curve towards the reference (fit.REACH);
        # one that went the whole configured depth, shallower than the reference, is read where it ends.
        reference_mm = min(reference_mm, max(depth))
    rate = list(depth_rate_mm_s(record.depth_mm, rate_hz)) if with_damping else None  # only a damping model reads it
    if not with_damping:
        kept = before_the_stop(depth, force, rate_hz)
        depth, force = depth[:kept], force[:kept]
    if with_damping and len(record.unload_depth_mm) >= 5:
        depth += record.unload_depth_mm
        force += record.unload_force_n
        rate += list(depth_rate_mm_s(record.unload_depth_mm, rate_hz))
    return fit_stiffness(depth, force, rate, model=s.model, criterion=s.criterion, reference_depth_mm=reference_mm)


def before_the_stop(depth_mm, force_n, rate_hz: float) -> int:
    """How many of the loading samples to fit: all of them, unless the stop's braking (the trailing samples
    slower than STOP_SPEED_FRACTION of the press's median speed, at most STOP_WINDOW_S) took away force that
    the depth does not explain: below the line the press followed just before it by more than BRAKING_SE
    standard errors. An elastic tissue's force follows its depth through the braking, and its trace is kept
    whole (leaving those samples out moved readings by up to 0.15 sd, and the learner's decisions with them)."""
    d, f = np.asarray(depth_mm, dtype=float), np.asarray(force_n, dtype=float)
    rate = depth_rate_mm_s(d, rate_hz)
    whole = d.size
    speed = float(np.median(rate)) if whole else 0.0
    if speed <= 0.0 or not np.all(np.isfinite(f)):
        return whole
    window = int(STOP_WINDOW_S * rate_hz)
    kept = whole
    while kept > max(whole - window, 0) and rate[kept - 1] < STOP_SPEED_FRACTION * speed:
        kept -= 1
    before = slice(max(kept - window, 0), kept)
    if kept == whole or kept - before.start < 5:
        return whole
    slope, intercept = np.polyfit(d[before], f[before], 1)
    noise_sd = float(np.std(f[before] - (slope * d[before] + intercept), ddof=2))
    shortfall = float(np.mean(slope * d[kept:] + intercept - f[kept:]))
    return kept if shortfall > BRAKING_SE * noise_sd / math.sqrt(whole - kept) else whole


def depth_rate_mm_s(depth_mm, rate_hz: float) -> np.ndarray:
    """dx/dt of a trace sampled every servo tick (zeros when it is too short to tell): a Savitzky–Golay
    derivative (quadratic, RATE_WINDOW_S wide), as scipy.signal.savgol_filter(d, window, 2, deriv=1) gives it
    (tests/test_stiffness.py checks it does), in numpy: scipy.signal brings scipy.stats with it, ~0.4 s of
    start-up in every process that fits a palpation, and every fit now reads the rate (before_the_stop)."""
    d = np.asarray(depth_mm, dtype=float)
    window = min(int(RATE_WINDOW_S * rate_hz) | 1, d.size if d.size % 2 else d.size - 1)
    if window < 5 or not np.all(np.isfinite(d)):
        return np.zeros_like(d)
    half = window // 2
    offsets = np.arange(-half, half + 1, dtype=float)
    rate = np.empty_like(d)
    # Inside: the slope of the least-squares quadratic at each window's centre, which is the straight line's.
    rate[half:d.size - half] = np.correlate(d, offsets / (offsets @ offsets), mode="valid")
    # The ends: the quadratic fitted to the first (last) whole window, differentiated at each point it covers.
    curvature, slope, _ = np.polyfit(offsets, d[:window], 2)
    rate[:half] = 2.0 * curvature * offsets[:half] + slope
    curvature, slope, _ = np.polyfit(offsets, d[-window:], 2)
    rate[d.size - half:] = 2.0 * curvature * offsets[half + 1:] + slope
    return rate * rate_hz
