"""palpd bench mechanics: the finite-element tissue against Hertz, Dimitriadis' layer law and a finer mesh.

Each line is a quarter block pressed at its corner by a 2.5 mm tip with the paraboloid gap both laws assume;
the error is FE / reference - 1 over the indentations listed.
"""
from __future__ import annotations

import json

DEPTHS_MM = (0.2, 0.4, 0.6, 0.8)
TIP_MM, MODULUS_KPA, POISSON = 2.5, 15.0, 0.48


def add_parser(subparsers):
    bench = subparsers.add_parser("mechanics", help="3-D tissue vs Hertz, finite thickness and a finer mesh")
    bench.add_argument("--json", action="store_true", help="print JSON")
    return bench


def run(args) -> int:
    from palpd.threads import pin_blas_to_one_thread

    pin_blas_to_one_thread()
    rows = [_layer("bonded layer 6 mm vs Dimitriadis 2002", 6.0, 0.3, "dimitriadis"),
            _layer("bonded layer 15 mm vs Dimitriadis 2002", 15.0, 0.25, "dimitriadis"),
            _layer("block 15 mm vs Hertz (half-space)", 15.0, 0.25, "hertz"),
            _inclusion()]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    for row in rows:
        errors = " ".join(f"{100 * e:+.1f}%" for e in row["errors"])
        print(f"{row['case']:45s} delta {row['depths_mm']} mm: {errors}  (max {100 * row['max_abs_error']:.1f} %)")
    return 0


def _layer(case: str, thickness_mm: float, fine_mm: float, reference: str) -> dict:
    from drivers.sim.mechanics.validation import bonded_layer_n, hertz_n, indentation_forces_n, quarter_block

    block = quarter_block(thickness_mm, MODULUS_KPA, POISSON, fine_mm)
    forces = indentation_forces_n(block, TIP_MM, DEPTHS_MM)
    if reference == "hertz":
        expected = [hertz_n(MODULUS_KPA, POISSON, TIP_MM, d) for d in DEPTHS_MM]
    else:
        expected = [bonded_layer_n(MODULUS_KPA, POISSON, TIP_MM, d, thickness_mm) for d in DEPTHS_MM]
    return _row(case, forces, expected)


def _inclusion() -> dict:
    """A 150 kPa sphere (r 2 mm, top 1 mm down) under the tip in a 6 mm layer: 0.4 mm mesh vs 0.25 mm."""
    from drivers.sim.bodies import Inclusion
    from drivers.sim.mechanics.validation import indentation_forces_n, quarter_block

    sphere = Inclusion(shape="sphere", center_mm=(0.0, 0.0, 3.0), radius_mm=2.0, modulus_kpa=150.0)

    def modulus(points):
        return MODULUS_KPA + (150.0 - MODULUS_KPA) * sphere.contains(points[0], points[1], -points[2])

    coarse, fine = (indentation_forces_n(quarter_block(6.0, modulus, POISSON, h), TIP_MM, DEPTHS_MM)
                    for h in (0.4, 0.25))
    return _row("sphere inclusion: 0.4 mm mesh vs 0.25 mm", coarse, fine)


def _row(case, forces, expected) -> dict:
    errors = [f / e - 1.0 for f, e in zip(forces, expected)]
    return {"case": case, "depths_mm": list(DEPTHS_MM), "force_n": forces, "reference_n": expected,
            "errors": errors, "max_abs_error": max(abs(e) for e in errors)}
