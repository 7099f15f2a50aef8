"""The simulator as robot and force-sensor backends (registered as ``sim``)."""
from __future__ import annotations

from drivers.errors import DriverInitializationError, DriverOperationError
from drivers.interfaces import ForceSample, ForceSensor, JointState, Robot
from drivers.phantom import model
from drivers.sim.nano17 import FORCE_RANGE_N
from drivers.sim.world import NO_FORCE, SimWorld


class SimRobot(Robot):
    def __init__(self, url: str = "sim://", world: SimWorld | None = None, **_ignored) -> None:
        if world is None:
            raise DriverInitializationError(f"{url}: the simulated robot needs a simulated world (a scene)")
        self.world = world

    def enable(self) -> None:
        if self.world.estop:
            raise DriverOperationError("sim://: cannot enable the amplifiers while the e-stop is pressed")
        self.world.amplifiers_on = True

    def disable(self) -> None:
        self.world.currents_a = NO_FORCE
        self.world.amplifiers_on = False

    def read(self) -> JointState:
        world = self.world
        world.advance_to(world.clock.now())
        counts = world.encoder_counts()
        return JointState(world.t_s, counts, model.counts_to_angles(counts), world.status())

    def write(self, currents_a: model.Vec3, hold_a: model.Vec3 | None = None) -> None:
        """No watchdog on this direct path (it has no wire to go quiet): hold_a is not used."""
        if self.world.amplifiers_on:
            self.world.currents_a = currents_a

    def press_estop(self) -> None:
        self.world.press_estop()


class SimForceSensor(ForceSensor):
    force_range_n = FORCE_RANGE_N

    def __init__(self, url: str = "sim-direct", world: SimWorld | None = None, **_ignored) -> None:
        if world is None:
            raise DriverInitializationError("sim force sensor: needs a simulated world (a scene)")
        self.world = world

    def read(self) -> ForceSample:
        self.world.advance_to(self.world.clock.now())
        return self.world.sensor_sample()
