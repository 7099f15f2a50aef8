"""How deep a lump lies, from how it is felt: a surrogate of the finite-element tissue.

A stiff body felt through the tissue above it is blurred by it: the deeper its top, the lower the contrast the
tip feels over it and the wider its edge for its size. So a lump's fitted profile (contrast a, size and edge
width: shapes.py's 75 % to 25 % width) carries its depth. The surrogate is linear in (log a, size, edge) and
log a × size, the size being the radius or an ellipse's minor semi-axis, fitted by least squares to the
simulator's own finite-element layer pressed over spheres of many radii, depths and contrasts in two layer
thicknesses (scripts/fit_depth_surrogate.py; its coefficients in depth_surrogate.json). Its sd is the fit's
residual, its error on bodies and layers it was not fitted on (a rod, an ellipsoid, a box, other
thicknesses), and the fitted profile's own uncertainty carried through.

Pressing deeper does not tell depth apart here: with the 2.5 mm tip the contact stops growing once the tip is
in (δ ≳ R_tip), and in a linear elastic layer the felt ratio over a body then stays what it was (measured: over
a 5 mm sphere its log changes by the same −0.2 from δ 2 to 4 mm whatever the depth from 0.5 to 8 mm); so the
ordinary press at the reference depth is read, and the lateral profile does the work.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

REFERENCE_DEPTH_MM = 2.0  # the stiffness readings' reference indentation (config stiffness.reference_depth_mm)
COEFFICIENTS = Path(__file__).with_name("depth_surrogate.json")


def _features(log_a: float, size_mm: float, edge_mm: float, tip_mm: float) -> np.ndarray:
    """Linear in log contrast, size and edge (tip radii), and the contrast's by the size: a fainter lump is
    deeper, more so the larger it is felt. A full quadratic fitted the spheres closer (0.52 against 0.56 mm)
    but read a rod felt wider than any sphere 10-15 mm deep; this form 6-8 mm, and the size is clamped."""
    size, edge = size_mm / tip_mm, edge_mm / tip_mm
    return np.array([1.0, log_a, size, edge, log_a * size])


@dataclass(frozen=True)
class Surrogate:
    tip_mm: float
    coefficients: tuple[float, ...]
    fit_sd_mm: float
    held_out_sd_mm: float = 0.0
    rows: int = 0
    ranges: dict = field(default_factory=dict)

    @classmethod
    def fit(cls, rows: list[dict], tip_mm: float) -> "Surrogate":
        """rows: contrast, radius_mm (the lump's size across its narrowest way), edge_mm, top_mm."""
        x = np.array([_features(math.log(r["contrast"]), r["radius_mm"], r["edge_mm"], tip_mm) for r in rows])
        y = np.array([r["top_mm"] / tip_mm for r in rows])  # in tip radii, as the features
        beta, *_ = np.linalg.lstsq(x, y, rcond=None)
        residual = (y - x @ beta) * tip_mm
        sd = math.sqrt(float(residual @ residual) / max(len(rows) - len(beta), 1))
        ranges = {key: [min(r[key] for r in rows), max(r[key] for r in rows)]
                  for key in ("contrast", "radius_mm", "edge_mm", "top_mm")}
        return cls(tip_mm, tuple(float(b) for b in beta), sd, 0.0, len(rows), ranges)

    def with_held_out_sd(self, sd_mm: float) -> "Surrogate":
        return replace(self, held_out_sd_mm=sd_mm)

    def top_mm(self, contrast: float, size_mm: float, edge_mm: float, clamped: bool = True) -> float:
        """The lump's top below the surface (mm, never above it). size: its radius, an ellipse's minor
        semi-axis (a rod's depth shows across it, not along it). Clamped: each input held within what was
        fitted on (a linear form extrapolates, but not without end)."""
        if clamped:
            contrast, size_mm, edge_mm = (self._within(key, value) for key, value in
                                          (("contrast", contrast), ("radius_mm", size_mm), ("edge_mm", edge_mm)))
        x = _features(math.log(max(contrast, 1e-6)), size_mm, edge_mm, self.tip_mm)
        return max(0.0, float(x @ np.asarray(self.coefficients)) * self.tip_mm)

    def _within(self, key: str, value: float) -> float:
        low, high = self.ranges.get(key, (-math.inf, math.inf))
        return min(max(value, low), high)

    def estimate(self, contrast: float, size_mm: float, edge_mm: float,
                 sds: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[float, float]:
        """(depth, sd): sds are those of log contrast, size and edge (mm), carried through one at a time. A
        lump outside the fitted ranges adds how far the unclamped form would have gone: extrapolation is a
        guess, and its sd says so."""
        top = self.top_mm(contrast, size_mm, edge_mm)
        spread = (self.top_mm(contrast, size_mm, edge_mm, clamped=False) - top) ** 2
        for i, sd in enumerate(sds):
            if not sd or not math.isfinite(sd):
                continue
            point = [math.log(max(contrast, 1e-6)), size_mm, edge_mm]
            point[i] += sd
            spread += (self.top_mm(math.exp(point[0]), point[1], point[2]) - top) ** 2
        return top, math.sqrt(self.fit_sd_mm**2 + self.held_out_sd_mm**2 + spread)

    def as_dict(self) -> dict:
        return {"tip_mm": self.tip_mm, "coefficients": list(self.coefficients), "fit_sd_mm": self.fit_sd_mm,
                "held_out_sd_mm": self.held_out_sd_mm, "rows": self.rows, "ranges": self.ranges}

    @classmethod
    def load(cls, path: Path = COEFFICIENTS) -> "Surrogate":
        data = json.loads(path.read_text())
        return cls(data["tip_mm"], tuple(data["coefficients"]), data["fit_sd_mm"], data["held_out_sd_mm"],
                   data["rows"], data["ranges"])


_loaded: Surrogate | None = None


def surrogate() -> Surrogate:
    global _loaded
    if _loaded is None:
        _loaded = Surrogate.load()
    return _loaded
