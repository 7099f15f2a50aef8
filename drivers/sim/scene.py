"""Scene files: the simulated bench (tissue, lumps, sensor) in the TOML format DESIGN.md fixes."""
from __future__ import annotations

import csv
import math
import statistics
from pathlib import Path
from typing import Annotated, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from drivers.errors import DriverInitializationError, describe_validation_error
from drivers.phantom.model import SPAN_MM
from drivers.sim.bodies import Inclusion, Probe, check_inclusions_fit
from drivers.tomlfile import read_toml

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
# A side no arm could reach across is a slip of units (metres, micrometres), refused before anything is planned on it.
TissueSide = Annotated[float, Field(gt=0, le=SPAN_MM, allow_inf_nan=False)]


class SceneError(DriverInitializationError):
    """A scene file is missing, unreadable or invalid; the message is one line naming the file."""

    exit_code = 78  # sysexits EX_CONFIG, as for a bad config file: a bad scene is bad configuration


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Tissue(_Strict):
    size_mm: tuple[TissueSide, TissueSide] = (60.0, 60.0)  # the palpable rectangle, centred on the tissue origin
    stiffness_n_per_mm: PositiveFloat = 0.12  # Hunt–Crossley k of the background tissue
    exponent: Annotated[float, Field(ge=0.5, le=3.0)] = 1.0  # Hunt–Crossley n (1: a linear spring)
    damping_n_s_per_mm: NonNegativeFloat = 0.0  # Hunt–Crossley b
    friction: Annotated[float, Field(ge=0.0, le=2.0)] = 0.0  # sliding (Coulomb) friction: lateral / normal force
    # the felt field from measured samples, a CSV x_mm,y_mm,stiffness_n_per_mm (path relative to the scene)
    map: Optional[str] = None
    # the map holds a probe's raw readings instead (a CSV x_mm,y_mm,reading, every press to one depth): this is
    # the probe's value at no force, and each reading is felt as stiffness_n_per_mm × (reading − baseline) /
    # (median reading − baseline) (stiffness_from_readings)
    map_baseline: Optional[FiniteFloat] = None
    thickness_mm: Optional[Annotated[float, Field(gt=0, le=200, allow_inf_nan=False)]] = None  # makes it 3-D
    modulus_kpa: Optional[Annotated[float, Field(gt=0, le=1e6, allow_inf_nan=False)]] = None
    # 0.5 itself is incompressible, which a displacement formulation cannot compute
    poisson: Annotated[float, Field(ge=0.0, le=0.495, allow_inf_nan=False)] = 0.48

    @property
    def is_3d(self) -> bool:
        return self.thickness_mm is not None


class Lump(_Strict):
    center_mm: tuple[FiniteFloat, FiniteFloat]  # tissue frame
    radius_mm: PositiveFloat  # the felt stiffness is halfway between background and lump exactly here
    depth_mm: NonNegativeFloat = 0.0  # below the surface; deeper lumps have a wider, softer edge
    stiffness_n_per_mm: PositiveFloat  # the effective k felt palpating straight above the centre


class Sensor(_Strict):
    noise_n: NonNegativeFloat = 0.01  # force noise, standard deviation
    tilt: bool = False  # the sensor's axes tilt with the arm's configuration (the seed paper's error source)
    bias_n: NonNegativeFloat = 0.05  # magnitude of the unknown offset per axis, tared away by palpd


class Placement(_Strict):
    origin_mm: tuple[FiniteFloat, FiniteFloat, FiniteFloat] = (0.0, -60.0, 0.0)  # tissue origin, robot frame
    rotation_deg: FiniteFloat = 0.0  # tissue turned about its normal, as the paper's test sets were


FaultKind = Literal["sensor_frozen", "sensor_drift", "nan_samples", "encoder_jump", "amplifier_fault"]


class FaultAt(_Strict):
    """A fault the simulated bench develops at_s seconds after it starts (drivers.sim.faults.FAULT_KINDS)."""

    at_s: NonNegativeFloat = 0.0
    value: Optional[FiniteFloat] = None  # sensor_drift: N/s along the sensor's z; encoder_jump: counts on joint 2


class Scene(_Strict):
    name: Annotated[str, Field(min_length=1)]
    seed: Annotated[int, Field(ge=0)] = 0  # the simulator's noise
    tissue: Tissue = Tissue()
    lump: list[Lump] = []
    sensor: Sensor = Sensor()
    placement: Placement = Placement()
    faults: dict[FaultKind, FaultAt] = {}  # [faults] sensor_drift = {at_s = 5.0, value = -0.5}
    inclusion: list[Inclusion] = []  # 3-D scenes: elastic bodies inside the layer
    probe: Probe = Probe()

    @model_validator(mode="after")
    def _one_kind_of_tissue(self):
        tissue, given = self.tissue, self.tissue.model_fields_set
        if tissue.map_baseline is not None and tissue.map is None:
            raise ValueError("tissue.map_baseline reads a map of raw readings: give tissue.map too")
        if not tissue.is_3d:
            for name in ("modulus_kpa", "poisson"):
                if name in given:
                    raise ValueError(f"tissue.{name} is for a 3-D tissue: give tissue.thickness_mm too")
            if self.inclusion:
                raise ValueError("[[inclusion]] bodies need a 3-D tissue: give tissue.thickness_mm "
                                 "(a 2-D scene's lumps are [[lump]])")
            return self
        if tissue.modulus_kpa is None:
            raise ValueError("a 3-D tissue (tissue.thickness_mm) needs tissue.modulus_kpa")
        mixed = [name for name in ("stiffness_n_per_mm", "exponent", "damping_n_s_per_mm", "map", "map_baseline")
                 if name in given]
        if mixed or self.lump:
            what = ", ".join(f"tissue.{n}" for n in mixed) or "[[lump]]"
            raise ValueError(f"{what} belong to a 2-D scene; a 3-D tissue is set by thickness_mm, modulus_kpa "
                             "and poisson, its lumps are [[inclusion]] bodies")
        check_inclusions_fit(self.inclusion, tissue.size_mm, tissue.thickness_mm)
        from drivers.sim.mechanics.table import MIN_TIP_RADIUS_MM

        if self.probe.tip_radius_mm < MIN_TIP_RADIUS_MM:
            raise ValueError(f"probe.tip_radius_mm {self.probe.tip_radius_mm:g} is below the {MIN_TIP_RADIUS_MM:g} mm "
                             "the 3-D simulator resolves (its surface nodes are 2 mm apart: a smaller tip's "
                             "contact is not resolved until it is sunk near its equator)")
        return self

    @model_validator(mode="after")
    def _lumps_touch_the_tissue(self):
        half_w, half_h = self.tissue.size_mm[0] / 2, self.tissue.size_mm[1] / 2
        for i, lump in enumerate(self.lump):
            cx, cy = lump.center_mm
            gap = math.hypot(max(abs(cx) - half_w, 0.0), max(abs(cy) - half_h, 0.0))
            if gap >= lump.radius_mm:
                raise ValueError(f"lump {i} at {lump.center_mm} mm lies wholly outside the {self.tissue.size_mm} mm tissue")
        return self


def load_scene(path: str | Path) -> Scene:
    path = Path(path)
    data = read_toml(path, "scene file", SceneError)
    try:
        scene = Scene.model_validate(data)
    except ValidationError as exc:
        raise SceneError(describe_validation_error(str(path), exc)) from None
    if scene.tissue.map is not None:
        map_path = path.parent / scene.tissue.map
        scene = scene.model_copy(update={"tissue": scene.tissue.model_copy(update={"map": str(map_path)})})
        rows = map_rows(scene.tissue)  # validated now, so a bad map fails before the robot moves
        _check_map_covers_tissue(map_path, rows, scene.tissue.size_mm)
    return scene


def map_rows(tissue: Tissue) -> list[tuple[float, float, float]]:
    """The tissue's measured map as rows (x_mm, y_mm, stiffness_n_per_mm): as given, or felt from raw readings
    (tissue.map_baseline)."""
    return load_stiffness_map(tissue.map, tissue.map_baseline, tissue.stiffness_n_per_mm)


def load_stiffness_map(path: str | Path, baseline: float | None = None,
                       tissue_n_per_mm: float = 0.12) -> list[tuple[float, float, float]]:
    """Rows (x_mm, y_mm, stiffness_n_per_mm) of a measured map CSV; with a baseline, of a CSV of raw readings
    (x_mm, y_mm, reading), felt as stiffness by stiffness_from_readings."""
    path = Path(path)
    value = "stiffness_n_per_mm" if baseline is None else "reading"
    try:
        # utf-8-sig: a spreadsheet's CSV export starts with a byte-order mark, which would hide the first column
        with path.open(newline="", encoding="utf-8-sig") as handle:
            reader = csv.DictReader(handle)
            reader.fieldnames = [name.strip() for name in reader.fieldnames or []]
            missing = {"x_mm", "y_mm", value} - set(reader.fieldnames or [])
            if missing:
                raise SceneError(f"{path}: missing column(s) {', '.join(sorted(missing))} "
                                 f"({_what_the_header_says(reader.fieldnames, value)})")
            # reader.line_num, not a count of rows: DictReader skips blank lines, and a line named must be the file's
            numbered = [(reader.line_num, _map_row(path, reader.line_num, row, value)) for row in reader]
            lines, rows = [n for n, _ in numbered], [r for _, r in numbered]
    except OSError as exc:
        raise SceneError(f"{path}: cannot read stiffness map: {exc.strerror}") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise SceneError(f"{path}: not a CSV text file ({type(exc).__name__})") from None
    if len(rows) < 4:
        raise SceneError(f"{path}: a stiffness map needs at least 4 points, found {len(rows)}")
    if _on_one_line(rows):
        raise SceneError(f"{path}: the map's points lie on one line; they must spread over the tissue")
    if baseline is None:
        return rows
    try:
        felt = stiffness_from_readings([r[2] for r in rows], baseline, tissue_n_per_mm)
    except ValueError as exc:
        # which reading: one press that never touched (a real dVRK file starts with one) is the usual cause,
        # and the user's fix is to drop that line, not to move the baseline under it
        lowest = min(range(len(rows)), key=lambda i: rows[i][2])
        x, y, _ = rows[lowest]
        raise SceneError(f"{path}: tissue.map_baseline: {exc}; the lowest is on line {lines[lowest]} "
                         f"(x {x:g}, y {y:g} mm)") from None
    return [(x, y, k) for (x, y, _), k in zip(rows, felt)]


def _what_the_header_says(fieldnames: list[str], value: str) -> str:
    """What the first line holds instead: a semicolon export, numbers with no header, nothing at all; or the
    other kind of map (raw readings without tissue.map_baseline, or stiffness with it)."""
    if fieldnames and value == "stiffness_n_per_mm" and "reading" in fieldnames:
        return "it holds raw readings: set tissue.map_baseline to the probe's value at no force"
    if fieldnames and value == "reading" and "stiffness_n_per_mm" in fieldnames:
        return "it holds stiffness already: leave tissue.map_baseline out"
    found = f"its first line reads {','.join(fieldnames)[:60]!r}" if fieldnames else "it is empty"
    return f"{found}; the map is comma-separated with the header x_mm,y_mm,{value}"


def stiffness_from_readings(readings, baseline: float, tissue_n_per_mm: float) -> list[float]:
    """The felt stiffness (N/mm) of raw readings, every press to one depth: there the force is the stiffness
    times that depth, and a raw reading is that force (in the probe's units) plus the probe's value at no
    force, the baseline. So stiffness is in proportion to reading − baseline; the depth and the units are
    not in the data, so the scale is set by the tissue: the median reading is felt as `tissue_n_per_mm`.
    Each reading is kept as read, its scatter included. ValueError if a reading is at or under the baseline
    (no force: no stiffness to feel)."""
    lowest = min(readings)
    if baseline >= lowest:
        under = sum(reading <= baseline for reading in readings)
        raise ValueError(f"the baseline {baseline:g} is not below the smallest reading {lowest:g} ({under} of "
                         f"{len(readings)} readings at or under it; the baseline is the probe's value at no force, "
                         f"and every press pushed harder: a reading under it is a press that never touched)")
    scale = tissue_n_per_mm / (statistics.median(readings) - baseline)
    return [scale * (reading - baseline) for reading in readings]


MIN_MAP_COVER = 0.5  # of the tissue's area: a map over less is most likely in another frame or unit


def _check_map_covers_tissue(path: Path, rows: list[tuple[float, float, float]], size_mm) -> None:
    """The map's extent overlaps at least MIN_MAP_COVER of the tissue, which is centred on (0, 0) in mm: a grid
    recorded from its corner (0..60 mm) or in metres would otherwise be stretched from its edge values over
    the rest of the tissue, a scene nobody measured."""
    xs, ys = [r[0] for r in rows], [r[1] for r in rows]
    half_w, half_h = size_mm[0] / 2.0, size_mm[1] / 2.0
    overlap_w = max(0.0, min(max(xs), half_w) - max(min(xs), -half_w))
    overlap_h = max(0.0, min(max(ys), half_h) - max(min(ys), -half_h))
    cover = overlap_w * overlap_h / (size_mm[0] * size_mm[1])
    if cover < MIN_MAP_COVER:
        raise SceneError(f"{path}: the map spans x {min(xs):g} to {max(xs):g}, y {min(ys):g} to {max(ys):g} mm, "
                         f"{100.0 * cover:.0f} % of the tissue (x within ±{half_w:g}, y within ±{half_h:g} mm, "
                         f"centred on 0, 0): shift its points to the tissue's frame, in mm, or set [tissue] size_mm")


def _on_one_line(rows: list[tuple[float, float, float]]) -> bool:
    """No three points of the map span an area (interpolating over the tissue needs a triangle)."""
    x0, y0, _ = rows[0]
    far = max(rows, key=lambda r: math.hypot(r[0] - x0, r[1] - y0))
    dx, dy = far[0] - x0, far[1] - y0
    length = math.hypot(dx, dy)
    if length == 0.0:
        return True
    # each point's distance from the line through the first point and the one farthest from it
    return all(abs(dx * (y - y0) - dy * (x - x0)) <= 1e-9 * length * length for x, y, _ in rows)


def _map_row(path: Path, line: int, row: dict, value: str) -> tuple[float, float, float]:
    try:
        x, y, k = (float(row[c]) for c in ("x_mm", "y_mm", value))
    except (TypeError, ValueError):
        raise SceneError(f"{path}:{line}: x_mm, y_mm and {value} must be numbers") from None
    if not all(map(math.isfinite, (x, y, k))) or (k <= 0 and value == "stiffness_n_per_mm"):
        raise SceneError(f"{path}:{line}: values must be finite and the stiffness positive")
    return x, y, k


def truth_lumps(scene: Scene) -> list[dict]:
    """The scene's lumps (or a 3-D scene's inclusions, as their footprints) as placed on the bench (after its rotation), in the tissue frame: those stiffer than
    the tissue (an inclusion as soft or softer, a cyst or fat, is tissue to palpate, not a lump to find)."""
    from drivers.geometry import rotate_xy

    if scene.tissue.is_3d:
        return _truth_inclusions(scene)
    return [
        {
            "center_mm": list(rotate_xy(*lump.center_mm, scene.placement.rotation_deg)),
            "radius_mm": lump.radius_mm,
            "depth_mm": lump.depth_mm,
            "stiffness_n_per_mm": lump.stiffness_n_per_mm,
        }
        for lump in scene.lump
        if lump.stiffness_n_per_mm > scene.tissue.stiffness_n_per_mm
    ]


def _truth_inclusions(scene: Scene) -> list[dict]:
    """Each inclusion stiffer than the layer: its centre, the outline of its widest horizontal cross-section
    (boundary_mm) and the radius of a circle as large, and depth_mm, where its top lies below the surface."""
    from drivers.geometry import rotate_xy

    turn = scene.placement.rotation_deg
    return [
        {
            "center_mm": list(rotate_xy(body.center_mm[0], body.center_mm[1], turn)),
            "radius_mm": body.equivalent_radius_mm(),
            "boundary_mm": [[round(v, 4) for v in rotate_xy(x, y, turn)] for x, y in body.footprint_mm()],
            "depth_mm": body.top_depth_mm(),
            "modulus_kpa": body.modulus_kpa,
            "shape": body.shape,
        }
        for body in scene.inclusion
        if body.modulus_kpa > scene.tissue.modulus_kpa
    ]
