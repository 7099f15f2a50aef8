"""The elastic layer by finite elements (scikit-fem), condensed onto its surface.

Quadratic tetrahedra (10 nodes): linear elements lock as Poisson's ratio nears 0.5 and read a near-incompressible
tissue far too stiff; quadratic ones do far less (the validation checks it). Not hexahedra of 27 nodes: scikit-fem
evaluates the form once per pair of an element's basis functions, 6 561 pairs against 900, and assembly was
~50 ms per hex27 element here.
The layer is bonded to a rigid base (every displacement zero at z = -h), its sides and top are free. The surface
compliance is the vertical displacement of surface nodes under a unit vertical load at one of them: one back-solve
of the factorised stiffness per loaded node (Green's functions, James & Pai 1999).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Grid:
    """Tensor-product node lines of the mesh (mm): xs, ys laterally, zs from -thickness up to 0 (the surface)."""

    xs: np.ndarray
    ys: np.ndarray
    zs: np.ndarray


def graded(lo: float, hi: float, fine_mm: float, fine_half_mm: float, centre: float = 0.0, growth: float = 1.5):
    """Element edges from lo to hi: fine_mm within fine_half_mm of centre, then growing geometrically outward."""
    inner = np.arange(max(lo, centre - fine_half_mm), min(hi, centre + fine_half_mm) + 1e-9, fine_mm)
    right, step, x = [], fine_mm, inner[-1]
    while x < hi - 1e-9:
        step *= growth
        x = min(hi, x + step) if hi - (x + step) > 0.5 * step * growth else hi
        right.append(x)
    left, step, x = [], fine_mm, inner[0]
    while x > lo + 1e-9:
        step *= growth
        x = max(lo, x - step) if (x - step) - lo > 0.5 * step * growth else lo
        left.append(x)
    return np.unique(np.concatenate([left[::-1], inner, right]))


def depth_lines(thickness_mm: float, fine_mm: float, growth: float = 1.5) -> np.ndarray:
    """Element edges from the base (-thickness) to the surface (0), fine under the surface."""
    edges, step, z = [0.0], fine_mm, 0.0
    while z > -thickness_mm + 1e-9:
        z = max(-thickness_mm, z - step)
        if z - -thickness_mm < 0.5 * step:
            z = -thickness_mm
        edges.append(z)
        step *= growth
    return np.array(sorted(edges))


# A hexahedron's corners by their offsets along (x, y, z), numbered as scikit-fem's MeshTet.init_tensor numbers
# them, and its split into six tetrahedra around the diagonal from corner 0 to corner 7 (Kuhn's).
CORNER_OFFSETS = ((0, 0, 0), (0, 1, 0), (1, 0, 0), (0, 0, 1), (1, 1, 0), (0, 1, 1), (1, 0, 1), (1, 1, 1))
KUHN_TETRAHEDRA = ((0, 1, 5, 7), (0, 1, 4, 7), (0, 2, 4, 7), (0, 3, 5, 7), (0, 2, 6, 7), (0, 3, 6, 7))


def mirrored_tensor_mesh(grid: Grid):
    """Tetrahedra on the grid's hexahedra, each split along its diagonal, mirrored in every other hexahedron
    along each axis: the mesh is then its own mirror image about every element face.

    scikit-fem's MeshTet.init_tensor splits every hexahedron along the same diagonal, towards +x +y +z: the layer
    felt that direction stiffer, and a sphere's bump over a 60 mm layer peaked 0.55 mm off its centre in x and
    in y (a 3 mm sphere under the middle of a 20 mm layer); paper-3d's rod was found (8.0, -3.3) mm, where the
    table's own bump was, 0.85 mm from the rod. Mirrored, the same sphere's bump lies within 0.15 mm of it."""
    from skfem import MeshTet

    xs, ys, zs = (np.sort(np.asarray(lines, dtype=float)) for lines in (grid.xs, grid.ys, grid.zs))
    x, y, z = np.meshgrid(xs, ys, zs, indexing="ij")
    points = np.vstack([x.ravel(), y.ravel(), z.ravel()])
    i, j, k = (a.ravel() for a in np.meshgrid(*(np.arange(len(lines) - 1) for lines in (xs, ys, zs)), indexing="ij"))
    flip = (i % 2, j % 2, k % 2)

    def corner(c: int) -> np.ndarray:
        dx, dy, dz = CORNER_OFFSETS[c]
        return ((i + (dx ^ flip[0])) * len(ys) + (j + (dy ^ flip[1]))) * len(zs) + (k + (dz ^ flip[2]))

    tetrahedra = np.hstack([np.vstack([corner(c) for c in tetrahedron]) for tetrahedron in KUHN_TETRAHEDRA])
    return MeshTet(points, tetrahedra.astype(np.int32))


class SurfaceCompliance:
    """Factorised layer; columns of the surface compliance (mm per N) on demand."""

    def __init__(self, grid: Grid, modulus_kpa, poisson: float, symmetric_quarter: bool = False,
                 roller_sides: bool = False) -> None:
        """modulus_kpa: a number or f(x, y, z) -> kPa at points (3, ...) in mm (inclusions). roller_sides: the
        four sides slide but do not move out (mirror planes: the layer goes on past them), else they are free."""
        from scipy.sparse.linalg import splu
        from skfem import Basis, ElementTetP2, ElementVector

        mesh = mirrored_tensor_mesh(grid)
        # strains of P2 are linear on a straight tetrahedron: order 2 integrates the stiffness exactly
        self.basis = Basis(mesh, ElementVector(ElementTetP2()), intorder=2)
        stiffness = self._assemble(modulus_kpa, poisson)
        locs = self.basis.doflocs
        fixed = np.isclose(locs[2], grid.zs[0])
        component = self._components()
        if symmetric_quarter:  # the tip on the corner x = y = 0: mirror planes there
            fixed |= (np.isclose(locs[0], grid.xs[0]) & (component == 0))
            fixed |= (np.isclose(locs[1], grid.ys[0]) & (component == 1))
        if roller_sides:
            fixed |= (np.isclose(locs[0], grid.xs[0]) | np.isclose(locs[0], grid.xs[-1])) & (component == 0)
            fixed |= (np.isclose(locs[1], grid.ys[0]) | np.isclose(locs[1], grid.ys[-1])) & (component == 1)
        self.free = np.flatnonzero(~fixed)
        k_free = stiffness[self.free][:, self.free].tocsc()
        # symmetric positive definite: a symmetric ordering and no pivoting (less fill than COLAMD: a 29k-DOF
        # layer factorised in 14 s against 22 s, 38M against 44M non-zeros, and back-solves as much faster)
        self._lu = splu(k_free, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        top = np.isclose(locs[2], 0.0) & (component == 2)
        self.surface_dofs = np.flatnonzero(top)
        self.surface_xy = locs[:2, self.surface_dofs].T.copy()
        self._free_index = np.full(locs.shape[1], -1)
        self._free_index[self.free] = np.arange(len(self.free))

    def _components(self) -> np.ndarray:
        n = self.basis.N
        return np.tile(np.arange(3), n // 3)

    def _assemble(self, modulus_kpa, poisson: float):
        from skfem import BilinearForm, asm
        from skfem.helpers import ddot, div, grad, transpose

        lam_per_e = poisson / ((1 + poisson) * (1 - 2 * poisson))
        mu_per_e = 1.0 / (2 * (1 + poisson))

        @BilinearForm
        def elasticity(u, v, w):
            # 2 eps(u):eps(v) = grad u:grad v + grad u:grad v^T, without building the symmetric parts
            # (sym_grad's copies took 2/3 of the assembly time)
            gu, gv = grad(u), grad(v)
            shear = ddot(gu, gv) + ddot(gu, transpose(gv))
            return w.e * (lam_per_e * div(u) * div(v) + mu_per_e * shear)

        points = self.basis.mapping.F(self.basis.X)  # (3, elements, quadrature points), mm
        if callable(modulus_kpa):
            e = modulus_kpa(points)
        else:
            e = np.full(points.shape[1:], float(modulus_kpa))
        # kPa = mN/mm^2; in N/mm^2 the displacement comes out in mm per N
        return asm(elasticity, self.basis, e=e * 1e-3)

    def column(self, surface_index: int) -> np.ndarray:
        """Vertical surface displacements (mm, down positive) under 1 N pressing down on one surface node."""
        return self.columns([surface_index])[:, 0]

    def columns(self, surface_indices) -> np.ndarray:
        """The columns of those surface nodes (surface nodes x loaded nodes), in one blocked back-solve: a
        solve with many right-hand sides costs little more than one (the factor is read once)."""
        surface_indices = np.asarray(surface_indices, dtype=int)
        rows = self._free_index[self.surface_dofs]
        load = np.zeros((len(self.free), len(surface_indices)))
        load[rows[surface_indices], np.arange(len(surface_indices))] = 1.0  # 1 N up lifts by C: 1 N down sinks by C
        return self._lu.solve(load)[rows]
