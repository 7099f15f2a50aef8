"""Build the force tables of the shipped 3-D scenes into drivers/sim/mechanics/tables/ (run: make tables).

A 3-D scene's table takes one to four minutes to build on two cores (drivers/sim/mechanics/table.py); shipped
beside the simulator, the shipped scenes' tables make a first `make run` start at once. Rerun after changing a
shipped 3-D scene or the table's recipe (its FORMAT_VERSION, mesh sizes or depths): tests/test_force_table.py
fails while a shipped scene has no table of its current key. Tables no shipped scene uses are removed.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from drivers.sim.mechanics import table as T  # noqa: E402
from drivers.sim.scene import load_scene  # noqa: E402


def shipped_3d_scenes() -> list:
    return [scene for scene in map(load_scene, sorted((ROOT / "config" / "scenes").glob("*.toml")))
            if scene.tissue.is_3d]


def main() -> None:
    T.SHIPPED_DIR.mkdir(exist_ok=True)
    wanted = set()
    for scene in shipped_3d_scenes():
        key = T.table_key(scene)
        path = T.SHIPPED_DIR / T.table_file_name(key)
        wanted.add(path.name)
        if path.exists():
            print(f"{scene.name}: {path.relative_to(ROOT)} is current")
            continue
        started = time.monotonic()
        T.build_table(scene, progress=True).save(path)
        print(f"{scene.name}: built {path.relative_to(ROOT)} in {time.monotonic() - started:.0f} s")
    for stale in T.SHIPPED_DIR.glob("*.npz"):
        if stale.name not in wanted:
            stale.unlink()
            print(f"removed {stale.relative_to(ROOT)}: no shipped scene uses it")


if __name__ == "__main__":
    main()
