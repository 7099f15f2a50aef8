"""Reproduce the seed paper's study and write docs/reproduction.md (run: make reproduce).

Datasets are made like the paper's: a manual (uneven) training set of 81
palpations and three test sets of 76 at other tissue rotations, on the
paper-edge scene (tilted sensor near the workspace edge) and on its
low-contrast variant (a lump 1.5 times as stiff as the tissue, where
stiffness errors of a few per cent start to cost classifications). Two set-ups:
"paper" reads the sensor's z axis only and fits the linear model through the
contact point (§3.1); "palpd" rotates all three axes into the tissue frame and
fits the model the data selects. The study is the same for both.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from drivers.sim.scene import load_scene, truth_lumps
from palpd.config import Settings
from palpd.dataset import Dataset, make_dataset, rotated
from palpd.study.run import run_study

ROOT = Path(__file__).resolve().parent.parent
SCENES = {"paper-edge": "the paper's sponge and hard object (lump 6.7 times as stiff as the tissue), tissue raised "
                         "50 mm so the tilted Nano17 matters",
          "paper-edge-low-contrast": "the same with a lump only 1.5 times as stiff as the tissue (0.18 vs 0.12 N/mm)"}
TRAIN_ROTATION, TEST_ROTATIONS = 0.0, (35.0, 140.0, 250.0)
SETUPS = {"paper": {"palpation": {"force_axes": "sensor_z"}, "stiffness": {"model": "linear"}},
          "palpd": {"palpation": {"force_axes": "tissue"}, "stiffness": {"model": "select"}}}
PAPER = {"threshold-radius": "~10 % FP+FN; centre ~10 mm", "centroid-radius": "~10 %; centre 8.79 mm (mean, §3.5–3.8)"}


def datasets(scene_name: str, setup: str):
    settings = Settings().updated(**SETUPS[setup])
    scene = load_scene(ROOT / "config" / "scenes" / f"{scene_name}.toml")
    made = []
    for i, rotation in enumerate((TRAIN_ROTATION, *TEST_ROTATIONS)):
        turned = rotated(scene, rotation)
        rows, _ = make_dataset(settings, turned, "manual", 81 if i == 0 else 76, seed=11 + i)
        values = np.array(rows, dtype=float)
        name = "train" if i == 0 else f"test-{rotation:g}deg"
        made.append((Dataset(name, values[:, :2], values[:, 2], values[:, 3].astype(int)), truth_lumps(turned)[0]))
    return made


def summarise(scene_name: str, setup: str) -> list[tuple]:
    made = datasets(scene_name, setup)
    train, tests = made[0][0], [d for d, _ in made[1:]]
    truth = {d.path: t for d, t in made[1:]}
    results = run_study(train, tests)
    rows = []
    for key in dict.fromkeys((r["method"], r["algorithm"]) for r in results):
        group = [r for r in results if (r["method"], r["algorithm"]) == key]
        rate = 100 * np.mean([(r["fp"] + r["fn"]) / r["n"] for r in group])
        centre = [math.dist(r["center_mm"], truth[r["test"]]["center_mm"]) for r in group if r["center_mm"]]
        radius = [abs(r["radius_mm"] - truth[r["test"]]["radius_mm"]) for r in group]
        rows.append((*key, rate, np.mean(centre) if centre else float("nan"), np.mean(radius)))
    return rows


def main() -> int:
    out = ROOT / "docs" / "reproduction.md"
    lines = [
        "# Reproducing the seed paper's study", "",
        "Made by `make reproduce` (`scripts/reproduce.py`); every figure below is recomputed by that command.", "",
        f"Training set: 81 manual (uneven, hand-like) palpations at {TRAIN_ROTATION:g}°; "
        f"test sets: 76 manual palpations each at {', '.join(f'{r:g}°' for r in TEST_ROTATIONS)}. "
        "FP+FN is the mean over the three test sets, as a percentage of their points; centre and radius errors are "
        "means against the scene's truth. GDA is LinearDiscriminantAnalysis; LR and SVM use C = 1 on standardised "
        "features; Equation 1 uses {10, 3}.", "",
        "The paper reports FP+FN of roughly 10 % or less for the supervised methods (Figure 10), a centre error of "
        "about 1 cm for §3.4 and 8.79 mm for the weighted centroid (§3.5–§3.8), and radii within 1 cm.", "",
        "Paper set-up: sensor z axis only (`palpation.force_axes = \"sensor_z\"`), linear model through "
        "the contact point (`stiffness.model = \"linear\"`). palpd set-up: three axes in the tissue frame "
        "(`\"tissue\"`) and the selected model (`\"select\"`, BIC) read at 2 mm.", "",
    ]
    for scene_name, about in SCENES.items():
        lines += _scene_table(scene_name, about)
    lines += ["With a stiff lump (first table) any stiffness estimate separates lump from tissue, so the improvements "
              "change little. At low contrast (second table) stiffness errors weigh more; the mean FP+FN lines say "
              "what the two improvements buy at this placement, where the tilt costs little.", ""]
    out.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


def _scene_table(scene_name: str, about: str) -> list[str]:
    tables = {setup: summarise(scene_name, setup) for setup in SETUPS}
    lines = [f"## Scene `config/scenes/{scene_name}.toml`", "", about[0].upper() + about[1:] + ".", "",
             "| method | algorithm | paper set-up: FP+FN % | centre err mm | radius err mm "
             "| palpd set-up: FP+FN % | centre err mm | radius err mm |",
             "|---|---|---|---|---|---|---|---|"]
    for paper_row, palpd_row in zip(tables["paper"], tables["palpd"]):
        method, algorithm = paper_row[:2]
        cells = [f"{v:.1f}" for v in (*paper_row[2:], *palpd_row[2:])]
        lines.append(f"| {method} | {algorithm or 'k-means'} | " + " | ".join(cells) + " |")
    paper_mean, palpd_mean = (np.mean([row[2] for row in tables[setup]]) for setup in ("paper", "palpd"))
    lines += ["", f"Mean FP+FN over all rows: paper set-up {paper_mean:.1f} %, palpd set-up {palpd_mean:.1f} %.", ""]
    return lines


if __name__ == "__main__":
    sys.exit(main())
