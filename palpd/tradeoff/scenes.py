"""Scenes drawn at random, none of which ships: what the learner is tried on beyond the scenes it was developed
on (scripts/active_scenes.py's tables, `palpd bench calibration`). Each draw is reproducible from its seed."""
from __future__ import annotations

import math
import random

from drivers.sim.scene import Scene


def random_scenes(count: int, seed: int) -> list[Scene]:
    """Scenes drawn at random: tissue 50-80 mm across and 0.05-0.4 N/mm; one to three lumps 3-12 mm in
    radius, 1-8 mm deep, 2.5-8 times as stiff, wholly on the tissue and at least 6 mm apart edge to edge
    (touching lumps are a shipped scene of their own); sensor noise 0.005-0.06 N."""
    rng = random.Random(seed)
    scenes = []
    for i in range(count):
        size = rng.choice([50.0, 60.0, 80.0])
        tissue_k = math.exp(rng.uniform(math.log(0.05), math.log(0.4)))
        lumps: list[dict] = []
        for _ in range(rng.choices([1, 2, 3], [0.5, 0.3, 0.2])[0]):
            _add_lump(rng, size, tissue_k, lumps)
        scenes.append(_square_scene(rng, f"random-{seed}-{i}", seed * 1000 + i, size, tissue_k, lumps))
    return scenes


def _square_scene(rng: random.Random, name: str, seed: int, size: float, tissue_k: float, lumps: list[dict]) -> Scene:
    """A square tissue of `size` with the lumps, its sensor noise drawn from 0.005-0.06 N."""
    return Scene(name=name, seed=seed, tissue={"size_mm": [size, size], "stiffness_n_per_mm": tissue_k}, lump=lumps,
                 sensor={"noise_n": rng.choice([0.005, 0.01, 0.03, 0.06]), "tilt": True})


def _add_lump(rng: random.Random, size: float, tissue_k: float, lumps: list[dict]) -> None:
    """One lump 3-12 mm in radius, 1-8 mm deep, 2.5-8 times as stiff, wholly on a square tissue of `size` and
    at least 6 mm from the others edge to edge (up to 100 draws; none if no draw fits)."""
    for _attempt in range(100):
        radius = rng.uniform(3.0, 12.0)
        centre = [rng.uniform(-size / 2 + radius, size / 2 - radius) for _ in range(2)]
        if all(math.dist(centre, other["center_mm"]) > radius + other["radius_mm"] + 6.0 for other in lumps):
            lumps.append({"center_mm": centre, "radius_mm": radius, "depth_mm": rng.uniform(1.0, 8.0),
                          "stiffness_n_per_mm": tissue_k * rng.uniform(2.5, 8.0)})
            return


def varied_scenes(count: int, seed: int) -> list[Scene]:
    """Scenes drawn at random from a wider range than random_scenes: tissue 40-80 mm on each side (not only
    square), hardening (exponent 1-2), sometimes damped or with sliding friction, turned on the bench by up
    to 30°; none to three lumps 2-12 mm in radius, 0-8 mm deep, 2.5-10 times as stiff, whose centre may lie
    up to 0.7 of their radius from the tissue's edge (part of the lump past it); sensor noise 0.001-0.06 N."""
    rng = random.Random(seed + 5000)
    scenes = []
    for i in range(count):
        width, height = rng.choice([40.0, 50.0, 60.0, 80.0]), rng.choice([40.0, 50.0, 60.0, 80.0])
        tissue_k = math.exp(rng.uniform(math.log(0.05), math.log(0.4)))
        lumps: list[dict] = []
        for _ in range(rng.choices([0, 1, 2, 3], [0.15, 0.45, 0.25, 0.15])[0]):
            for _attempt in range(100):
                radius = rng.uniform(2.0, 12.0)
                centre = [rng.uniform(-width / 2 + radius * 0.3, width / 2 - radius * 0.3),
                          rng.uniform(-height / 2 + radius * 0.3, height / 2 - radius * 0.3)]
                if all(math.dist(centre, other["center_mm"]) > radius + other["radius_mm"] + 6.0 for other in lumps):
                    lumps.append({"center_mm": centre, "radius_mm": radius, "depth_mm": rng.uniform(0.0, 8.0),
                                  "stiffness_n_per_mm": tissue_k * rng.uniform(2.5, 10.0)})
                    break
        tissue = {"size_mm": [width, height], "stiffness_n_per_mm": tissue_k,
                  "exponent": rng.choice([1.0, 1.0, 1.5, 2.0]), "damping_n_s_per_mm": rng.choice([0.0, 0.0, 0.01]),
                  "friction": rng.choice([0.0, 0.0, 0.3])}
        scenes.append(Scene(name=f"varied-{seed}-{i}", seed=seed * 1000 + i, tissue=tissue, lump=lumps,
                            placement={"rotation_deg": rng.choice([0.0, 0.0, 15.0, 30.0])},
                            sensor={"noise_n": rng.choice([0.001, 0.005, 0.01, 0.03, 0.06]), "tilt": True}))
    return scenes


def soft_scenes(count: int, seed: int) -> list[Scene]:
    """Scenes with one soft inclusion (a cyst, a pocket of fat: no lump to find, metrics.scene_truth): tissue
    50-80 mm across and 0.05-0.4 N/mm, the inclusion 5-15 mm in radius, 0-3 mm deep, 1.5-5 times softer and
    wholly on the tissue; none to two lumps beside it as random_scenes draws them, at least 6 mm from it and
    from each other edge to edge; sensor noise 0.005-0.06 N."""
    rng = random.Random(seed + 9000)
    scenes = []
    for i in range(count):
        size = rng.choice([50.0, 60.0, 80.0])
        tissue_k = math.exp(rng.uniform(math.log(0.05), math.log(0.4)))
        radius = rng.uniform(5.0, 15.0)
        soft = {"center_mm": [rng.uniform(-size / 2 + radius, size / 2 - radius) for _ in range(2)],
                "radius_mm": radius, "depth_mm": rng.uniform(0.0, 3.0), "stiffness_n_per_mm": tissue_k / rng.uniform(1.5, 5.0)}
        lumps: list[dict] = [soft]
        for _ in range(rng.choices([0, 1, 2], [0.4, 0.4, 0.2])[0]):
            _add_lump(rng, size, tissue_k, lumps)
        scenes.append(_square_scene(rng, f"soft-{seed}-{i}", seed * 1000 + i, size, tissue_k, lumps))
    return scenes
