"""What the palpations said, as the learner keeps it: log stiffness readings and censored bounds.

Each palpation has an outcome (DESIGN.md, scan report `probes[].outcome`):
`fit` is a reading with its fit uncertainty; `too_stiff` says the stiffness is
at least a bound (the force limit came first), `too_soft` at most one: both are
kept as bounds, never dropped, since the stiffest spots are the evidence of a
lump. `no_contact` and `rejected` teach nothing about stiffness, but the spot
was tried and is not asked for again. Values are kept as log stiffness, where a
relative error is one number whatever the tissue.
"""
from __future__ import annotations

import math

import numpy as np

OUTCOMES = ("fit", "no_contact", "too_stiff", "too_soft", "rejected")
EXACT, AT_LEAST, AT_MOST = 0, 1, -1
CENSORED = {"too_stiff": AT_LEAST, "too_soft": AT_MOST}


class Observations:
    """Readings in arrival order: xy (n × 2, mm), y = log k, sd of y, and kind (EXACT, AT_LEAST, AT_MOST)."""

    def __init__(self) -> None:
        self.xy = np.empty((0, 2))
        self.y = np.empty(0)
        self.sd = np.empty(0)
        self.kind = np.empty(0, dtype=int)

    @property
    def n(self) -> int:
        return len(self.y)

    @property
    def exact(self) -> np.ndarray:
        return self.kind == EXACT

    def add(self, xy, outcome: str, stiffness_n_per_mm: float | None, sd_n_per_mm: float = 0.0) -> bool:
        """Keep one palpation's reading; False when it carries no stiffness (nothing kept)."""
        if outcome not in OUTCOMES:
            raise ValueError(f"unknown palpation outcome {outcome!r}; expected one of {', '.join(OUTCOMES)}")
        kind = EXACT if outcome == "fit" else CENSORED.get(outcome)
        if kind is None or not _usable(stiffness_n_per_mm):
            return False
        sd = sd_n_per_mm if sd_n_per_mm is not None and math.isfinite(sd_n_per_mm) and sd_n_per_mm > 0 else 0.0
        self.xy = np.vstack([self.xy, np.asarray(xy, dtype=float).reshape(1, 2)])
        self.y = np.append(self.y, math.log(stiffness_n_per_mm))
        self.sd = np.append(self.sd, sd / stiffness_n_per_mm)
        self.kind = np.append(self.kind, kind)
        return True


def _usable(value) -> bool:
    return value is not None and math.isfinite(value) and value > 0
