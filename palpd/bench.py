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
from palpd.control.controller import READING_AGE_PERIODS, CartesianPD
from palpd.control.forces import ForceReader
from palpd.control.health import SensorHealth
from palpd.control.limits import NANO17_FORCE_RANGE_N, refuse_unsafe_configuration, rest_pose_mm
from palpd.control.safety import SafetySupervisor
from palpd.control.servo import ServoLoop
from palpd.control.surface import SurfaceGuard
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
    # The reply to a tick's command is the next tick's reading unless that tick comes late.
    return {"clock": clock, "watchdog_s": robot.watchdog_s, "timeout_s": robot.timeout_s,
            "current_limit_a": robot.current_limit_a, "hold_after_s": robot.hold_after_s,
            "hold_ramp_s": robot.hold_ramp_s, "reply_fresh_s": READING_AGE_PERIODS / settings.servo.rate_hz}


def _assemble(settings, robot, sensor, clock, world=None) -> Bench:
    frame = TissueFrame(tuple(v / 1000.0 for v in settings.tissue.origin_mm))
    try:
        q_aligned = model.inverse(frame.to_robot((0.0, 0.0, 0.0)))
    except model.UnreachableError as exc:
        raise ConfigError(f"tissue.origin_mm {settings.tissue.origin_mm}: {exc}") from None
    refuse_unsafe_configuration(settings, frame, getattr(sensor, "force_range_n", NANO17_FORCE_RANGE_N))
    forces = ForceReader(settings.palpation.force_axes, settings.sensor.mount == "link2", q_aligned)
    control, period_s = settings.control, 1.0 / settings.servo.rate_hz
    # No command stays on longer than the bridge's hold plus half its ramp: the gains are designed for that.
    max_hold_s = settings.robot.hold_after_s + settings.robot.hold_ramp_s / 2
    supervisor = SafetySupervisor(settings.safety, settings.tissue.size_mm, rest_pose_mm(frame), period_s)
    health = SensorHealth(settings.safety, forces, settings.palpation.clearance_mm, period_s)
    surface = SurfaceGuard(settings.palpation, settings.safety)
    supervisor.add_monitor(surface)  # each monitor goes first among them: the sensor's own checks name the cause
    supervisor.add_monitor(health)
    servo = ServoLoop(
        robot, sensor, clock, frame,
        CartesianPD(control.stiffness_n_per_mm, control.damping_n_s_per_mm, settings.robot.current_limit_a,
                    settings.safety.force_cap_n, period_s, max_hold_s, control.velocity_filter_hz),
        supervisor,
        forces, settings.servo.rate_hz, control.velocity_filter_hz,
        safety_settings=settings.safety, clear_z_mm=settings.palpation.clearance_mm, truth=world,
        drift_after_s=settings.robot.hold_after_s + settings.robot.hold_ramp_s,
    )
    servo.health = health  # its summary (re-tares, largest drift) goes into the scan report
    servo.surface = surface
    return Bench(servo, clock, frame, settings.tissue.size_mm, world)
