"""A 3-D scene's force–indentation table F(x, y, δ), built once by finite elements and read per physics step.

Building: one coarse P2-tetrahedra mesh of the layer with its inclusions, a margin past the palpable rectangle
(layer_mesh; fem.SurfaceCompliance, one factorisation), the surface compliance among the surface nodes a tip
can touch (block back-solves), then at every surface node of the rectangle (the table's lateral grid) the
frictionless sphere contact (contact.contact_forces_n) at each tabulated depth.
Reading (TableField): bilinear in x, y and a power law in δ between the tabulated depths, in plain Python.
The table is cached per scene's mechanical fields (cached_table).
"""
from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

FORMAT_VERSION = 6  # bump when the table's meaning or the mesh recipe changes: old cache files are ignored
DEPTHS_MM = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0)
ELEMENT_MM = 4.0  # lateral element edge: P2 nodes, and so the table's grid, every 2 mm
# The smallest tip the table resolves. Until the contact radius √(Rδ) spans the surface nodes' spacing the tip
# presses one node (_hertz_onset puts Hertz's δ^1.5 there, up to the first tabulated depth past s²/R), and that
# onset holds only while the tip is sunk well short of its equator: for R = 2 mm it ran to δ = 2 mm = R and met
# the mesh's flatter law there in a kink (exponent 1.5, then 0.9). From 2.5 mm (onset to 2 mm, 0.8 R) the two
# meet smoothly (within 2 % of Hertz at 0.5-3 mm on a 25 mm layer). A tip below 1 mm read 61-131 % over Hertz.
MIN_TIP_RADIUS_MM = 2.5
SURFACE_ELEMENT_MM = 2.0  # depth of the first element layer under the surface, growing x1.5 downward
MARGIN_MM = 10.0  # the layer meshed this far past each side of the palpable rectangle (layer_mesh)
MARGIN_GROWTH = 1.5  # the margin's elements growing outward by this factor
BLOCK_COLUMNS = 128  # right-hand sides per back-solve
CACHE_ENV = "PALPD_CACHE_DIR"
# The shipped 3-D scenes' tables, built by `make tables` (scripts/build_force_tables.py) and read before the
# user's cache: a first `make run` starts at once instead of after a minutes-long build.
SHIPPED_DIR = Path(__file__).parent / "tables"


@dataclass
class ForceTable:
    """Normal force (N) of the tip at lateral grid point (xs[i], ys[j]) pressed depths_mm[k] into the surface."""

    xs: np.ndarray
    ys: np.ndarray
    depths_mm: np.ndarray
    forces_n: np.ndarray  # (len(xs), len(ys), len(depths_mm))
    key: str = ""
    build_s: float = 0.0
    meta: dict = field(default_factory=dict)

    def save(self, path: Path) -> None:
        """Atomically: a reader sees the old file or the whole new one, never half of it."""
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = tempfile.NamedTemporaryFile(dir=path.parent, prefix=path.name + ".", suffix=".tmp", delete=False)
        try:
            with handle:
                np.savez_compressed(handle, xs=self.xs, ys=self.ys, depths_mm=self.depths_mm,
                                    forces_n=self.forces_n,
                                    key=np.array(self.key), version=np.array(FORMAT_VERSION),
                                    build_s=np.array(self.build_s))
            os.replace(handle.name, path)
        except BaseException:
            Path(handle.name).unlink(missing_ok=True)
            raise

    @classmethod
    def load(cls, path: Path, key: str) -> "ForceTable":
        """The table in path; ValueError if it is not a whole table for this key and format."""
        with np.load(path, allow_pickle=False) as data:
            if int(data["version"]) != FORMAT_VERSION or str(data["key"]) != key:
                raise ValueError("another format or scene")
            table = cls(data["xs"], data["ys"], data["depths_mm"], data["forces_n"], key, float(data["build_s"]))
        shape = (len(table.xs), len(table.ys), len(table.depths_mm))
        if table.forces_n.shape != shape or not np.all(np.isfinite(table.forces_n)) or table.forces_n.min() <= 0:
            raise ValueError("inconsistent arrays")
        return table


def modulus_field(scene):
    """f(points (3, ...) mm, z up from -thickness to 0) -> kPa: the layer's modulus, each inclusion's inside it."""
    background, bodies = scene.tissue.modulus_kpa, list(scene.inclusion)

    def modulus(points):
        e = np.full(points.shape[1:], float(background))
        for body in bodies:  # a later body wins where two overlap
            e[body.contains(points[0], points[1], -points[2])] = body.modulus_kpa
        return e

    return modulus


def layer_mesh(scene, element_mm: float = ELEMENT_MM, surface_element_mm: float = SURFACE_ELEMENT_MM):
    """The layer's node lines: uniform elements across the palpable rectangle and a margin past each side."""
    from drivers.sim.mechanics.fem import Grid, depth_lines

    w, h = scene.tissue.size_mm
    return Grid(_with_margin(w, element_mm), _with_margin(h, element_mm),
                depth_lines(scene.tissue.thickness_mm, surface_element_mm))


def _with_margin(width_mm: float, element_mm: float) -> np.ndarray:
    """Element edges across [-width/2, width/2], then MARGIN_MM more each side: one more element of the same
    size (a tip at the side presses nodes spaced as everywhere else: coarser ones there read it 6 % softer),
    then growing x1.5.

    Why a margin: the palpable rectangle is part of a larger layer. Sides on rollers alone are mirror planes,
    and a tip near one is pressed by its own mirror image too: a homogeneous 60 x 60 x 20 mm layer read 13 %
    softer in its corners than in its middle, a bowl the learner's background cannot draw (a scan of a deep
    sphere ended `undetermined`, missing its corner readings). With 4 + 6 mm of margin a 32 x 32 x 20 mm layer
    reads within 1.3 % of its middle everywhere, corners included."""
    n = max(1, round(width_mm / element_mm))
    inner = np.linspace(-width_mm / 2, width_mm / 2, n + 1)
    step, outer = inner[1] - inner[0], [width_mm / 2 + (inner[1] - inner[0])]
    while outer[-1] < width_mm / 2 + MARGIN_MM - 1e-9:
        step *= MARGIN_GROWTH
        outer.append(outer[-1] + step)
    outer = np.array(outer)
    return np.concatenate([-outer[::-1], inner, outer])


MAX_UNKNOWNS = 60_000  # paper-3d's 60 x 60 x 20 mm (with its margin) has 50 193 and builds in 1.5-5 minutes on 2 cores


def layer_compliance(scene, element_mm: float = ELEMENT_MM, surface_element_mm: float = SURFACE_ELEMENT_MM):
    from drivers.sim.mechanics.fem import SurfaceCompliance
    from drivers.sim.scene import SceneError

    grid = layer_mesh(scene, element_mm, surface_element_mm)
    unknowns = 3 * (2 * len(grid.xs) - 1) * (2 * len(grid.ys) - 1) * (2 * len(grid.zs) - 1)  # P2 nodes x 3
    if unknowns > MAX_UNKNOWNS:  # its factor would not fit in minutes or memory here: say so, not hang
        w, h = scene.tissue.size_mm
        raise SceneError(f"scene {scene.name!r}: a 3-D tissue {w:g} x {h:g} x {scene.tissue.thickness_mm:g} mm "
                         f"needs {unknowns} finite-element unknowns, more than the {MAX_UNKNOWNS} the simulator "
                         "builds (about 65 x 65 x 20 mm): make size_mm or thickness_mm smaller")
    # the outer sides on rollers (they slide but do not move out), past the margin (layer_mesh)
    return SurfaceCompliance(grid, modulus_field(scene), scene.tissue.poisson, roller_sides=True)


def surface_matrix(block, reach_mm: tuple[float, float], progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The surface compliance (mm per N, symmetric) among the surface nodes within reach_mm = (x, y) of the
    middle, and their (x, y): column j = displacements under 1 N at node j. One back-solve per such node:
    the margin's nodes are loaded by no tip, so they need none."""
    from tqdm import tqdm

    xy = block.surface_xy
    kept = np.flatnonzero((np.abs(xy[:, 0]) <= reach_mm[0] + 1e-9) & (np.abs(xy[:, 1]) <= reach_mm[1] + 1e-9))
    n = len(kept)
    matrix = np.empty((n, n))
    starts = range(0, n, BLOCK_COLUMNS)
    for start in tqdm(starts, desc="3-D tissue: surface compliance", unit="block", leave=False,
                      disable=None if progress else True):  # None: only on a terminal
        stop = min(n, start + BLOCK_COLUMNS)
        matrix[:, start:stop] = block.columns(kept[start:stop])[kept]
    return xy[kept], (matrix + matrix.T) / 2.0


def _reach_mm(scene) -> tuple[float, float]:
    """How far from the middle a tip on the palpable rectangle touches: its half-sizes plus the tip's radius."""
    w, h = scene.tissue.size_mm
    return w / 2 + scene.probe.tip_radius_mm, h / 2 + scene.probe.tip_radius_mm


def force_at(surface_xy, compliance, x_mm, y_mm, tip_radius_mm, depths_mm) -> list[float]:
    """Total normal force of the sphere whose lowest point is at (x, y), pressed each depth into the surface."""
    from drivers.sim.mechanics.contact import contact_forces_n, sphere_gap_mm

    r = np.hypot(surface_xy[:, 0] - x_mm, surface_xy[:, 1] - y_mm)
    near = np.flatnonzero(r < tip_radius_mm)
    sub = compliance[np.ix_(near, near)]
    gap = sphere_gap_mm(r[near], tip_radius_mm)
    return [float(contact_forces_n(sub, gap, d).sum()) for d in depths_mm]


def build_table(scene, depths_mm=DEPTHS_MM, element_mm: float = ELEMENT_MM,
                surface_element_mm: float = SURFACE_ELEMENT_MM, progress: bool = False) -> ForceTable:
    """F(x, y, δ) at every surface node of the palpable rectangle (the scene's own frame, before its rotation)."""
    import time

    started = time.monotonic()
    block = layer_compliance(scene, element_mm, surface_element_mm)
    surface_xy, compliance = surface_matrix(block, _reach_mm(scene), progress)
    table = tabulate(scene, surface_xy, compliance, depths_mm, progress)
    table.key = table_key(scene, depths_mm, element_mm, surface_element_mm)
    table.build_s = time.monotonic() - started
    return table


def tabulate(scene, surface_xy, compliance, depths_mm=DEPTHS_MM, progress: bool = False) -> ForceTable:
    """The contact at every surface node of the palpable rectangle, given the surface compliance around it."""
    from tqdm import tqdm

    tip = scene.probe.tip_radius_mm
    sizes = scene.tissue.size_mm
    xs, ys = (_within(np.unique(np.round(surface_xy[:, axis], 9)), sizes[axis] / 2) for axis in (0, 1))
    forces = np.empty((len(xs), len(ys), len(depths_mm)))
    points = [(i, j) for i in range(len(xs)) for j in range(len(ys))]
    for i, j in tqdm(points, desc="3-D tissue: force table", unit="point", leave=False,
                     disable=None if progress else True):
        forces[i, j] = force_at(surface_xy, compliance, xs[i], ys[j], tip, depths_mm)
    depths = np.asarray(depths_mm, float)
    return ForceTable(xs, ys, depths, _hertz_onset(_smoothed(forces), depths, tip, float(xs[1] - xs[0])))


def _hertz_onset(forces: np.ndarray, depths_mm: np.ndarray, tip_radius_mm: float, node_mm: float) -> np.ndarray:
    """The force below the first depth whose contact the mesh resolves, as Hertz's δ^1.5 scaled to the force there.

    Until the tip's contact radius √(Rδ) spans the surface nodes' spacing, the tip presses one node: a point load,
    its force linear in δ (a 2.5 mm tip: 0.5 and 1 mm read 1.64 and 3.28 N on a stiff layer, then 12.2 N at 2 mm,
    a kink no tissue has, and 44 % over Hertz at 0.5 mm on a 25 mm layer). From that depth on, the mesh's force is
    Hertz's within a few per cent (tests/test_force_table.py), and a sphere's contact grows as δ^1.5 from its
    onset, whatever lies below: what an inclusion changes is how much force, which the resolved depth carries."""
    resolved = int(np.searchsorted(depths_mm, node_mm**2 / tip_radius_mm - 1e-9))
    if 0 < resolved < len(depths_mm):
        forces = forces.copy()
        forces[..., :resolved] = forces[..., resolved:resolved + 1] * (depths_mm[:resolved] / depths_mm[resolved]) ** 1.5
    return forces


def _smoothed(forces: np.ndarray) -> np.ndarray:
    """Each grid value as 1/4, 1/2, 1/4 of its neighbours along x, then y (mirrored at the edges, as the layer).

    A point load on a quadratic element's corner node and on its mid-side node meet different compliances: the
    raw table alternates node to node, ±15 % on a homogeneous layer (0.135, 0.156, 0.185 N at 2 mm), a ripple of
    the mesh, not of the tissue. This filter removes exactly that period-2 pattern and blurs by one node."""
    for axis in (0, 1):
        if forces.shape[axis] < 3:
            continue
        padded = np.pad(forces, [(1, 1) if a == axis else (0, 0) for a in range(3)], mode="reflect")
        lo, mid, hi = (np.take(padded, range(k, k + forces.shape[axis]), axis=axis) for k in (0, 1, 2))
        forces = 0.25 * lo + 0.5 * mid + 0.25 * hi
    return forces


def _within(lines: np.ndarray, half_mm: float) -> np.ndarray:
    """The node lines on the palpable rectangle (the margin's lie past it)."""
    return lines[np.abs(lines) <= half_mm + 1e-9]


def table_key(scene, depths_mm=DEPTHS_MM, element_mm=ELEMENT_MM, surface_element_mm=SURFACE_ELEMENT_MM) -> str:
    """Hash of everything the table depends on: the layer, its inclusions, the tip, the mesh and the format."""
    tissue = scene.tissue
    fields = {
        "version": FORMAT_VERSION,
        "size_mm": list(tissue.size_mm), "thickness_mm": tissue.thickness_mm, "modulus_kpa": tissue.modulus_kpa,
        "poisson": tissue.poisson, "inclusions": [body.model_dump() for body in scene.inclusion],
        "tip_radius_mm": scene.probe.tip_radius_mm, "depths_mm": list(depths_mm), "element_mm": element_mm,
        "surface_element_mm": surface_element_mm,
    }
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()


def cache_dir() -> Path:
    """$PALPD_CACHE_DIR, else $XDG_CACHE_HOME/palpd, else ~/.cache/palpd."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    if os.environ.get("XDG_CACHE_HOME"):
        return Path(os.environ["XDG_CACHE_HOME"]) / "palpd"
    return Path.home() / ".cache" / "palpd"


def table_file_name(key: str) -> str:
    return f"force-table-{key[:24]}.npz"


def cached_table(scene, progress: bool = True) -> ForceTable:
    """The scene's table as shipped or cached, else built (and cached: a cache that cannot be written only logs)."""
    key = table_key(scene)
    name = table_file_name(key)
    for path in (SHIPPED_DIR / name, cache_dir() / name):
        if path.exists():
            try:
                return ForceTable.load(path, key)
            except Exception as exc:  # a truncated or foreign file: numpy raises many kinds
                log.warning("3-D tissue table %s unreadable (%s): rebuilding it", path, type(exc).__name__)
    path = cache_dir() / name
    table = build_table(scene, progress=progress)
    try:
        table.save(path)
    except OSError as exc:
        log.warning("3-D tissue table not cached in %s: %s", path.parent, exc.strerror or exc)
    return table


class TableField:
    """The tip's normal force at (x, y) in the scene's frame, depth δ, rate, read from a ForceTable per tick."""

    def __init__(self, table: ForceTable, damping_n_s_per_mm: float = 0.0) -> None:
        self._xs, self._ys = table.xs.tolist(), table.ys.tolist()
        self._x0, self._y0 = self._xs[0], self._ys[0]
        self._dx = (self._xs[-1] - self._x0) / (len(self._xs) - 1)
        self._dy = (self._ys[-1] - self._y0) / (len(self._ys) - 1)
        self._depths = table.depths_mm.tolist()
        log_f = np.log(table.forces_n)
        log_d = np.log(table.depths_mm)
        # exponent of each depth interval (the last one also past the deepest depth, the first one below the first)
        self._exponents = (np.diff(log_f, axis=2) / np.diff(log_d)).tolist()
        self._forces = table.forces_n.tolist()
        self._damping = damping_n_s_per_mm
        self._nx, self._ny = len(self._xs) - 1.000001, len(self._ys) - 1.000001
        self._inner_depths = self._depths[1:-1]  # the first k with depth < these[k] is the interval
        self.table = table

    def elastic_n(self, x_mm: float, y_mm: float, depth_mm: float) -> float:
        """Twice per servo tick: written out, the same sums as a loop over the four corners."""
        if depth_mm <= 0.0:
            return 0.0
        fx = min(max((x_mm - self._x0) / self._dx, 0.0), self._nx)
        fy = min(max((y_mm - self._y0) / self._dy, 0.0), self._ny)
        i, j = int(fx), int(fy)
        ax, ay = fx - i, fy - j
        k = 0
        for bound in self._inner_depths:
            if depth_mm < bound:
                break
            k += 1
        scale = math.log(depth_mm / self._depths[k])
        exp = math.exp
        row, row1 = self._forces[i], self._forces[i + 1]
        erow, erow1 = self._exponents[i], self._exponents[i + 1]
        total = 0.0
        w = (1 - ax) * (1 - ay)
        if w:
            total += w * row[j][k] * exp(erow[j][k] * scale)
        w = ax * (1 - ay)
        if w:
            total += w * row1[j][k] * exp(erow1[j][k] * scale)
        w = (1 - ax) * ay
        if w:
            total += w * row[j + 1][k] * exp(erow[j + 1][k] * scale)
        w = ax * ay
        if w:
            total += w * row1[j + 1][k] * exp(erow1[j + 1][k] * scale)
        return total

    def force_n(self, x_mm: float, y_mm: float, depth_mm: float, rate_mm_s: float = 0.0) -> float:
        """Normal force (N), never pulling; a damping term proportional to depth and rate as Hunt–Crossley's."""
        elastic = self.elastic_n(x_mm, y_mm, depth_mm)
        if not self._damping or depth_mm <= 0.0:
            return elastic
        return max(0.0, elastic + self._damping * depth_mm * rate_mm_s)

    def k_at(self, x_mm: float, y_mm: float) -> float:
        """Secant stiffness at 1 mm (N/mm), the felt stiffness a 2-D scene's field gives."""
        return self.elastic_n(x_mm, y_mm, 1.0)
