"""What palpd needs from a robot and a force sensor, whatever carries the bytes.

Backends implement these; the simulator is one backend among others.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass

# Status bits a robot reports with each joint state (the bridge protocol carries the same bits).
STATUS_AMPLIFIER_FAULT = 0x01
STATUS_ESTOP = 0x02
STATUS_WATCHDOG_TRIPPED = 0x04
STATUS_OVER_TEMPERATURE = 0x08
STATUS_AMPLIFIERS_ON = 0x10
STATUS_HOLDING = 0x20  # the host went silent: the bridge ramped the currents to the hold it was given

# Flags a force sensor sets on a sample it cannot vouch for.
SAMPLE_SATURATED = 0x01
SAMPLE_INVALID = 0x02
SAMPLE_STALE = 0x04
SAMPLE_GAP = 0x08  # samples were lost just before this one (a sequence gap); counted, not a reason to stop
SAMPLE_REPEAT = 0x10  # no new reading since the last read: this is the last one again (SAMPLE_STALE if it lasts)


@dataclass(slots=True)
class JointState:
    t_s: float
    counts: tuple[int, int, int]
    angles_rad: tuple[float, float, float]
    status: int = 0
    device_t_s: float | None = None  # the device's own clock, when it reports one (t_s is the host's)


@dataclass(slots=True)
class ForceSample:
    """Force (N) and torque (N*mm) on the tool, in the sensor's own frame."""

    t_s: float
    force_n: tuple[float, float, float]
    torque_n_mm: tuple[float, float, float]
    flags: int = 0
    status: int = 0  # the device's own status word, passed on as is (e.g. Net F/T RDT status)


class Robot(abc.ABC):
    """A 3-joint arm driven by motor currents and read through its encoders."""

    @abc.abstractmethod
    def enable(self) -> None:
        """Turn the amplifiers on."""

    @abc.abstractmethod
    def disable(self) -> None:
        """Zero the currents and turn the amplifiers off; must never raise for a healthy link."""

    @abc.abstractmethod
    def read(self) -> JointState: ...

    @abc.abstractmethod
    def write(self, currents_a: tuple[float, float, float], hold_a: tuple[float, float, float] | None = None) -> None:
        """Command motor currents; hold_a is what a device with a watchdog should fall back to if the
        host goes silent (gravity compensation at this pose), None for no current."""

    def close(self) -> None:
        self.disable()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class ForceSensor(abc.ABC):
    """A six-axis force/torque sensor giving timestamped samples."""

    @abc.abstractmethod
    def read(self) -> ForceSample: ...

    def close(self) -> None:
        """Release the device; the default has nothing to release."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
