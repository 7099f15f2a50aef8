"""Hardware-facing drivers: robots, force sensors, and the simulator behind the same interfaces.

Backends are found by name through a registry of lazily imported modules, so a
missing vendor library never breaks ``import drivers`` (python-can's BACKENDS).
drivers/ knows devices, never palpation: it must not import palpd.
"""
from __future__ import annotations

import importlib
from urllib.parse import urlsplit

from drivers.errors import DriverError, DriverInitializationError, DriverOperationError, DriverTimeoutError
from drivers.interfaces import ForceSample, ForceSensor, JointState, Robot

from drivers.transport import TRANSPORTS

# scheme/name -> (module, factory). Imported only when asked for.
# Every transport carries the Phantom bridge protocol (sim:// included); "sim-direct" skips the codec
# and calls the simulator directly, kept only to measure what the codec costs.
ROBOT_BACKENDS: dict[str, tuple[str, str]] = {
    **{scheme: ("drivers.phantom.bridge", "open_bridge_robot") for scheme in TRANSPORTS},
    "sim-direct": ("drivers.sim.backend", "SimRobot"),
}
SENSOR_BACKENDS: dict[str, tuple[str, str]] = {
    "sim": ("drivers.sim.daq", "open_sim_sensor"),
    "netft": ("drivers.nano17.netft", "open_netft_sensor"),
    "nidaqmx": ("drivers.nano17.nidaq", "open_nidaqmx_sensor"),
    "sim-direct": ("drivers.sim.backend", "SimForceSensor"),
}

__all__ = [
    "DriverError", "DriverInitializationError", "DriverOperationError", "DriverTimeoutError",
    "ForceSample", "ForceSensor", "JointState", "Robot",
    "ROBOT_BACKENDS", "SENSOR_BACKENDS", "open_robot", "open_sensor", "load_backend",
]


def load_backend(module_name: str, attribute: str):
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise DriverInitializationError(f"backend module {module_name} cannot be imported: {exc}") from exc
    return getattr(module, attribute)


def open_robot(url: str, **options) -> Robot:
    """Open the robot named by url, e.g. ``sim://``."""
    scheme = urlsplit(url).scheme or url
    if scheme not in ROBOT_BACKENDS:
        raise DriverInitializationError(
            f"no robot backend for {url!r}; known schemes: {', '.join(sorted(ROBOT_BACKENDS))}"
        )
    return load_backend(*ROBOT_BACKENDS[scheme])(url, **options)


def open_sensor(url: str, **options) -> ForceSensor:
    """Open the force sensor url names: ``sim``, ``netft://HOST[:PORT]``, ``nidaqmx://Dev1/ai0:5``."""
    scheme = urlsplit(url).scheme or url
    if scheme not in SENSOR_BACKENDS:
        raise DriverInitializationError(
            f"no force sensor backend for {url!r}; known: {', '.join(sorted(SENSOR_BACKENDS))}"
        )
    return load_backend(*SENSOR_BACKENDS[scheme])(url, **options)
