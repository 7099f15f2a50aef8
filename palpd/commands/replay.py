"""palpd replay SESSION_DIR: re-run fitting and learning on a recorded session and check its estimate."""
from __future__ import annotations

from pathlib import Path


def add_parser(subparsers):
    replay = subparsers.add_parser("replay", help="re-run fitting and learning on a session; compare estimates")
    replay.add_argument("session_dir", metavar="SESSION_DIR")
    replay.add_argument("--config", metavar="FILE", help="settings (TOML) to learn with")
    return replay


def run(args) -> int:
    from palpd.config import load_settings

    settings = load_settings(args.config)  # checked before the fitting and learning code is imported
    from palpd.daemon.replay import replay

    result = replay(Path(args.session_dir), settings)
    print(f"{result['palpations']} palpations refitted ({result['segmented']} re-segmented from raw samples), largest stiffness difference "
          f"{result['max_stiffness_difference_n_per_mm']:.2e} N/mm")
    for i, lump in enumerate(result["estimate"]["lumps"], 1):
        (x, y), r = lump["center_mm"], lump["radius_mm"]
        print(f"lump {i}: centre ({x:.2f}, {y:.2f}) mm, radius {r:.2f} mm")
    if result["reproduced"]:
        print("the recorded estimate is reproduced")
        return 0
    print("the recorded estimate is NOT reproduced" if result["recorded"] else "no estimate was recorded")
    return 1
