"""palpd dataset: a palpation dataset CSV from a scene, through the simulated robot."""
from __future__ import annotations

import sys


def add_parser(subparsers):
    dataset = subparsers.add_parser("dataset", help="palpate a simulated scene and write x, y, stiffness, tumor as CSV")
    dataset.add_argument("--scene", required=True, metavar="FILE|NAME", help="scene file (TOML) or shipped scene name")
    dataset.add_argument("--palpations", required=True, type=int, metavar="N")
    dataset.add_argument("--pattern", choices=["raster", "random", "manual"], default="manual",
                         help="where to palpate (default manual: uneven, hand-like)")
    dataset.add_argument("--rotation-deg", type=float, metavar="A", help="turn the tissue by A degrees (default: scene's)")
    dataset.add_argument("--seed", type=int, default=0, metavar="N", help="points and sensor noise")
    dataset.add_argument("--out", metavar="FILE.csv", help="default: standard output")
    dataset.add_argument("--config", metavar="FILE", help="settings (TOML); e.g. palpation.force_axes, stiffness.model")
    return dataset


def run(args) -> int:
    import math

    from palpd.config import load_settings
    from palpd.errors import UsageError
    from palpd.shipped import load_scene_named

    if args.palpations < 1:
        raise UsageError("--palpations must be at least 1")
    if args.rotation_deg is not None and not math.isfinite(args.rotation_deg):
        raise UsageError("--rotation-deg must be a finite number")
    settings = load_settings(args.config)
    scene = load_scene_named(args.scene)
    from palpd.dataset import make_dataset, rotated, to_csv
    from palpd.files import check_writable, write_text

    check_writable(args.out)  # before palpating: the dataset must not be lost to a typo in a path
    if args.rotation_deg is not None:
        scene = rotated(scene, args.rotation_deg)
    from tqdm import tqdm

    with tqdm(total=args.palpations, desc=f"dataset {scene.name}", unit="palpation", disable=None) as bar:
        rows, report = make_dataset(settings, scene, args.pattern, args.palpations, args.seed,
                                    lambda done, total, probe: bar.update(done - bar.n))
    text = to_csv(rows)
    labels = [row[3] for row in rows]
    if args.out:
        write_text(args.out, text)
    else:
        sys.stdout.write(text)
    print(f"palpd: {len(rows)} of {report['palpations']} palpations fitted ({sum(labels)} on a lump)"
          + (f", written to {args.out}" if args.out else ""), file=sys.stderr)
    if report["faults"]:
        print(f"palpd: stopped by a safety fault: {report['faults'][0]['message']}", file=sys.stderr)
        return 1
    return 0
