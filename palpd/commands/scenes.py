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

    rows = []
    for name in scene_names():
        path = shipped_scene(name)
        scene = load_scene(path)
        kind = "3-D" if scene.tissue.is_3d else "2-D"
        rows.append({"name": name, "kind": kind, "lumps": len(scene.inclusion if scene.tissue.is_3d else scene.lump),
                     "size_mm": list(scene.tissue.size_mm),
                     "about": _first_comment(path), "path": str(path)})
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    width = max(len(row["name"]) for row in rows)
    for row in rows:
        w, h = row["size_mm"]
        print(f"{row['name']:{width}s}  {row['kind']}, {row['lumps']} lump(s), {w:g} x {h:g} mm  {row['about']}")
    return 0


def _first_comment(path) -> str:
    """The first sentence of the scene file's opening comment: what the scene is for."""
    words = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        words.append(line.lstrip("# ").strip())
    text = " ".join(words)
    return text.split(". ")[0].rstrip(".") + "." if text else ""
