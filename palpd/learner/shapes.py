"""The parametric lump family: log stiffness of k lumps on a smoothly varying background.

    log k(x) = β0 + βx·x/L + βy·y/L + log(1 + max_j a_j·p_j(x)),
    p = 1 / (1 + h),   h = (e^{λ·ρ^s} − 1) / (e^λ − 1)   (h = ρ^s at λ = 0)

Each lump j has a centre, a size R (the radius of a circle, the equal-area
radius of an ellipse), an edge sharpness s, a tail shape λ and a contrast
a = k_lump/k_tissue − 1. ρ is the distance from the centre in units of R (for
an ellipse, through the shape matrix exp(−E)/R² with E = [[e1, e2], [e2, −e1]],
axes R·e^{±|e|/2}), so p = ½ exactly on the lump's boundary: its half-height,
the felt stiffness halfway between tissue and lump, whatever the edge. Large s
is a flat top with a sharp edge, small s a wide, gradual rise. p = 1 over the
centre and ½ at ρ = 1 for every s and λ. λ = 0 is the Hill profile
1/(1 + ρ^s), whose tails fall off as a power (a hard inclusion felt through
tissue); λ > 0 makes them fall off as exp(−λ·ρ^s) (s = 2, λ ≈ 0.7 is a
Gaussian bump); λ < 0 ends them at a finite distance, h = u·(1 − c)/(1 − c·u)
with c = −λ/2 and u = ρ^s, so p = 0 from ρ^s = 1/c on (s = 2, c = ½ is a
paraboloid cap 1 − ρ²/2; a cone, a plateau with a ramp). One family for lumps
from sharp to gradual, whatever their tails. The two tail branches meet at the
Hill profile, where either thins the tails: a fit stays on the branch it
started on (priors.branch_bounds), and fits from both compete by evidence.
Where lumps come close the stiffer one is felt (the max). Working in log
stiffness keeps readings comparable from 0.005 to 50 N/mm and turns a relative
error into a constant one.

A soft region (a cyst, fat: tissue softer than around it, no lump) is a lump
drawn the other way: the background times (1 − b·p(x)), b = a/(1 + a), so its
core is 1 + a times softer than the tissue around and p = ½ is again halfway in
stiffness. `none+soft:1` is no lump on a background with one soft region, which
a flat or sloping background alone misses and lumps could only mimic by standing
for the tissue around it.

Parameters are [β0, βx, βy] then per lump [cx, cy, log R, (e1, e2,) λ, log s, log a], then a soft region's,
laid out as a circle's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BACKGROUND_PARAMS = 3
CIRCLE_PARAMS = 6
ELLIPSE_PARAMS = 8
SOFT_PARAMS = CIRCLE_PARAMS  # a soft region is a disc lump drawn the other way
TAIL_RANGE = (-1.2, 1.5)  # λ: to c = 0.6 (ending at ρ^s = 1.67) on one side, to Gaussian-like tails on the other
TINY = 1e-12


@dataclass(frozen=True)
class Family:
    """Which lumps, how many: `circles` or `ellipses`, k of them, on a tissue of half-size L (mm), and
    whether the background has a soft region (`soft`: 0 or 1)."""
    kind: str
    k: int
    scale_mm: float
    soft: int = 0

    @property
    def per_lump(self) -> int:
        return ELLIPSE_PARAMS if self.kind == "ellipses" else CIRCLE_PARAMS

    @property
    def size(self) -> int:
        return BACKGROUND_PARAMS + self.k * self.per_lump + self.soft * SOFT_PARAMS

    def lump_slice(self, j: int) -> slice:
        start = BACKGROUND_PARAMS + j * self.per_lump
        return slice(start, start + self.per_lump)

    @property
    def soft_slice(self) -> slice:
        """The soft region's parameters (empty without one)."""
        start = BACKGROUND_PARAMS + self.k * self.per_lump
        return slice(start, start + self.soft * SOFT_PARAMS)

    def profile_slices(self) -> list[slice]:
        """Each lump's parameters, then the soft region's: every part with a profile [.., λ, log s, log a]."""
        return [self.lump_slice(j) for j in range(self.k)] + ([self.soft_slice] if self.soft else [])

    @property
    def name(self) -> str:
        lumps = "none" if self.k == 0 else f"{'ellipse' if self.kind == 'ellipses' else 'circles'}:{self.k}"
        return f"{lumps}+soft:{self.soft}" if self.soft else lumps


def background(theta: np.ndarray, xy: np.ndarray, scale_mm: float) -> np.ndarray:
    """The background's log stiffness at xy (n × 2): n values, or S × n for S parameter vectors (S × size)."""
    return theta[..., 0:1] + (theta[..., 1:2] * xy[:, 0] + theta[..., 2:3] * xy[:, 1]) / scale_mm


def log_rho2(params: np.ndarray, xy: np.ndarray, ellipse: bool,
             derivatives: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """log ρ² at each point and its derivatives (n × shape params) w.r.t. [cx, cy, log R(, e1, e2)] (None when
    not asked for: where a point lies against the lump's boundary needs none)."""
    lr2, d = _log_rho2_all(np.asarray(params, dtype=float)[None, :], xy, ellipse, derivatives)
    return lr2[:, 0], (None if d is None else d[:, 0, :])


def _log_rho2_all(lumps: np.ndarray, xy: np.ndarray, ellipse: bool, derivatives: bool = True):
    """log ρ² of every point (n) for every lump (k), and its derivatives (n × k × shape params; None
    when not asked for: most evaluations want values only)."""
    ux = xy[:, 0:1] - lumps[None, :, 0]
    uy = xy[:, 1:2] - lumps[None, :, 1]
    r2 = ux * ux + uy * uy + TINY
    lr = lumps[None, :, 2]
    if not ellipse:
        if not derivatives:
            return np.log(r2) - 2.0 * lr, None
        d = np.empty(r2.shape + (3,))
        d[:, :, 0] = -2.0 * ux / r2
        d[:, :, 1] = -2.0 * uy / r2
        d[:, :, 2] = -2.0
        return np.log(r2) - 2.0 * lr, d
    e1, e2 = lumps[:, 3], lumps[:, 4]
    eps = np.hypot(e1, e2)
    cosh, sinh_over, d_sinh_over = np.cosh(eps), _sinh_over(eps), _d_sinh_over_by_eps(eps)
    uxx, uyy = ux * ux - uy * uy, ux * uy
    q = e1 * uxx + 2.0 * e2 * uyy
    big_q = np.maximum(cosh * r2 - sinh_over * q, TINY)
    if not derivatives:
        return np.log(big_q) - 2.0 * lr, None
    dq_dux = 2.0 * cosh * ux - sinh_over * (2.0 * e1 * ux + 2.0 * e2 * uy)
    dq_duy = 2.0 * cosh * uy - sinh_over * (-2.0 * e1 * uy + 2.0 * e2 * ux)
    dq_de1 = sinh_over * e1 * r2 - d_sinh_over * e1 * q - sinh_over * uxx
    dq_de2 = sinh_over * e2 * r2 - d_sinh_over * e2 * q - sinh_over * 2.0 * uyy
    d = np.empty(r2.shape + (5,))  # filled column by column: np.stack's wrapper cost more than the arithmetic
    d[:, :, 0] = -dq_dux / big_q
    d[:, :, 1] = -dq_duy / big_q
    d[:, :, 2] = -2.0
    d[:, :, 3] = dq_de1 / big_q
    d[:, :, 4] = dq_de2 / big_q
    return np.log(big_q) - 2.0 * lr, d


def _sinh_over(eps: np.ndarray) -> np.ndarray:
    safe = np.maximum(eps, 1e-4)
    return np.where(eps < 1e-4, 1.0 + eps * eps / 6.0, np.sinh(safe) / safe)


def _d_sinh_over_by_eps(eps: np.ndarray) -> np.ndarray:
    safe = np.maximum(eps, 1e-3)
    return np.where(eps < 1e-3, 1.0 / 3.0 + eps * eps / 30.0, (safe * np.cosh(safe) - np.sinh(safe)) / safe**3)


def _heights(lumps: np.ndarray, xy: np.ndarray, ellipse: bool, jacobian: bool):
    """a·p(x) of every lump (n × k) and, if asked, its derivatives (n × k × per-lump params)."""
    lr2, d_lr2 = _log_rho2_all(lumps, xy, ellipse, jacobian)
    tail, s, a = lumps[:, -3], np.exp(lumps[:, -2]), np.exp(lumps[:, -1])
    # np.minimum/np.maximum rather than np.clip (the same values): this runs at every fit step, and
    # np.clip's Python wrapper cost more than the arithmetic on a few dozen readings
    log_u = np.minimum(np.maximum(0.5 * s * lr2, -700.0), 50.0)  # u = ρ^s
    t, dt_dlog_u, dt_dtail = _log_h(log_u, tail, jacobian)
    t = np.minimum(np.maximum(t, -700.0), 700.0)
    p = 1.0 / (1.0 + np.exp(t))
    height = a * p
    if not jacobian:
        return height, None
    dh_dt = -a * p * (1.0 - p)
    jac = np.empty(lr2.shape + (lumps.shape[1],))
    jac[:, :, :-3] = (dh_dt * dt_dlog_u * 0.5 * s)[:, :, None] * d_lr2
    jac[:, :, -3] = dh_dt * dt_dtail
    jac[:, :, -2] = dh_dt * dt_dlog_u * log_u
    jac[:, :, -1] = height
    return height, jac


def _log_h(log_u: np.ndarray, tail: np.ndarray, derivatives: bool = True):
    """t = log h for u = e^log_u (n × K, one column per lump), with dt/dlog u and dt/dλ (None, None when
    not asked for); the Hill limit (λ = 0) by its series. Columns take one branch or the other, computed
    for all columns at once (lumps from many starts are evaluated together: a loop over them would cost
    a dozen numpy calls each)."""
    u = np.exp(log_u)
    if (tail < 0.0).any():  # the method, not np.any: its wrapper costs more than the test here
        return _log_h_branches(log_u, u, tail, derivatives)
    hill = tail < 1e-4
    if hill.all():
        return log_u + tail * (u - 1.0) / 2.0, *((1.0 + tail * u / 2.0, (u - 1.0) / 2.0) if derivatives else (None, None))
    lam = np.where(hill, 1.0, tail)  # the Hill columns' values come from the series below
    x = np.maximum(lam * u, 1e-300)
    one_minus = np.maximum(-np.expm1(-x), 1e-300)  # 1 − e^{−x}
    t = np.where(x > 1e-8, x + np.log(one_minus), np.log(x)) - np.log(np.expm1(lam))
    if derivatives:
        dt_dlog_u, dt_dtail = x / one_minus, u / one_minus + 1.0 / np.expm1(-lam)
    if hill.any():
        t = np.where(hill, log_u + tail * (u - 1.0) / 2.0, t)
        if derivatives:
            dt_dlog_u = np.where(hill, 1.0 + tail * u / 2.0, dt_dlog_u)
            dt_dtail = np.where(hill, (u - 1.0) / 2.0, dt_dtail)
    return (t, dt_dlog_u, dt_dtail) if derivatives else (t, None, None)


def _log_h_branches(log_u: np.ndarray, u: np.ndarray, tail: np.ndarray, derivatives: bool):
    """_log_h where some lumps end at a finite distance (λ < 0): each column from its own branch."""
    compact = tail < 0.0
    t, dt_dlog_u, dt_dtail = _log_h(log_u, np.where(compact, 0.0, tail), derivatives)
    c = -0.5 * np.minimum(tail, 0.0)  # one per column: broadcast by the arithmetic below (np.broadcast_to's wrapper costs)
    cu = c * u
    inside = cu < 1.0 - 1e-12
    rest = np.where(inside, 1.0 - cu, 1.0)
    t_compact = np.where(inside, log_u + np.log1p(-c) - np.log(rest), 700.0)  # past the end: p = 0
    t = np.where(compact, t_compact, t)
    if not derivatives:
        return t, None, None
    dt_dlog_u = np.where(compact, np.where(inside, 1.0 / rest, 0.0), dt_dlog_u)
    dt_dtail = np.where(compact, np.where(inside, 0.5 / (1.0 - c) - 0.5 * u / rest, 0.0), dt_dtail)
    return t, dt_dlog_u, dt_dtail


def rho_at(params: np.ndarray, t: float) -> float:
    """ρ where a lump's log h equals t (its 1/(1 + eᵗ) level)."""
    tail, s = params[-3], math.exp(params[-2])
    if tail < 0.0:  # h = u(1 − c)/(1 − cu): u = h / (1 − c + c·h)
        c, h = -0.5 * tail, math.exp(min(t, 700.0))
        log_u = t - math.log(1.0 - c + c * h) if h < 1e300 else -math.log(c)
    elif tail < 1e-4:
        log_u = t
    else:
        x = math.log1p(math.exp(min(t + math.log(math.expm1(tail)), 700.0)))  # λu
        log_u = math.log(max(x / tail, 1e-300))
    return math.exp(log_u / s)


def make_lump(center, radius_mm: float, sharpness: float, contrast: float, stretch=None, tail: float = 0.0):
    """Parameters of one lump (an ellipse when `stretch` (e1, e2) is given)."""
    shape = [] if stretch is None else [float(stretch[0]), float(stretch[1])]
    return np.array([float(center[0]), float(center[1]), math.log(radius_mm), *shape, tail,
                     math.log(sharpness), math.log(contrast)])


def lumps_of(family: Family, theta: np.ndarray) -> np.ndarray:
    """The lumps' parameters as a (k × per-lump) array."""
    return theta[BACKGROUND_PARAMS:family.soft_slice.start].reshape(family.k, family.per_lump)


def evaluate(family: Family, theta: np.ndarray, xy: np.ndarray, jacobian: bool = True):
    """Model log stiffness at xy (n × 2), and (if asked) its Jacobian (n × family.size)."""
    f, jac = evaluate_many(family, theta[None, :], xy, jacobian)
    return f[0], (None if jac is None else jac[0])


def evaluate_many(family: Family, thetas: np.ndarray, xy: np.ndarray, jacobian: bool = True):
    """`evaluate` for S parameter vectors at once (S × family.size): S × n values and S × n × size
    Jacobians. Fits from several starts step together (solver.py), one pass of numpy calls for all:
    on a few dozen readings a call's overhead, not its arithmetic, is the cost."""
    count, n = len(thetas), len(xy)
    base = background(thetas, xy, family.scale_mm)
    if family.soft:
        lowered, dip_jac = _soft(thetas[:, family.soft_slice], xy, jacobian)
        base = base - lowered
    if family.k == 0:
        if not jacobian:
            return base, None
        out = np.zeros((count, n, family.size))
        out[:, :, :BACKGROUND_PARAMS] = _background_jac(xy, family.scale_mm)
        if family.soft:
            out[:, :, family.soft_slice] = -dip_jac
        return base, out
    lumps = thetas[:, BACKGROUND_PARAMS:family.soft_slice.start].reshape(count * family.k, family.per_lump)
    heights, jacs = _heights(lumps, xy, family.kind == "ellipses", jacobian)
    heights = heights.reshape(n, count, family.k)
    if family.k == 1:  # one lump, felt everywhere (the common case, without the search for the top one)
        top, m = None, heights[:, :, 0]
    else:
        top = np.argmax(heights, axis=2)  # n × S: the lump felt at each point (the stiffest)
        m = heights[np.arange(n)[:, None], np.arange(count)[None, :], top]  # take_along_axis, without its wrapper
    f = base + np.log1p(m.T)
    if not jacobian:
        return f, None
    out = np.zeros((count, n, family.size))  # the background's columns, then each lump's (only the top one's set)
    out[:, :, :BACKGROUND_PARAMS] = _background_jac(xy, family.scale_mm)
    if family.soft:
        out[:, :, family.soft_slice] = -dip_jac
    lump_columns = slice(BACKGROUND_PARAMS, family.soft_slice.start)
    jacs = jacs.reshape(n, count, family.k, family.per_lump) / (1.0 + m[:, :, None, None])
    if top is None:
        out[:, :, lump_columns] = jacs[:, :, 0].transpose(1, 0, 2)
        return f, out
    per_lump = out[:, :, lump_columns].reshape(count, n, family.k, family.per_lump)  # a view: splits one axis
    rows, starts = np.arange(n)[:, None], np.arange(count)[None, :]
    per_lump[starts, rows, top] = jacs[rows, starts, top]
    return f, out


def row_variances(rows: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """rᵢᵀ Σ rᵢ for each row rᵢ: the variance of each linearised quantity (a prediction's, from the model's
    Jacobian). Summed by einsum: numpy's sum along a short last axis cost 3-5x the product itself."""
    return np.einsum("ij,ij->i", rows @ cov, rows)


def heights_of(family: Family, theta: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """a_j·p_j(x) of every lump (n × k): which lump is felt where, and how much."""
    if family.k == 0:
        return np.zeros((len(xy), 0))
    return _heights(lumps_of(family, theta), xy, family.kind == "ellipses", False)[0]


def soft_dip(family: Family, theta: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """How far the soft region lowers the log stiffness at each point (zeros without one)."""
    if not family.soft:
        return np.zeros(len(xy))
    return _soft(theta[None, family.soft_slice], xy, False)[0][0]


def _soft(regions: np.ndarray, xy: np.ndarray, jacobian: bool):
    """−log(1 − b·p) of one soft region per row of `regions` (S × its params) at each point: S × n, and its
    derivatives S × n × params (None when not asked for). With h = a·p: log(1 + a) − log(1 + a − h)."""
    h, jac = _heights(regions, xy, False, jacobian)  # n × S, n × S × params (its last column: a·p = h)
    a = np.exp(regions[:, -1])
    rest = 1.0 + a[None, :] - h
    lowered = (np.log1p(a)[None, :] - np.log(rest)).T
    if not jacobian:
        return lowered, None
    d = jac / rest[:, :, None]  # d(−log rest) w.r.t. the profile's parameters
    d[:, :, -1] = a[None, :] / (1.0 + a[None, :]) - (a[None, :] - h) / rest
    return lowered, d.transpose(1, 0, 2)


def _background_jac(xy: np.ndarray, scale_mm: float) -> np.ndarray:
    jac = np.empty((len(xy), BACKGROUND_PARAMS))
    jac[:, 0] = 1.0
    jac[:, 1:] = xy / scale_mm
    return jac


# -- geometry of one lump ---------------------------------------------------------------------------
def axes_and_angle(params: np.ndarray, ellipse: bool) -> tuple[float, float, float]:
    """(major, minor) semi-axes in mm and the major axis's angle in degrees, in [0, 180)."""
    radius = math.exp(params[2])
    if not ellipse:
        return radius, radius, 0.0
    e1, e2 = params[3], params[4]
    eps = math.hypot(e1, e2)
    # exp(−E)/R² has its smallest eigenvalue (longest axis) along E's eigenvector of eigenvalue +ε.
    angle = 0.5 * math.degrees(math.atan2(e2, e1)) % 180.0
    return radius * math.exp(eps / 2.0), radius * math.exp(-eps / 2.0), angle


def edge_width_mm(params: np.ndarray) -> float:
    """Distance from the 75 % to the 25 % level along a radius of the equal-area circle."""
    log3 = math.log(3.0)
    return math.exp(params[2]) * (rho_at(params, log3) - rho_at(params, -log3))


def boundary_polygon(params: np.ndarray, ellipse: bool, vertices: int = 72) -> np.ndarray:
    """The lump's 50 % boundary (ρ = 1) as a closed polygon (first vertex repeated)."""
    major, minor, angle_deg = axes_and_angle(params, ellipse)
    t = np.linspace(0.0, 2.0 * math.pi, vertices + 1)
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    ex, ey = major * np.cos(t), minor * np.sin(t)
    points = np.column_stack([params[0] + c * ex - s * ey, params[1] + s * ex + c * ey])
    points[-1] = points[0]
    return points
