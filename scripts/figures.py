"""Measure and write the figures the README and the manual include (run: make figures).

Each table and picture is stamped with the commit it measured (`git rev-parse`; "uncommitted" when the tree
has changes outside what this writes). Writes docs/figures/*.md and *.png (the manual includes them with
pymdownx.snippets) and copies each table into README.md between its marker comments
`<!-- figures:NAME -->` and `<!-- /figures:NAME -->` (GitHub cannot include files). Only what runs in a few
minutes: active scans of a few shipped scenes in simulated time, the paper scan's map, the real phantom's active
scan beside a raster of the same count, `palpd bench learner`,
and `palpd bench calibration` (about ten minutes on two cores).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FIGURES = ROOT / "docs" / "figures"
WRITTEN_HERE = ("docs/figures/", "README.md")  # rewriting these does not make the measured code another one
SCENES = ("paper", "two-lumps", "no-lump", "elongated-lump", "deep-lump", "paper-3d", "sphere-3d", "two-lumps-3d",
          "no-lump-3d")
REAL_SCENE = "garg-phantom"  # the shipped real data: a dVRK's readings of a silicone phantom

sys.path.insert(0, str(ROOT / "scripts"))
import active_scenes  # noqa: E402  the same scans and rows as its tables


def commit_stamp(root: Path = ROOT) -> str:
    head = _git(root, "rev-parse", "--short", "HEAD").strip()
    changed = [line[3:] for line in _git(root, "status", "--porcelain").splitlines()]  # "XY path": keep X's blank
    dirty = any(not path.startswith(WRITTEN_HERE) for path in changed)
    return f"{head} (uncommitted changes)" if dirty else head


def _git(root: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, check=True).stdout


def scans_table(stamp: str) -> str:
    rows = [active_scenes.HEADER]
    for name in SCENES:
        scene = active_scenes.load_scene(active_scenes.SCENES / f"{name}.toml")
        settings = active_scenes.BASE[0]
        report, m = active_scenes.scan(scene, "active", settings.learner.max_palpations, 0)
        rows.append(active_scenes.row(name, report, m))
    command = "`palpd scan --scene NAME --strategy active --seed 0` (simulated time, default settings)"
    return "\n".join(rows) + (f"\n\nMeasured at commit {stamp} by `make figures`: each row is {command}. The *-3d "
                               "scenes are 3-D layers pressed through finite elements; their depth error is the "
                               "reported top's against the inclusion's, and in the lump's own sds.\n")


def paper_map(stamp: str) -> str:
    """The paper scene's active scan drawn as `palpd scan --plot` draws it; returns its caption."""
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "report.json"
        subprocess.run([sys.executable, "-m", "palpd", "scan", "--scene", "paper", "--strategy", "active",
                        "--report", str(report), "--plot", str(FIGURES / "paper-map.png")],
                       check=True, capture_output=True, text=True)
        palpations = json.loads(report.read_text())["palpations"]
    return (f"The paper scene's active scan: {palpations} palpations (`palpd scan --scene paper --strategy active "
            f"--plot paper-map.png`, measured at commit {stamp} by `make figures`).\n")


def real_data(stamp: str) -> str:
    """The real dVRK phantom (garg-phantom): its active scan drawn as `palpd scan --plot` draws it, and scored beside
    a raster of the same count (issue 48's "report what it finds against a raster of the same count")."""
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "report.json"
        subprocess.run([sys.executable, "-m", "palpd", "scan", "--scene", REAL_SCENE, "--strategy", "active",
                        "--report", str(report), "--plot", str(FIGURES / f"{REAL_SCENE}-map.png")],
                       check=True, capture_output=True, text=True)
        active = json.loads(report.read_text())  # scored against the truth as the scan's own report is
    palpations = active["palpations"]
    scene = active_scenes.load_scene(active_scenes.scene_path(REAL_SCENE))
    raster, raster_metrics = active_scenes.scan(scene, "raster", palpations, 0)
    rows = [active_scenes.HEADER, active_scenes.row(f"{REAL_SCENE}, active", active, active["metrics"]),
            active_scenes.row(f"{REAL_SCENE}, raster", raster, raster_metrics)]
    return "\n".join(rows) + (f"\n\nMeasured at commit {stamp} by `make figures`: `palpd scan --scene {REAL_SCENE} "
                               f"--strategy active --seed 0` (default settings), then `--strategy raster "
                               f"--max-palpations {palpations}`: the raster's square grid within the active scan's "
                               f"count ({raster['palpations']} palpations). The truth is the map's own half-height "
                               "region; the picture is the active scan's `--plot`.\n")


def learner_table(stamp: str) -> str:
    result = json.loads(subprocess.run([sys.executable, "-m", "palpd", "bench", "learner", "--json"],
                                       check=True, capture_output=True, text=True).stdout)
    fixed, optimised, spikes = result["sklearn_fixed_kernel_ms"], result["sklearn_optimised_ms"], result["spikes"]
    rows = ["| learner update at 200 points, 121² grid | median | largest |", "|---|---|---|",
            f"| palpd (wall) | {result['update_ms']['p50']:.2f} ms | {result['update_ms']['max']:.2f} ms |",
            f"| scikit-learn GP refitted, kernel fixed | {fixed['p50']:.1f} ms | {fixed['max']:.1f} ms |",
            f"| scikit-learn GP refitted, its optimiser | {optimised['p50']:.1f} ms | {optimised['max']:.1f} ms |"]
    load = os.getloadavg()[0]  # wall times: a busy machine reads slower, so the figure says how busy
    # the largest of every update from the first reading on: the refits the median at 200 points never sees
    return "\n".join(rows) + (f"\n\npalpd's every update from the first reading to reading {spikes['to_points']}: "
                              f"the largest {spikes['max_ms']:.1f} ms, at reading {spikes['at_points']}; "
                              f"{result['update_cpu_ms']['over_50_ms']} over 50 ms of CPU time. "
                              f"Measured at commit {stamp} by `make figures` (`palpd bench learner`), "
                              f"load average {load:.1f} on {os.cpu_count()} CPUs.\n")


def shipped_lump_scenes() -> list[str]:
    """The shipped scenes with a lump to find (their truth holds one): what the tolerance's trade is summed over."""
    names = sorted(path.stem for path in active_scenes.SCENES.glob("*.toml"))
    return [name for name in names
            if active_scenes.metrics.scene_truth(active_scenes.load_scene(active_scenes.SCENES / f"{name}.toml"))]


def calibration_table(stamp: str) -> str:
    """`palpd bench calibration` on the shipped lump scenes at three tolerances (the speed-for-accuracy trade, issue
    48), and on random scenes, none shipped, at the tightest and loosest."""
    def bench(*args: str) -> str:
        done = subprocess.run([sys.executable, "-m", "palpd", "bench", "calibration", "--workers", "2", *args,
                               "--out", tempfile.mkdtemp()], check=True, capture_output=True, text=True)
        return "\n".join(line for line in done.stdout.splitlines() if line.startswith("|"))
    shipped = shipped_lump_scenes()
    shipped_args = ("--scenes", *shipped, "--tolerances", "0.25,0.5,2")
    random_args = ("--random", "12", "--tolerances", "0.25,2")
    shipped_table = bench(*shipped_args)
    return (f"{shipped_table}\n\nThe {len(shipped)} shipped scenes with a lump ({trade(shipped_table)}): `palpd bench calibration "
            f"--scenes {' '.join(shipped)} --tolerances 0.25,0.5,2`.\n\n"
            f"{bench(*random_args)}\n\nRandom scenes: `palpd bench calibration {' '.join(random_args)}`. Both measured "
            f"at commit {stamp} by `make figures`.\n")


def trade(table: str) -> str:
    """The speed-for-accuracy trade of a calibration table in one phrase: how many fewer palpations its loosest
    tolerance took than its tightest (the rows are in the order asked, tightest first)."""
    rows = [[cell.strip() for cell in line.split("|")[1:-1]] for line in table.splitlines()[2:] if line.startswith("|")]
    tight, loose = rows[0], rows[-1]
    fewer = 1.0 - float(loose[2]) / float(tight[2])
    return f"{loose[0]} mm took {fewer:.0%} fewer palpations than {tight[0]} mm"


def marked(name: str) -> re.Pattern:
    """What sits between a figure's marker comments in the README."""
    return re.compile(rf"(<!-- figures:{name} -->\n)(.*?)(<!-- /figures:{name} -->)", re.S)


def copy_into_readme(name: str, text: str, readme: Path = ROOT / "README.md") -> None:
    content = readme.read_text()
    readme.write_text(marked(name).sub(lambda m: m.group(1) + text + m.group(3), content))


def main() -> int:
    FIGURES.mkdir(parents=True, exist_ok=True)
    stamp = commit_stamp()
    figures = {"paper-map": paper_map(stamp), "scans": scans_table(stamp), "real-data": real_data(stamp),
               "learner-bench": learner_table(stamp), "calibration": calibration_table(stamp)}
    for name, text in figures.items():
        (FIGURES / f"{name}.md").write_text(text)
        copy_into_readme(name, text)
        print(f"figures: docs/figures/{name}.md", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
