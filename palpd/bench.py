"""Assembling a bench: robot, sensor, clock and servo loop from settings.

A simulated bench builds the simulated world from a scene and opens the same
driver interfaces through the backend registry, so everything above this
module is the code that runs on the real robot.
"""
from __future__ import annotations

from dataclasses import dataclass

import drivers
from drivers.clock import RealClock, VirtualClock
from drivers.geometry import TissueFrame
from drivers.phantom import model
from palpd.control.controller import CartesianPD
from palpd.control.forces import ForceReader
from palpd.control.health import SensorHealth
from palpd.control.safety import NANO17_FORCE_RANGE_N, SafetySupervisor, refuse_unsafe_configuration
from palpd.control.servo import ServoLoop
from palpd.errors import ConfigError


@dataclass
class Bench:
    servo: ServoLoop
    clock: object
    frame: TissueFrame
    tissue_size_mm: tuple[float, float]
    world: object = None  # the simulated world, when there is one


def open_bench(settings, scene, seed: int = 0, realtime: bool = False) -> Bench:
    """The simulated bench in this process for sim://, otherwise the hardware (or a `palpd simulate`) at the URLs."""
    if settings.robot.url.startswith("sim"):
        return open_simulated_bench(settings, scene, seed, realtime)
    return open_hardware_bench(placed_settings(settings, scene), scene)


def placed_settings(settings, scene):
    """The settings a bench runs with: a scene, when given, says where the tissue is and how the sensor is
    mounted (on hardware it says nothing else); without one, the tissue and sensor sections do."""
    if scene is None:
        if settings.robot.url.startswith("sim"):
            raise ConfigError("the simulated bench (robot.url sim://) needs a scene")
        return settings
    return settings.updated(tissue=_placement(scene), sensor=_mount(scene))


def check_reach(settings, scene=None) -> None:
    """Refuse, before any process or device is opened, a tissue placement the arm cannot reach (ConfigError:
    one line naming where the placement comes from)."""
    placed = placed_settings(settings, scene)
    frame = TissueFrame(tuple(v / 1000.0 for v in placed.tissue.origin_mm))
    source = "" if scene is None else f"scene {scene.name!r} (placement.origin_mm, tissue.size_mm): "
    try:
        model.inverse(frame.to_robot((0.0, 0.0, 0.0)))
    except model.UnreachableError as exc:
        raise ConfigError(f"{source}tissue.origin_mm {list(placed.tissue.origin_mm)}: the tissue's centre is out "
                          f"of the arm's reach ({exc})") from None
    try:
        refuse_unsafe_configuration(placed, frame)
    except ConfigError as exc:
        raise ConfigError(f"{source}{exc}") from None


def open_hardware_bench(settings, scene=None) -> Bench:
    """Robot and sensor over their transports, on the wall clock; the scene (if any) only says where the tissue is."""
    clock = RealClock()
    sensor_settings = settings.sensor
    if sensor_settings.backend.startswith("sim"):
        raise ConfigError(f"sensor.backend {sensor_settings.backend!r} needs the simulated robot; "
                          f"robot.url is {settings.robot.url!r}")
    robot = drivers.open_robot(settings.robot.url, **_robot_options(settings, clock))
    try:
        sensor = drivers.open_sensor(
            sensor_settings.backend, clock=clock, timeout_s=sensor_settings.timeout_s,
            stale_after_s=sensor_settings.stale_after_s, calibration_file=sensor_settings.calibration,
            counts_per_force=sensor_settings.counts_per_force, counts_per_torque=sensor_settings.counts_per_torque)
    except drivers.DriverError:
        robot.close()
        raise
    return _assemble(settings, robot, sensor, clock)


def _mount(scene) -> dict:
    return {"mount": "link2" if scene.sensor.tilt else "level"}


def _placement(scene) -> dict:
    return {"origin_mm": scene.placement.origin_mm, "size_mm": scene.tissue.size_mm}


def open_simulated_bench(settings, scene, seed: int = 0, realtime: bool = False) -> Bench:
    settings = placed_settings(settings, scene)
    clock = RealClock() if realtime else VirtualClock()
    world = drivers.load_backend("drivers.sim.world", "SimWorld")(scene, clock, seed=seed)
    # The robot talks the bridge protocol to a simulated bridge, the sensor goes through the DAQ layer.
    robot = drivers.open_robot(settings.robot.url, world=world, **_robot_options(settings, clock))
    sensor = drivers.open_sensor(settings.sensor.backend, world=world, clock=clock)
    return _assemble(settings, robot, sensor, clock, world)


def _robot_options(settings, clock) -> dict:
    robot = settings.robot
    return {"clock": clock, "watchdog_s": robot.watchdog_s, "timeout_s": robot.timeout_s,
            "current_limit_a": robot.current_limit_a}


def _assemble(settings, robot, sensor, clock, world=None) -> Bench:
    frame = TissueFrame(tuple(v / 1000.0 for v in settings.tissue.origin_mm))
    try:
        q_aligned = model.inverse(frame.to_robot((0.0, 0.0, 0.0)))
    except model.UnreachableError as exc:
        raise ConfigError(f"tissue.origin_mm {settings.tissue.origin_mm}: {exc}") from None
    refuse_unsafe_configuration(settings, frame, getattr(sensor, "force_range_n", NANO17_FORCE_RANGE_N))
    forces = ForceReader(settings.palpation.force_axes, settings.sensor.mount == "link2", q_aligned)
    control = settings.control
    supervisor = SafetySupervisor(settings.safety, settings.tissue.size_mm, _home_mm(frame), 1.0 / settings.servo.rate_hz)
    health = SensorHealth(settings.safety, forces, settings.palpation.clearance_mm, 1.0 / settings.servo.rate_hz)
    supervisor.monitors.append(health)
    servo = ServoLoop(
        robot, sensor, clock, frame,
        CartesianPD(control.stiffness_n_per_mm, control.damping_n_s_per_mm, settings.robot.current_limit_a,
                    settings.safety.force_cap_n),
        supervisor, forces, settings.servo.rate_hz, control.velocity_filter_hz,
        safety_settings=settings.safety, retract_height_mm=settings.palpation.clearance_mm,
    )
    servo.health = health  # its summary (re-tares, largest drift) goes into the scan report
    return Bench(servo, clock, frame, settings.tissue.size_mm, world)


def _home_mm(frame: TissueFrame) -> tuple[float, float, float]:
    """Where the tip rests at home (all joints zero), in the tissue frame."""
    return tuple(1000.0 * v for v in frame.from_robot(model.forward((0.0, 0.0, 0.0))))  # type: ignore[return-value]
