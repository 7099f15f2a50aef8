"""palpd scenes: the scenes palpd ships, by name (`--scene NAME` takes any of them)."""
from __future__ import annotations

import json


def add_parser(subparsers):
    scenes = subparsers.add_parser("scenes", help="list the shipped scenes (use with --scene NAME)")
    scenes.add_argument("--json", action="store_true", help="print JSON")
    return scenes


def run(args) -> int:
    from drivers.sim.scene import load_scene
    from palpd.shipped import scene_names, shipped_scene

    rows = [_row(name, shipped_scene(name), load_scene(shipped_scene(name))) for name in scene_names()]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    width = max(len(row["name"]) for row in rows)
    for row in rows:
        w, h = row["size_mm"]
        print(f"{row['name']:{width}s}  {row['kind']}, {_what(row)}, {w:g} x {h:g} mm  {row['about']}")
    return 0


def _row(name: str, path, scene) -> dict:
    """A scene's summary: 2-D (a felt stiffness field) or 3-D (an elastic layer with inclusions). Its lumps are
    those stiffer than the tissue (as the scan's truth counts them); a measured map's felt field is the map, whose lumps the scene's [[lump]] tables (none) do not say."""
    from drivers.sim.scene import truth_lumps

    lumps = None if scene.tissue.map else len(truth_lumps(scene))
    bodies = scene.inclusion if scene.tissue.is_3d else scene.lump
    return {"name": name, "kind": "3-D" if scene.tissue.is_3d else "2-D", "lumps": lumps,
            "softer": len(bodies) - (lumps or 0),
            "map": scene.tissue.map is not None, "size_mm": list(scene.tissue.size_mm),
            "about": _first_comment(path), "path": str(path)}


def _what(row: dict) -> str:
    if row["map"]:
        return "measured map"
    softer = f" and {row['softer']} softer spot(s)" if row["softer"] else ""
    return f"{row['lumps']} lump(s){softer}"


def _first_comment(path) -> str:
    """The first sentence of the scene file's opening comment: what the scene is for."""
    words = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        words.append(line.lstrip("# ").strip())
    text = " ".join(words)
    return text.split(". ")[0].rstrip(".") + "." if text else ""
