"""Fit the depth surrogate (palpd/learner/depth.py) to the simulator's finite-element tissue (run: make surrogate).

A lump felt through tissue is blurred by the tissue above it: the deeper its top, the lower its contrast and
the wider its edge for its size. For each sphere of a grid (radius, top depth, contrast, layer thickness), this
presses the simulator's own finite-element layer (drivers/sim/mechanics/table.py, the recipe the 3-D scenes
use) along a line out from over the sphere's centre, reads the felt stiffness ratio to the bare layer at the
reference depth, fits it with the learner's lump profile (palpd/learner/shapes.py: contrast a, radius R, edge
width), and fits the top depth, linear in (log a, R, edge) and log a × R, in tip radii, by least squares (depth.py). Spheres only:
the held-out rows (a rod, an ellipsoid, a box, other thicknesses) measure the surrogate's error on bodies it was
not fitted on, which becomes part of every reported depth_sd_mm. Writes palpd/learner/depth_surrogate.json.
A few minutes per ten bodies on two cores.
"""
from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from drivers.sim.mechanics import table as T  # noqa: E402
from drivers.sim.scene import Scene  # noqa: E402
from palpd.learner import depth, shapes  # noqa: E402

TIP_MM = 2.5
MODULUS_KPA = 15.0
NODE_MM = T.ELEMENT_MM / 2.0
OUT = ROOT / "palpd" / "learner" / "depth_surrogate.json"
FAINTEST = 0.1  # contrast (k_lump / k_tissue - 1) below which a body is left out of the fit


def felt_profile(thickness_mm: float, body: dict | None, reach_mm: float, offset_mm: float = 0.0):
    """(distance from the body's centre, force at the reference depth) along +x, smoothed as the table is."""
    half = NODE_MM * math.ceil((reach_mm + 6.0) / NODE_MM) + 4.0
    scene = Scene.model_validate({"name": "fit", "tissue": {"size_mm": [2 * half, 2 * half],
                                  "thickness_mm": thickness_mm, "modulus_kpa": MODULUS_KPA},
                                  "inclusion": [body] if body else [], "probe": {"tip_radius_mm": TIP_MM}})
    block = T.layer_compliance(scene)
    xy = block.surface_xy
    xs = np.arange(-NODE_MM, reach_mm + offset_mm + 2 * NODE_MM, NODE_MM)
    ys = np.array([-NODE_MM, 0.0, NODE_MM])
    near = ((xy[:, 0] >= xs[0] - TIP_MM - 1e-9) & (xy[:, 0] <= xs[-1] + TIP_MM + 1e-9)
            & (np.abs(xy[:, 1]) <= ys[-1] + TIP_MM + 1e-9))
    kept = np.flatnonzero(near)
    c = block.columns(kept)[kept]
    c = (c + c.T) / 2.0
    forces = np.array([[T.force_at(xy[kept], c, x, y, TIP_MM, [depth.REFERENCE_DEPTH_MM]) for y in ys] for x in xs])
    smooth = T._smoothed(forces)[1:-1, 1, 0]  # the table's 1/4 1/2 1/4, its ends dropped (mirrored there)
    return xs[1:-1] - offset_mm, smooth


def lump_features(distance_mm: np.ndarray, ratio: np.ndarray) -> tuple[float, float, float]:
    """(contrast a, radius R, edge width) of the learner's one-lump profile fitted to a radial felt ratio."""
    keep = distance_mm >= 0
    d, log_ratio = distance_mm[keep], np.log(ratio[keep])

    family, xy = shapes.Family("circles", 1, 1.0), np.column_stack([d, np.zeros_like(d)])

    def residual(p):  # a flat background of 1 (the ratio), one circle at the origin
        theta = np.array([0.0, 0.0, 0.0, 0.0, 0.0, p[0], p[1], p[2], p[3]])
        return shapes.evaluate(family, theta, xy, jacobian=False)[0] - log_ratio

    a0 = max(float(np.expm1(log_ratio.max())), 0.05)
    half = d[np.argmin(np.abs(log_ratio - math.log1p(a0 / 2)))] or 1.0
    best = None
    for tail in (-0.5, 0.0, 0.7):
        fit = least_squares(residual, [math.log(half), tail, math.log(2.0), math.log(a0)],
                            bounds=([-3, shapes.TAIL_RANGE[0], -2, -6], [4, shapes.TAIL_RANGE[1], 3, 5]))
        if best is None or fit.cost < best.cost:
            best = fit
    log_r, tail, log_s, log_a = best.x
    params = np.array([0.0, 0.0, log_r, tail, log_s, log_a])
    return math.exp(log_a), math.exp(log_r), shapes.edge_width_mm(params)


def rows_for(bodies, progress=lambda line: print(line, flush=True)):
    rows = []
    background = {}
    rng = np.random.default_rng(0)
    for thickness, body, top in bodies:
        reach = max(body.get("radius_mm", 0.0), *body.get("semi_axes_mm", body.get("size_mm", [5.0]))[:2]) + 12.0
        if thickness not in background:
            background[thickness] = felt_profile(thickness, None, 4.0)[1].mean()
        offset = float(rng.uniform(0.0, NODE_MM))
        body = {**body, "center_mm": [offset, 0.0, body["center_mm"][2]]}
        started = time.monotonic()
        distance, force = felt_profile(thickness, body, reach, offset)
        a, radius, edge = lump_features(distance, force / background[thickness])
        rows.append({"thickness_mm": thickness, "shape": body["shape"], "modulus_kpa": body["modulus_kpa"],
                     "top_mm": top, "contrast": a, "radius_mm": radius, "edge_mm": edge})
        progress(f"{body['shape']} top {top:g} mm in {thickness:g} mm: a {a:.3f} R {radius:.2f} edge {edge:.2f}"
                 f" ({time.monotonic() - started:.0f} s)")
    return rows


def sphere(radius, top, contrast):
    return {"shape": "sphere", "center_mm": [0.0, 0.0, top + radius], "radius_mm": radius,
            "modulus_kpa": MODULUS_KPA * contrast}


def training_bodies():
    for thickness, radius, top, contrast in itertools.product((20.0, 12.0), (2.5, 4.0, 6.0, 9.0),
                                                              (0.5, 1.5, 3.0, 4.5, 6.0, 8.0), (5.0, 20.0)):
        if top + 2 * radius <= thickness - 1.0:
            yield thickness, sphere(radius, top, contrast), top


def held_out_bodies():
    """Bodies and layers the fit never sees: its error on them is what a depth's sd must cover."""
    # an elongated body is read across itself (turned 90°: its long axis along y), as the learner reads an
    # ellipse's depth along its minor axis (depth.py)
    yield 20.0, {"shape": "cylinder", "center_mm": [0, 0, 8.0], "radius_mm": 5.0, "length_mm": 15.7,
                 "angle_deg": 90.0, "modulus_kpa": 150.0}, 3.0
    yield 20.0, {"shape": "cylinder", "center_mm": [0, 0, 4.0], "radius_mm": 2.5, "length_mm": 20.0,
                 "angle_deg": 90.0, "modulus_kpa": 100.0}, 1.5
    yield 20.0, {"shape": "ellipsoid", "center_mm": [0, 0, 7.0], "semi_axes_mm": [7.0, 4.0, 3.0],
                 "angle_deg": 90.0, "modulus_kpa": 120.0}, 4.0
    yield 20.0, {"shape": "box", "center_mm": [0, 0, 5.0], "size_mm": [8.0, 8.0, 4.0], "modulus_kpa": 200.0}, 3.0
    yield 16.0, sphere(3.5, 2.0, 8.0), 2.0
    yield 25.0, sphere(5.0, 5.0, 12.0), 5.0
    yield 20.0, sphere(5.0, 3.0, 10.0), 3.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=Path, help="reuse measured rows (JSON) instead of pressing the FE layer")
    parser.add_argument("--held-out-again", action="store_true", help="with --rows: press the held-out bodies anew")
    args = parser.parse_args()
    if args.rows:
        measured = json.loads(args.rows.read_text())
        if args.held_out_again:
            measured["held_out"] = rows_for(list(held_out_bodies()))
    else:
        measured = {"training": rows_for(list(training_bodies())), "held_out": rows_for(list(held_out_bodies()))}
    if not args.rows or args.held_out_again:
        (ROOT / "out").mkdir(exist_ok=True)
        (ROOT / "out" / "depth-rows.json").write_text(json.dumps(measured, indent=1))
        print("rows written to out/depth-rows.json (--rows reuses them)")
    # a body felt fainter than this is no lump a scan reports (the learner's lumps are 30 % over the tissue at
    # least, scan.min_contrast): its fitted profile is noise (a 2.5 mm sphere 8 mm down fitted a 0.4 mm disc)
    found = [row for row in measured["training"] if row["contrast"] >= FAINTEST]
    print(f"{len(found)} of {len(measured['training'])} training bodies felt at {FAINTEST:.0%} or more")
    surrogate = depth.Surrogate.fit(found, TIP_MM)
    held = [(row, surrogate.top_mm(row["contrast"], row["radius_mm"], row["edge_mm"])) for row in measured["held_out"]]
    errors = np.array([estimate - row["top_mm"] for row, estimate in held])
    surrogate = surrogate.with_held_out_sd(float(np.sqrt(np.mean(errors**2))))
    for row, estimate in held:
        print(f"held out: {row['shape']} top {row['top_mm']:g} mm in {row['thickness_mm']:g} mm -> {estimate:.2f} mm")
    print(f"fit residual sd {surrogate.fit_sd_mm:.2f} mm, held-out RMS error {surrogate.held_out_sd_mm:.2f} mm")
    OUT.write_text(json.dumps(surrogate.as_dict(), indent=1) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
