"""palpd bench drivers: what the wire path costs per servo tick, sim:// + the DAQ layer next to sim-direct.

Each tick does what the servo loop asks of the drivers: read the robot, read
the sensor, write three currents, with the simulated world advancing 1 ms in
simulated time. The sim:// path goes through the bridge codec both ways
(frames, CRC, sequence numbers, thermal limit) and the sensor through the
Nano17 calibration from digitised gauge voltages; sim-direct calls the
simulator. Both run in this process, one after the other, so they compare
side by side; the physics is the same in both and included in both.
"""
from __future__ import annotations

import json
import time

PATHS = {"sim:// + DAQ": ("sim://", "sim"), "sim-direct": ("sim-direct", "sim-direct")}


def add_parser(subparsers):
    drivers = subparsers.add_parser("drivers", help="CPU per servo tick through the codec + DAQ path vs sim-direct")
    drivers.add_argument("--scene", default="paper", metavar="FILE|NAME",
                         help="scene file (TOML) or shipped scene name (default: paper)")
    drivers.add_argument("--ticks", type=int, default=20000, metavar="N", help="ticks per path (default 20000)")
    drivers.add_argument("--json", action="store_true", help="print the figures as JSON")
    return drivers


def run(args) -> int:
    from palpd.errors import UsageError
    from palpd.shipped import load_scene_named

    if not 100 <= args.ticks <= 10_000_000:
        raise UsageError("--ticks must be in [100, 10000000]")
    scene = load_scene_named(args.scene)
    for robot_url, sensor in PATHS.values():  # warm-up: imports and first calls stay out of the figures
        measure(scene, 100, robot_url, sensor)
    results = {name: measure(scene, args.ticks, robot_url, sensor) for name, (robot_url, sensor) in PATHS.items()}
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    for name, r in results.items():
        print(f"{name:13s}: {r['ticks']} ticks, CPU {r['cpu_s']:.3f} s, {r['cpu_us_per_tick']:.1f} us/tick")
    wire, direct = results["sim:// + DAQ"], results["sim-direct"]
    print(f"codec + DAQ path: {wire['cpu_us_per_tick'] - direct['cpu_us_per_tick']:.1f} us/tick more "
          f"({wire['cpu_s'] / direct['cpu_s']:.2f}x the CPU)")
    return 0


def measure(scene, ticks: int, robot_url: str, sensor_backend: str) -> dict:
    import drivers
    from drivers.clock import VirtualClock
    from drivers.sim.world import SimWorld

    world = SimWorld(scene, VirtualClock())
    robot = drivers.open_robot(robot_url, world=world, clock=world.clock)
    sensor = drivers.open_sensor(sensor_backend, world=world, clock=world.clock)
    robot.enable()
    started, t_s = time.process_time(), world.clock.now()
    for _ in range(ticks):
        t_s += 0.001
        world.clock.sleep_until(t_s)
        robot.read()
        sensor.read()
        robot.write((0.0, 0.05, 0.0))  # a gentle lift on joint 2: the arm moves, the encoders change
    cpu_s = time.process_time() - started
    return {"ticks": ticks, "cpu_s": round(cpu_s, 3), "cpu_us_per_tick": round(1e6 * cpu_s / ticks, 2)}
