"""3-D scene parts: inclusions (elastic bodies inside the layer) and the probe tip, as DESIGN.md's scene format.

An inclusion's centre is (x, y, depth of its centre below the surface) in mm; angle_deg turns it about the
tissue's normal. Its footprint (truth for the learner) is the largest horizontal cross-section: its outline, and
the radius of a circle of the same area; its depth is where its top lies below the surface.
"""
from __future__ import annotations

import math
from typing import Annotated, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, model_validator

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
Modulus = Annotated[float, Field(gt=0, le=1e6, allow_inf_nan=False)]  # kPa: 1 GPa is as hard as a tip meets

# which size field each shape takes; the others are refused so that a slip (a box's radius) is not ignored
SHAPE_FIELDS = {"sphere": ("radius_mm",), "ellipsoid": ("semi_axes_mm",),
                "cylinder": ("radius_mm", "length_mm"), "box": ("size_mm",)}
SIZE_FIELDS = ("radius_mm", "semi_axes_mm", "length_mm", "size_mm")


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Probe(Strict):
    tip_radius_mm: Annotated[float, Field(gt=0, le=20, allow_inf_nan=False)] = 2.5


class Inclusion(Strict):
    shape: Literal["sphere", "ellipsoid", "cylinder", "box"]
    center_mm: tuple[FiniteFloat, FiniteFloat, FiniteFloat]
    modulus_kpa: Modulus
    radius_mm: Optional[PositiveFloat] = None
    semi_axes_mm: Optional[tuple[PositiveFloat, PositiveFloat, PositiveFloat]] = None
    length_mm: Optional[PositiveFloat] = None
    size_mm: Optional[tuple[PositiveFloat, PositiveFloat, PositiveFloat]] = None
    angle_deg: FiniteFloat = 0.0

    @model_validator(mode="after")
    def _sizes_fit_the_shape(self):
        wanted = SHAPE_FIELDS[self.shape]
        missing = [name for name in wanted if getattr(self, name) is None]
        if missing:
            raise ValueError(f"a {self.shape} needs {' and '.join(missing)}")
        extra = [name for name in SIZE_FIELDS if name not in wanted and getattr(self, name) is not None]
        if extra:
            raise ValueError(f"a {self.shape} takes {' and '.join(wanted)}, not {' or '.join(extra)}")
        if self.angle_deg and self.shape == "sphere":
            raise ValueError("a sphere takes no angle_deg")
        return self

    def half_height_mm(self) -> float:
        if self.shape == "ellipsoid":
            return self.semi_axes_mm[2]
        if self.shape == "box":
            return self.size_mm[2] / 2.0
        return self.radius_mm

    def top_depth_mm(self) -> float:
        return self.center_mm[2] - self.half_height_mm()

    def bottom_depth_mm(self) -> float:
        return self.center_mm[2] + self.half_height_mm()

    def footprint_half_extent_mm(self) -> float:
        """Half the widest horizontal reach from the centre (for 'is it on the tissue')."""
        if self.shape == "sphere":
            return self.radius_mm
        if self.shape == "ellipsoid":
            return max(self.semi_axes_mm[:2])
        if self.shape == "box":
            return math.hypot(*self.size_mm[:2]) / 2.0
        return math.hypot(self.length_mm / 2.0, self.radius_mm)

    def equivalent_radius_mm(self) -> float:
        """Radius of the circle with the area of the largest horizontal cross-section."""
        if self.shape == "sphere":
            return self.radius_mm
        if self.shape == "ellipsoid":
            return math.sqrt(self.semi_axes_mm[0] * self.semi_axes_mm[1])
        if self.shape == "box":
            return math.sqrt(self.size_mm[0] * self.size_mm[1] / math.pi)
        return math.sqrt(2.0 * self.radius_mm * self.length_mm / math.pi)

    def footprint_mm(self, vertices: int = 96) -> list[tuple[float, float]]:
        """The outline of the largest horizontal cross-section, (x, y) in mm about the tissue's centre: what a
        reading from above can find of the body (a rod's rectangle, an ellipsoid's ellipse), so that a found
        outline is scored against it rather than against a circle of its area (a 15.7 x 10 mm rod found as a
        16.8 x 10.1 mm ellipse scored IoU 0.70 against the circle, 0.8 against the rod)."""
        if self.shape in ("sphere", "ellipsoid"):
            a, b = (self.radius_mm, self.radius_mm) if self.shape == "sphere" else self.semi_axes_mm[:2]
            turns = [2.0 * math.pi * i / vertices for i in range(vertices)]
            local = [(a * math.cos(t), b * math.sin(t)) for t in turns]
        else:
            a, b = (self.size_mm[0] / 2.0, self.size_mm[1] / 2.0) if self.shape == "box" else \
                (self.length_mm / 2.0, self.radius_mm)
            local = [(a, b), (-a, b), (-a, -b), (a, -b)]
        turn = math.radians(self.angle_deg)
        c, s = math.cos(turn), math.sin(turn)
        cx, cy, _ = self.center_mm
        return [(cx + c * u - s * v, cy + s * u + c * v) for u, v in local]

    def contains(self, x, y, depth):
        """Which points (arrays, mm; depth below the surface) lie inside the body."""
        import numpy as np

        cx, cy, cd = self.center_mm
        turn = math.radians(self.angle_deg)
        dx, dy, dz = x - cx, y - cy, depth - cd
        u = dx * math.cos(turn) + dy * math.sin(turn)  # along the body's own axis
        v = -dx * math.sin(turn) + dy * math.cos(turn)
        if self.shape == "sphere":
            return dx * dx + dy * dy + dz * dz <= self.radius_mm ** 2
        if self.shape == "ellipsoid":
            a, b, c = self.semi_axes_mm
            return (u / a) ** 2 + (v / b) ** 2 + (dz / c) ** 2 <= 1.0
        if self.shape == "box":
            a, b, c = self.size_mm
            return (np.abs(u) <= a / 2) & (np.abs(v) <= b / 2) & (np.abs(dz) <= c / 2)
        return (np.abs(u) <= self.length_mm / 2) & (v * v + dz * dz <= self.radius_mm ** 2)


def check_inclusions_fit(inclusions, size_mm, thickness_mm) -> None:
    """Each inclusion lies under the palpable rectangle, below the surface and above the rigid base."""
    half_w, half_h = size_mm[0] / 2, size_mm[1] / 2
    for i, body in enumerate(inclusions):
        cx, cy, _ = body.center_mm
        if abs(cx) > half_w or abs(cy) > half_h:
            raise ValueError(f"inclusion {i}: its centre ({cx:g}, {cy:g}) mm lies off the {size_mm[0]:g} x "
                             f"{size_mm[1]:g} mm tissue")
        if body.top_depth_mm() < 0.0:
            raise ValueError(f"inclusion {i}: its top is {-body.top_depth_mm():g} mm above the surface "
                             "(center_mm's third value is the depth of its centre below the surface)")
        if body.bottom_depth_mm() > thickness_mm:
            raise ValueError(f"inclusion {i}: it reaches {body.bottom_depth_mm():g} mm deep, below the "
                             f"{thickness_mm:g} mm layer")
