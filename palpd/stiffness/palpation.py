"""The stiffness of one recorded palpation, as the settings ask for it.

Loading and unloading are fitted together when the model may carry damping:
at a constant indentation speed k·xⁿ and b·xⁿ·ẋ cannot be told apart on the
way in alone, while the way out (ẋ < 0) separates them. The rate comes from
the depth trace itself (a Savitzky–Golay derivative over ~15 ms), since the
encoder steps (~23 µm) make sample-to-sample differences useless.
"""
from __future__ import annotations

import numpy as np

from palpd.stiffness.selection import SELECT, StiffnessResult, fit_stiffness
from palpd.stiffness.models import MODELS

RATE_WINDOW_S = 0.015


def fit_palpation(record, stiffness_settings, rate_hz: float, rate_varies: bool = False) -> StiffnessResult:
    """Raises FitRejected with a named reason when the record gives no stiffness. rate_varies: the press
    swung its speed (palpation.speed_profile = "varying"); only then may selection weigh a damping model,
    which at one constant speed would buy itself out of the controller's start-up transient and any lag
    left between force and position, not out of the tissue."""
    s = stiffness_settings
    with_damping = MODELS[s.model].needs_rate if s.model != SELECT else rate_varies
    depth, force = list(record.depth_mm), list(record.force_n)
    rate = list(depth_rate_mm_s(record.depth_mm, rate_hz)) if with_damping else None  # only a damping model reads it
    if with_damping and len(record.unload_depth_mm) >= 5:
        depth += record.unload_depth_mm
        force += record.unload_force_n
        rate += list(depth_rate_mm_s(record.unload_depth_mm, rate_hz))
    return fit_stiffness(depth, force, rate, model=s.model, criterion=s.criterion,
                         reference_depth_mm=s.reference_depth_mm)


def depth_rate_mm_s(depth_mm, rate_hz: float) -> np.ndarray:
    """dx/dt of a trace sampled every servo tick (zeros when it is too short to tell)."""
    d = np.asarray(depth_mm, dtype=float)
    window = min(int(RATE_WINDOW_S * rate_hz) | 1, d.size if d.size % 2 else d.size - 1)
    if window < 5 or not np.all(np.isfinite(d)):
        return np.zeros_like(d)
    from scipy.signal import savgol_filter  # here: scipy.signal brings scipy.stats, ~0.4 s of start-up

    return savgol_filter(d, window, 2, deriv=1, delta=1.0 / rate_hz)
