"""The sensor-drift matrix of issue 51: a raster-16 scan per scene, drift rate and onset, in simulated time.

    .venv/bin/python scripts/drift_matrix.py [--scenes paper stiff-tissue] [--rates -20 -5 5 20] [--onsets 1 3 5]

One row per run: the simulator's true peak force and deepest indentation, against the cap and depth_mm + 1 mm,
and the first fault's code (it should name the sensor: sensor_drift / force_mismatch).
"""
from __future__ import annotations

import argparse

from drivers.sim.scene import FaultAt
from palpd.embedded import run_simulated_scan, scan_settings
from palpd.shipped import load_scene_named

SENSOR_FAULTS = ("sensor_drift",)


def one_run(scene_name: str, rate: float, onset: float, settings) -> dict:
    scene = load_scene_named(scene_name)
    scene = scene.model_copy(update={"faults": {"sensor_drift": FaultAt(at_s=onset, value=rate)}})
    report, _ = run_simulated_scan(settings, scene, in_process=True)
    faults = report["faults"]
    return {"scene": scene_name, "rate": rate, "onset": onset, "force": report["truth"]["max_contact_force_n"],
            "depth": report["truth"]["max_indentation_mm"], "fault": faults[0]["code"] if faults else "-",
            "fault_t": faults[0]["t_s"] if faults else None, "palpations": report["palpations"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["paper", "stiff-tissue"])
    parser.add_argument("--rates", nargs="+", type=float, default=[-20.0, -5.0, 5.0, 20.0])
    parser.add_argument("--onsets", nargs="+", type=float, default=[1.0, 3.0, 5.0])
    args = parser.parse_args()
    settings = scan_settings(strategy="raster", max_palpations=16)
    cap, limit = settings.safety.force_cap_n, settings.palpation.depth_mm + 1.0
    print(f"| scene | drift N/s | onset s | true peak N (cap {cap}) | deepest mm (limit {limit}) | first fault "
          "| after onset, s (drift then, N) | palpations | ok |")
    print("|---|---|---|---|---|---|---|---|---|")
    bad = 0
    for scene in args.scenes:
        for rate in args.rates:
            for onset in args.onsets:
                r = one_run(scene, rate, onset, settings)
                ok = r["force"] <= cap and r["depth"] <= limit and r["fault"] in SENSOR_FAULTS
                bad += not ok
                late = "-" if r["fault_t"] is None else \
                    f"{r['fault_t'] - onset:.3f} ({rate * (r['fault_t'] - onset):+.2f})"
                print(f"| {scene} | {rate:+g} | {onset:g} | {r['force']:.3f} | {r['depth']:.2f} | {r['fault']} | "
                      f"{late} | {r['palpations']} | {'yes' if ok else 'NO'} |", flush=True)
    print(f"\n{bad} of the runs outside the bounds")


if __name__ == "__main__":
    main()
