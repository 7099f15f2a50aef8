"""The servo loop: read -> estimate -> safety -> task -> control -> write, on absolute deadlines.

It runs on whatever clock it is given: the virtual clock in simulation (time
passes only when the loop sleeps) or the wall clock on a bench. An overrun
skips the missed cycles instead of bursting to catch up.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.geometry import TissueFrame
from drivers.interfaces import ForceSample
from drivers.phantom import model
from palpd.control.safety import Fault
from palpd.errors import ScanFault

Vec3 = tuple[float, float, float]


@dataclass(slots=True)
class Tick:
    """What the loop knows at one instant, handed to the safety supervisor and the task."""

    t_s: float
    q: Vec3
    tip_mm: Vec3
    velocity_mm_s: Vec3
    force_tissue_n: Vec3
    normal_force_n: float
    sample: ForceSample
    status: int


class ServoLoop:
    def __init__(self, robot, sensor, clock, frame: TissueFrame, controller, supervisor, forces,
                 rate_hz: float = 1000.0, velocity_filter_hz: float = 100.0) -> None:
        self.robot, self.sensor, self.clock = robot, sensor, clock
        self.frame, self.controller, self.supervisor, self.forces = frame, controller, supervisor, forces
        self.period_s = 1.0 / rate_hz
        self._smoothing = math.exp(-2.0 * math.pi * velocity_filter_hz * self.period_s)
        self._previous_tip: Vec3 | None = None
        self._velocity: Vec3 = (0.0, 0.0, 0.0)
        self.fault = None
        self.ticks = 0
        self.overruns = 0
        self.max_contact_force_n = 0.0
        self.last_tick: Tick | None = None

    def start(self) -> None:
        self.robot.enable()
        self._deadline = self.clock.now()

    def stop(self) -> None:
        self.robot.disable()

    def run(self, task, timeout_s: float = 120.0) -> None:
        """Tick until the task is done; raises ScanFault (motors already off) if safety stops it."""
        if self.fault is not None:
            raise ScanFault(f"fault latched ({self.fault.code}): {self.fault.message}; reset first")
        give_up = self.clock.now() + timeout_s
        while not task.done:
            tick = self._sense()
            fault = self.supervisor.check(tick) or (
                self._timeout_fault(tick) if tick.t_s > give_up else None
            )
            if fault is not None:
                self._trip(fault)
            target = task.step(tick)
            self.robot.write(self.controller.currents(tick.q, tick.tip_mm, tick.velocity_mm_s, target))
            self._wait_for_next_period()

    def _sense(self) -> Tick:
        state = self.robot.read()
        sample = self.sensor.read()
        q = state.angles_rad
        tip_m = self.frame.from_robot(model.forward(q))
        tip = (tip_m[0] * 1000.0, tip_m[1] * 1000.0, tip_m[2] * 1000.0)
        self._update_velocity(tip)
        force = self.forces.tissue_force(sample, q)
        normal = self.forces.normal_force(sample, q, force)
        if normal > self.max_contact_force_n:
            self.max_contact_force_n = normal
        tick = Tick(state.t_s, q, tip, self._velocity, force, normal, sample, state.status)
        self.last_tick = tick
        self.ticks += 1
        return tick

    def _update_velocity(self, tip: Vec3) -> None:
        previous = self._previous_tip
        self._previous_tip = tip
        if previous is None:
            return
        a, rate = self._smoothing, (1.0 - self._smoothing) / self.period_s
        v = self._velocity
        self._velocity = (
            a * v[0] + rate * (tip[0] - previous[0]),
            a * v[1] + rate * (tip[1] - previous[1]),
            a * v[2] + rate * (tip[2] - previous[2]),
        )

    def _wait_for_next_period(self) -> None:
        self._deadline += self.period_s
        now = self.clock.now()
        if now > self._deadline + self.period_s:  # overrun: skip what was missed, never burst
            missed = int((now - self._deadline) / self.period_s)
            self.overruns += missed
            self._deadline += missed * self.period_s
        self.clock.sleep_until(self._deadline)

    def _timeout_fault(self, tick: Tick) -> Fault:
        return Fault("task_timeout", "motion did not finish in time", tick.t_s)

    def _trip(self, fault) -> None:
        self.robot.disable()
        self.fault = fault
        raise ScanFault(f"{fault.code}: {fault.message} at t = {fault.t_s:.3f} s; motors off")

    def reset(self) -> None:
        self.fault = None
