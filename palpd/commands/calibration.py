"""palpd calibration show FILE.cal [--json]: what an ATI calibration file says."""
from __future__ import annotations

import json

from palpd.errors import UsageError


def add_parser(subparsers):
    calibration = subparsers.add_parser("calibration", help="inspect a force sensor calibration file")
    actions = calibration.add_subparsers(dest="action", required=True, metavar="ACTION")
    show = actions.add_parser("show", help="serial, body style, part number, units, ranges and the user matrix")
    show.add_argument("file", metavar="FILE.cal")
    show.add_argument("--json", action="store_true", help="print JSON instead of text")
    return calibration


def run(args) -> int:
    from drivers.nano17.calfile import load_calibration

    if args.action != "show":
        raise UsageError(f"unknown calibration action {args.action!r}")
    info = load_calibration(args.file).as_dict()
    print(json.dumps(info, indent=2) if args.json else _text(info))
    return 0


def _text(info: dict) -> str:
    lines = [f"serial {info['serial']}, {info['body_style']} {info['part_number']}, {info['gauges']} gauges",
             f"units: force {info['force_units']}, torque {info['torque_units']}, distance {info['dist_units']}",
             "ranges: " + ", ".join(f"{axis} ±{value:g}" for axis, value in info["ranges"].items())]
    disagreement = info["axis_disagreement"]
    if disagreement is not None:
        verdict = "agree" if disagreement < 1e-3 else "DISAGREE"
        lines.append(f"UserAxis and Axis/scale + BasicTransform {verdict} (largest difference {disagreement:.2g})")
    lines.append("user matrix (rows Fx Fy Fz Tx Ty Tz, columns gauges 0-5):")
    lines += ["  " + " ".join(f"{v:10.5f}" for v in row) for row in info["user_matrix"]]
    return "\n".join(lines)
