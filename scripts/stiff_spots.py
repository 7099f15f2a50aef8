"""Stiff spots pressed once and with a gentle second press (palpation.too_stiff = bound vs repalpate).

    .venv/bin/python scripts/stiff_spots.py

Each row: a lump in stiffer tissue (simulated, the real control and fit code), palpated at its centre
with each setting: outcome, presses, the stiffness read (± its sd) or the censored bound.
"""
from __future__ import annotations

from drivers.sim.scene import Scene
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.scan import palpate

CASES = ((5.0, 30.0), (5.0, 50.0), (2.0, 40.0), (5.0, 100.0))  # tissue, lump N/mm


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


if __name__ == "__main__":
    main()
