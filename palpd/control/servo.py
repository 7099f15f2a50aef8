"""The servo loop: read -> estimate -> safety -> task -> control -> write, on absolute deadlines.

It runs on whatever clock it is given: the virtual clock in simulation (time
passes only when the loop sleeps) or the wall clock on a bench. An overrun
skips the missed cycles instead of bursting to catch up.

A fault stops the motion before any command of that tick is written: faults
after which the probe can still be trusted to move (force cap, timeout) back it
out first, supervised, for at most retract_timeout_s; every other fault cuts
the current at once. Either way the fault is latched until reset().
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass

from drivers.geometry import TissueFrame
from drivers.interfaces import ForceSample
from drivers.phantom import model
from palpd.control.safety import RETRACTABLE, Fault
from palpd.control.tasks import MoveTo
from palpd.control.timing import TimingStats
from palpd.errors import ScanFault

Vec3 = tuple[float, float, float]
FAULT_HISTORY_TICKS = 20  # samples kept with a fault record
RETRACT_ACCEL_MM_S2 = 5000.0
FORCE_LIMITED_TICKS = 10  # commanding the capped force this long means pushing against something rigid
DEVICE_CLOCK_WRAP_S = 2**32 * 1e-6  # the bridge's microsecond counter is 32 bits
NO_CURRENT = (0.0, 0.0, 0.0)


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
    gap_s: float = 0.0  # since the previous tick, on the host's clock
    sample_gap_s: float = 0.0  # between the two encoder samples: the device's clock when it has one


class ServoLoop:
    def __init__(self, robot, sensor, clock, frame: TissueFrame, controller, supervisor, forces,
                 rate_hz: float = 1000.0, velocity_filter_hz: float = 100.0, safety_settings=None,
                 retract_height_mm: float = 4.0) -> None:
        self.robot, self.sensor, self.clock = robot, sensor, clock
        self.frame, self.controller, self.supervisor, self.forces = frame, controller, supervisor, forces
        self.period_s = 1.0 / rate_hz
        self._filter_rad_s = 2.0 * math.pi * velocity_filter_hz
        self._smoothing = math.exp(-self._filter_rad_s * self.period_s)
        self._previous_tip: Vec3 | None = None
        self._previous_t: float | None = None
        self._previous_device_t: float | None = None
        self._velocity: Vec3 = (0.0, 0.0, 0.0)
        self.retract_speed_mm_s = getattr(safety_settings, "retract_speed_mm_s", 60.0)
        self.retract_timeout_s = getattr(safety_settings, "retract_timeout_s", 0.5)
        self.retract_height_mm = retract_height_mm
        self.fault: Fault | None = None
        self.timing = TimingStats(rate_hz)
        self.max_contact_force_n = 0.0
        self.last_tick: Tick | None = None
        self.history: deque = deque(maxlen=FAULT_HISTORY_TICKS)
        self.tick_hook = None  # called with each Tick after the command is written (recorders, tests)
        self._estop_requested = False
        self.estop_input = None  # an outside e-stop (anything with is_set()), read every tick
        self._limited_ticks = 0
        self.motors_on = False
        self._deadline = clock.now()
        self._hold_mm: Vec3 | None = None  # where idle ticks hold the tip: the last setpoint

    @property
    def ticks(self) -> int:
        return self.timing.ticks

    @property
    def overruns(self) -> int:
        return self.timing.overruns

    def start(self) -> None:
        self.robot.enable()
        self.motors_on = True
        self._hold_mm = None
        self._deadline = self.clock.now()
        self._previous_t = None
        self.supervisor.reset()  # the arm may have been moved by hand while the motors were off

    def stop(self) -> None:
        self.robot.disable()
        self.motors_on = False

    def request_estop(self) -> None:
        """The software e-stop input: the next tick cuts the current and latches a fault."""
        self._estop_requested = True

    def run(self, task, timeout_s: float = 120.0) -> None:
        """Tick until the task is done; raises ScanFault (motors already off) if safety stops it."""
        if self.fault is not None:
            raise ScanFault(f"fault latched ({self.fault.code}): {self.fault.message}; reset first")
        self._resume()
        give_up = self.clock.now() + timeout_s
        while not task.done:
            started = time.perf_counter()
            tick = self._sense()
            fault = self._check(tick, give_up)
            if fault is not None:
                self._controlled_stop(fault, tick)
            self._hold_mm = task.step(tick)
            self.robot.write(self.controller.currents(tick.q, tick.tip_mm, tick.velocity_mm_s, self._hold_mm))
            self._end_tick(tick, started)

    def idle_tick(self) -> None:
        """A tick between tasks (the servo process on the wall clock): hold the last setpoint while the
        motors are on, otherwise write zero current; either way the bridge watchdog stays fed and the
        supervisor keeps watching. Raises ScanFault (motors off) like run()."""
        started = time.perf_counter()
        tick = self._sense()
        if self.motors_on and self.fault is None:
            fault = self._check(tick, math.inf)
            if fault is not None:
                self._controlled_stop(fault, tick)
            if self._hold_mm is None:
                self._hold_mm = tick.tip_mm
            self.robot.write(self.controller.currents(tick.q, tick.tip_mm, tick.velocity_mm_s, self._hold_mm))
        else:
            fault = self._idle_fault(tick)
            self.robot.write(NO_CURRENT)
            if fault is not None:
                self._end_tick(tick, started)
                self._controlled_stop(fault, tick)
        self._end_tick(tick, started)

    def _idle_fault(self, tick: Tick) -> Fault | None:
        """With the motors off only the e-stop and the robot's own status can demand a latched fault."""
        if self.fault is not None:
            return None
        if self._estop_wanted():
            return Fault("estop", "e-stop requested", tick.t_s)
        return self.supervisor.check_device(tick)

    def _estop_wanted(self) -> bool:
        return self._estop_requested or (self.estop_input is not None and self.estop_input.is_set())

    def _resume(self) -> None:
        """Between tasks this in-process loop does not tick; on the wall clock that pause is neither a
        stall nor an encoder jump, so timing and motion checks start afresh (virtual time never pauses)."""
        now = self.clock.now()
        if now > self._deadline + self.period_s:
            self._deadline = now
            self._previous_t = None
            self._previous_tip = None
            self.supervisor.reset()

    def _check(self, tick: Tick, give_up: float) -> Fault | None:
        if self._estop_wanted():
            return Fault("estop", "e-stop requested", tick.t_s)
        fault = self.supervisor.check(tick)
        self._limited_ticks = self._limited_ticks + 1 if self.controller.limited else 0
        if fault is None and self._limited_ticks >= FORCE_LIMITED_TICKS:
            fault = Fault("force_cap", f"commanded force held at the {self.controller.force_limit_n} N cap for "
                          f"{FORCE_LIMITED_TICKS} ticks: pushing against something rigid", tick.t_s)
        if fault is None and tick.t_s > give_up:
            fault = Fault("task_timeout", "motion did not finish in time", tick.t_s)
        return fault

    def _end_tick(self, tick: Tick, started: float) -> None:
        if self.tick_hook is not None:
            self.tick_hook(tick)
        compute_s = time.perf_counter() - started
        lateness_s = self._wait_for_next_period()
        self.timing.record(lateness_s, compute_s)

    def _sense(self) -> Tick:
        state = self.robot.read()
        sample = self.sensor.read()
        q = state.angles_rad
        tip_m = self.frame.from_robot(model.forward(q))
        tip = (tip_m[0] * 1000.0, tip_m[1] * 1000.0, tip_m[2] * 1000.0)
        gap = 0.0 if self._previous_t is None else state.t_s - self._previous_t
        self._previous_t = state.t_s
        sample_gap = self._sample_gap_s(state.device_t_s, gap)
        self._update_velocity(tip, sample_gap)
        force = self.forces.tissue_force(sample, q)
        normal = self.forces.normal_force(sample, q, force)
        if normal > self.max_contact_force_n:
            self.max_contact_force_n = normal
        tick = Tick(state.t_s, q, tip, self._velocity, force, normal, sample, state.status, gap, sample_gap)
        self.last_tick = tick
        self.history.append((tick.t_s, tip, force))
        return tick

    def _sample_gap_s(self, device_t_s: float | None, host_gap_s: float) -> float:
        """The real time between this encoder sample and the previous one. A bridge stamps its samples
        with its own microsecond clock (wrapping at 2**32 us); the host's receive times add the transport's
        jitter, so a late reply followed by a prompt one would shrink the gap and inflate the speed. A
        device clock that stands still or leaps is not believed: the host's gap is used instead."""
        previous, self._previous_device_t = self._previous_device_t, device_t_s
        if device_t_s is None or previous is None or host_gap_s <= 0.0:
            return host_gap_s
        device_gap_s = (device_t_s - previous) % DEVICE_CLOCK_WRAP_S
        return device_gap_s if 0.0 < device_gap_s < 1.0 else host_gap_s

    def _update_velocity(self, tip: Vec3, dt_s: float) -> None:
        """Low-pass filtered differences over the real time between ticks, so a late tick is no speed spike."""
        previous = self._previous_tip
        self._previous_tip = tip
        if previous is None or dt_s <= 0.0:
            return
        a = self._smoothing if dt_s == self.period_s else math.exp(-self._filter_rad_s * dt_s)
        rate = (1.0 - a) / dt_s
        v = self._velocity
        self._velocity = (
            a * v[0] + rate * (tip[0] - previous[0]),
            a * v[1] + rate * (tip[1] - previous[1]),
            a * v[2] + rate * (tip[2] - previous[2]),
        )

    def _wait_for_next_period(self) -> float:
        """Sleep to the next absolute deadline; returns how late the wake-up was (s)."""
        self._deadline += self.period_s
        now = self.clock.now()
        if now > self._deadline + self.period_s:  # overrun: skip what was missed, never burst
            missed = int((now - self._deadline) / self.period_s)
            self.timing.overruns += missed
            self._deadline += missed * self.period_s
        self.clock.sleep_until(self._deadline)
        return max(0.0, self.clock.now() - self._deadline)

    # -- stopping --------------------------------------------------------------------------------
    def _controlled_stop(self, fault: Fault, tick: Tick) -> None:
        fault = Fault(fault.code, fault.message, fault.t_s, tuple(self.history))
        self.fault = fault
        if fault.code in RETRACTABLE and self.motors_on:
            self._retract(tick)
        self.robot.disable()
        self.motors_on = False
        raise ScanFault(f"{fault.code}: {fault.message} at t = {fault.t_s:.3f} s; motors off")

    def _retract(self, tick: Tick) -> None:
        """Back straight out, still supervised; any fault that makes moving unsafe ends it at once."""
        x, y, z = tick.tip_mm
        goal = (x, y, max(z, self.retract_height_mm))
        back_out = MoveTo(goal, self.retract_speed_mm_s, RETRACT_ACCEL_MM_S2, start=tick.tip_mm)
        give_up = tick.t_s + self.retract_timeout_s
        while not back_out.done:
            started = time.perf_counter()
            tick = self._sense()
            fault = self._check(tick, math.inf)
            if tick.t_s > give_up or (fault is not None and fault.code not in RETRACTABLE):
                return
            self.robot.write(self.controller.currents(tick.q, tick.tip_mm, tick.velocity_mm_s, back_out.step(tick)))
            self._end_tick(tick, started)

    def reset(self) -> None:
        """Clear a latched fault (an explicit operator action); the motors stay off until start()."""
        self.fault = None
        self._estop_requested = False
        self.supervisor.reset()
