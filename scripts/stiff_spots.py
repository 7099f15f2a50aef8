"""Stiff spots pressed once and with a gentle second press (palpation.too_stiff = bound vs repalpate).

    .venv/bin/python scripts/stiff_spots.py

Each row of the first table: a lump in stiffer tissue (simulated, the real control and fit code), palpated at
its centre with each setting: outcome, presses, the stiffness read (± its sd) or the censored bound. The second
table presses lumps too stiff to press (100-250 N/mm in 0.5 N/mm tissue, where the probe bounces) ten times
each within 5 mm of their centre, in runs of ten as a scan would: the safety faults met and the highest
contact force between the samples (the simulator's), against the 6 N cap.
"""
from __future__ import annotations

import random

from drivers.sim.scene import Scene
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.errors import ScanFault
from palpd.scan import palpate

CASES = ((5.0, 30.0), (5.0, 50.0), (2.0, 40.0), (5.0, 100.0))  # tissue, lump N/mm
ROCKS = (100.0, 150.0, 250.0)  # lump N/mm in 0.5 N/mm tissue
RUNS, PRESSES = 4, 10


def tared_bench(settings, scene):
    bench = open_simulated_bench(settings, scene)
    bench.servo.start()
    above = (0.0, 0.0, settings.palpation.clearance_mm)
    bench.servo.run(MoveTo(above, settings.palpation.travel_speed_mm_s, settings.palpation.accel_mm_s2))
    tare = HoldAndCollect(settings.palpation.tare_samples, where=above)
    bench.servo.run(tare)
    bench.servo.forces.tare(tare.samples)
    return bench


def reading(probe) -> str:
    if probe.fit is not None:
        return f"{probe.stiffness_n_per_mm:.1f} ± {probe.fit.stiffness_se_n_per_mm:.1f} N/mm"
    if probe.stiffness_bound_n_per_mm is not None:
        return f"{probe.outcome}, k ≥ {probe.stiffness_bound_n_per_mm:.1f} N/mm"
    return probe.outcome


def main() -> None:
    print("| tissue N/mm | lump N/mm | one press (bound) | gentle second press (repalpate, presses) |\n|---|---|---|---|")
    for tissue, lump in CASES:
        scene = Scene(name="stiff", tissue={"stiffness_n_per_mm": tissue}, sensor={"tilt": True},
                      lump=[{"center_mm": (0.0, 0.0), "radius_mm": 10.0, "stiffness_n_per_mm": lump}])
        cells = []
        for mode in ("bound", "repalpate"):
            settings = Settings().updated(palpation={"too_stiff": mode})
            probe = palpate(tared_bench(settings, scene), settings, (0.0, 0.0))
            cells.append(reading(probe) + (f" ({probe.presses})" if mode == "repalpate" else ""))
        print(f"| {tissue:g} | {lump:g} | {cells[0]} | {cells[1]} |")
    print(f"\n| lump N/mm | setting | runs that met a fault (of {RUNS}) | presses made | highest contact force |\n|---|---|---|---|---|")
    for lump in ROCKS:
        for mode in ("bound", "repalpate"):
            faults, presses, peak = 0, 0, 0.0
            for run in range(RUNS):
                made, met, top = pressed_ten_times(lump, mode, seed=run)
                faults, presses, peak = faults + met, presses + made, max(peak, top)
            print(f"| {lump:g} | {mode} | {faults} | {presses} | {peak:.2f} N |")


def pressed_ten_times(lump: float, mode: str, seed: int) -> tuple[int, int, float]:
    """(presses made, 1 if a safety fault stopped the run, the highest true contact force)."""
    scene = Scene(name="rock", seed=seed, tissue={"stiffness_n_per_mm": 0.5}, sensor={"noise_n": 0.01, "tilt": True},
                  lump=[{"center_mm": (0.0, 0.0), "radius_mm": 8.0, "depth_mm": 1.0, "stiffness_n_per_mm": lump}])
    settings = Settings().updated(palpation={"too_stiff": mode})
    bench, rng = tared_bench(settings, scene), random.Random(seed)
    for made in range(PRESSES):
        try:
            palpate(bench, settings, (rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0)))
        except ScanFault:
            return made + 1, 1, bench.world.reset_peak()
    return PRESSES, 0, bench.world.reset_peak()


if __name__ == "__main__":
    main()
