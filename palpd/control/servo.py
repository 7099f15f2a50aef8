"""The servo loop: read -> estimate -> safety -> task -> control -> write, on absolute deadlines.

It runs on whatever clock it is given: the virtual clock in simulation (time
passes only when the loop sleeps) or the wall clock on a bench. An overrun
skips the missed cycles instead of bursting to catch up. Tasks move on the
loop's own tick clock (one period per tick), so a late host pauses the motion.

A fault stops the motion before any command of that tick is written, by its
stop category (palpd/control/stopping.py): category 0 cuts the current at
once; category 1 backs the probe out along the tissue normal, parks the arm at
its rest pose and only then powers off. Either way the fault is latched until
reset(). stop() parks at the rest pose before the amplifiers go off, too.
"""
from __future__ import annotations

import math
import time
from collections import deque

from drivers.errors import DriverError
from drivers.geometry import TissueFrame
from drivers.interfaces import ForceSample
from palpd.control.limits import rest_pose_mm
from palpd.control.rejoin import Rejoin
from palpd.control.sensing import DEVICE_CLOCK_WRAP_S, Sensing, Tick  # noqa: F401 (both importable from here)
from palpd.control.safety import Fault
from palpd.control.stopping import Stopping
from palpd.control.timing import TimingStats
from palpd.errors import ScanFault

Vec3 = tuple[float, float, float]
FAULT_HISTORY_TICKS = 20  # samples kept with a fault record
NO_OFFSET = (0.0, 0.0, 0.0)
NO_CURRENT = (0.0, 0.0, 0.0)
JUMP_ACCEL_MM_S2 = 10000.0  # a path's velocity changing faster than this is a jump (a new task, a release), not motion


class ServoLoop(Sensing, Stopping):
    def __init__(self, robot, sensor, clock, frame: TissueFrame, controller, supervisor, forces,
                 rate_hz: float = 1000.0, velocity_filter_hz: float = 100.0, safety_settings=None,
                 clear_z_mm: float = 4.0, truth=None, drift_after_s: float | None = None) -> None:
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
        self._max_setpoint_speed_sq = getattr(safety_settings, "max_tip_speed_mm_s", 400.0) ** 2
        self.clear_z_mm = clear_z_mm  # how high above the tissue a stop backs out before it parks
        self.rest_mm = rest_pose_mm(frame)  # where the arm is parked before the amplifiers go off
        self.truth = truth  # the simulated world, when there is one: the true contact force
        self._sim_cpu_s = truth.cpu_s if truth is not None else 0.0
        self.fault: Fault | None = None
        self._unsettled: ScanFault | None = None  # a fault of a task begun (begin) after it settled
        self.timing = TimingStats(rate_hz)
        self.max_contact_force_n = 0.0
        self.last_tick: Tick | None = None
        self.history: deque = deque(maxlen=FAULT_HISTORY_TICKS)
        self.tick_hook = None  # called with each Tick after the command is written (recorders, tests)
        self._estop_requested = False
        self.estop_input = None  # an outside e-stop (anything with is_set()), read every tick
        self._wind_down_requested = False
        self.wind_down_input = None  # an outside wind-down request (anything with wind_down_wanted())
        self.motors_on = False
        self._deadline = clock.now()
        self._motion_t = 0.0
        self._lost_s = 0.0
        self._setpoint: Vec3 | None = None  # the last command's target, rejoin offset included
        # The path's own last target (no offset): idle ticks hold it. Holding _setpoint instead added the
        # offset again on every tick a rejoin was under way: a 20 ms late idle tick walked the arm 8 mm at
        # 350 mm/s (the speed fault a loaded CI run met between a scan's last palpation and its park).
        self._hold_mm: Vec3 | None = None
        self._error: Vec3 | None = None  # tip minus target when the last command went out
        self.rejoin = Rejoin(self.period_s)  # the drift over a late tick, being taken back
        # A gap longer than this left the arm in the bridge's gravity hold (its hold plus its ramp): it drifted.
        self.drift_after_s = drift_after_s if drift_after_s is not None else 2.5 * self.period_s
        self._velocity_error: Vec3 = NO_OFFSET
        self._task_target: Vec3 | None = None  # the task's own last target (without the offset)
        self._path_v: Vec3 = NO_OFFSET
        self._path_accel: Vec3 = NO_OFFSET  # how the path's velocity changed at the last command (the arm's inertia)
        self._sensor_lost: str | None = None
        self._last_sample: ForceSample | None = None
        self.surface = None  # where the tissue surface is (palpd.control.surface.SurfaceGuard): tasks keep above its floor

    @property
    def ticks(self) -> int:
        return self.timing.ticks

    @property
    def overruns(self) -> int:
        return self.timing.overruns

    @property
    def true_max_contact_force_n(self) -> float | None:
        """In simulation, the world's own peak contact force since start(); None on hardware."""
        return None if self.truth is None else self.truth.max_contact_force_n

    @property
    def true_max_indentation_mm(self) -> float | None:
        """In simulation, the tip's deepest position below the true surface since start(); None on hardware."""
        return None if self.truth is None else self.truth.max_indentation_mm

    def start(self, home: bool = True) -> None:
        """Amplifiers on, then (home=True) the arm back to its rest pose from wherever it lies, supervised:
        straight up off the tissue first (after a category-0 stop it may have fallen onto it). Raises ScanFault
        (motors off) if safety stops that. The first tick comes a period after the enable and reads its reply
        (one exchange a tick). home=False is for a person holding the arm (a manual session). A bridge that
        does not answer the enable is a robot_link fault (ScanFault), as it is mid-task."""
        try:
            self.robot.enable()
        except DriverError as exc:
            self._link_lost(exc)
        self.motors_on = True
        self._setpoint, self._hold_mm, self._error, self._task_target = None, None, None, None
        self.rejoin.reset()
        self._sensor_lost = None
        self._deadline = self.clock.now() + self.period_s
        self.clock.sleep_until(self._deadline)
        self._previous_t = None
        # Deadlines missed before the enable (an idle tick, the servo process's start-up: on a cold machine
        # its mlockall takes 40-370 ms) were not the supervised loop's: charged to the homing's first tick
        # they made a loop_stall at start().
        self._lost_s = 0.0
        self.supervisor.reset()  # the arm may have been moved by hand while the motors were off
        if self.surface is not None:
            self.surface.forget()  # a new scan: the tissue may have been moved
        if self.truth is not None:
            self.truth.reset_peak()
        if home:
            self.home()

    def request_estop(self) -> None:
        """The software e-stop input: the next tick cuts the current and latches a fault."""
        self._estop_requested = True

    def request_wind_down(self, on: bool = True) -> None:
        """Ask the task under way to end gently (a slide lifts off at once); cleared with on=False."""
        self._wind_down_requested = on

    def _wind_down_wanted(self) -> bool:
        return self._wind_down_requested or (self.wind_down_input is not None and self.wind_down_input.wind_down_wanted())

    def begin(self, task, timeout_s: float = 120.0) -> None:
        """run() for a caller that goes on with the task's result once it has `settled` and calls settle()
        before anything else (RemoteServo.begin returns there while the servo process finishes the task). In
        process the task runs to its end here; a fault after it settled is raised by settle(), as there."""
        self.settle()
        try:
            self.run(task, timeout_s)
        except ScanFault as exc:
            if not getattr(task, "settled", False):
                raise
            self._unsettled = exc

    def settle(self) -> None:
        """The task begun last has ended: raises the ScanFault that stopped it after it settled."""
        fault, self._unsettled = self._unsettled, None
        if fault is not None:
            raise fault

    def run(self, task, timeout_s: float = 120.0) -> None:
        """Tick until the task is done; raises ScanFault (motors already off) if safety stops it.
        A task with wind_down() hears a wind-down request on the tick it comes."""
        self.settle()
        if self.fault is not None:
            raise ScanFault(f"fault latched ({self.fault.code}): {self.fault.message}; reset first")
        self._resume()
        give_up = self.clock.now() + timeout_s
        widen = getattr(task, "from_anywhere", False)
        wind_down = getattr(task, "wind_down", None)
        declares_jumps = hasattr(task, "jumped")  # a palpation's release (control.palpation): no speed in it
        self.supervisor.guided_by_hand(getattr(task, "follows_hand", False))
        try:
            while not task.done:
                started = time.perf_counter()
                tick = self._sense()
                if widen:
                    self.supervisor.widen_to(tick)
                    widen = False
                if wind_down is not None and self._wind_down_wanted():
                    wind_down()
                    wind_down = None
                fault = self._check(tick, give_up)
                if fault is not None:
                    self._stop_for(fault, tick)
                target = task.step(tick)
                if declares_jumps and task.jumped:
                    task.jumped, self._task_target = False, None
                self._command(tick, target)
                self._end_tick(tick, started)
            if self.surface is not None:
                self.surface.learn(task)
        except DriverError as exc:
            self._link_lost(exc)
        finally:
            if getattr(task, "from_anywhere", False):
                self.supervisor.narrow()

    def idle_tick(self) -> None:
        """A tick between tasks (the servo process on the wall clock): hold the last setpoint while the
        motors are on, otherwise write zero current; either way the bridge watchdog stays fed and the
        supervisor keeps watching. Raises ScanFault (motors off) like run()."""
        started = time.perf_counter()
        try:
            tick = self._sense()
            if self.motors_on and self.fault is None:
                fault = self._check(tick, math.inf)
                if fault is not None:
                    self._stop_for(fault, tick)
                self._command(tick, tick.tip_mm if self._hold_mm is None else self._hold_mm)
            else:
                self.robot.write(NO_CURRENT)
                fault = self._idle_fault(tick)
                if fault is not None:
                    self._end_tick(tick, started)
                    self._stop_for(fault, tick)
        except DriverError as exc:
            self._link_lost(exc)
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
            self._lost_s = 0.0
            self._previous_t = None
            self._previous_tip = None
            self.supervisor.reset()

    def _check(self, tick: Tick, give_up: float) -> Fault | None:
        if self._estop_wanted():
            return Fault("estop", "e-stop requested", tick.t_s)
        if self._sensor_lost is not None:
            return Fault("sensor_link", self._sensor_lost, tick.t_s)
        fault = self.supervisor.check(tick)
        if fault is None and tick.t_s > give_up:
            fault = Fault("task_timeout", "motion did not finish in time", tick.t_s)
        return fault

    def _command(self, tick: Tick, target: Vec3) -> None:
        """Write the currents that take the tip to the task's target, rejoining the path after a late tick."""
        velocity = self._path_velocity(target)
        self._path_accel = self._path_acceleration(velocity)
        self._hold_mm = target
        rejoin = self.rejoin
        if tick.gap_s > self.drift_after_s and self._error is not None:
            rejoin.drifted(tick.tip_mm, tick.velocity_mm_s, target, velocity, self._error, self._velocity_error)
        if rejoin.active:
            (ox, oy, oz), (wx, wy, wz) = rejoin.step(math.sqrt(sum(v * v for v in velocity)))
            target = (target[0] + ox, target[1] + oy, target[2] + oz)
            velocity = (velocity[0] + wx, velocity[1] + wy, velocity[2] + wz)
        controller = self.controller
        currents = controller.currents(tick.q, tick.tip_mm, tick.velocity_mm_s, target, velocity, tick.gap_s)
        self._setpoint = target
        tip, v = tick.tip_mm, tick.velocity_mm_s
        self._error = (tip[0] - target[0], tip[1] - target[1], tip[2] - target[2])
        self._velocity_error = (v[0] - velocity[0], v[1] - velocity[1], v[2] - velocity[2])
        self.robot.write(currents, controller.hold_a)

    def _path_velocity(self, target: Vec3) -> Vec3:
        """How fast the task's target moves on the tick clock; a jump (a new task's first target) is no velocity."""
        previous, self._task_target = self._task_target, target
        if previous is None:
            return NO_OFFSET
        rate = 1.0 / self.period_s
        v = ((target[0] - previous[0]) * rate, (target[1] - previous[1]) * rate, (target[2] - previous[2]) * rate)
        return v if v[0] * v[0] + v[1] * v[1] + v[2] * v[2] <= self._max_setpoint_speed_sq else NO_OFFSET

    def _path_acceleration(self, velocity: Vec3) -> Vec3:
        previous, self._path_v = self._path_v, velocity
        rate = 1.0 / self.period_s
        a = ((velocity[0] - previous[0]) * rate, (velocity[1] - previous[1]) * rate, (velocity[2] - previous[2]) * rate)
        return a if a[0] * a[0] + a[1] * a[1] + a[2] * a[2] <= JUMP_ACCEL_MM_S2 ** 2 else NO_OFFSET

    def _end_tick(self, tick: Tick, started: float) -> None:
        if self.tick_hook is not None:
            self.tick_hook(tick)
        compute_s = time.perf_counter() - started
        sim_s = 0.0
        if self.truth is not None:  # the simulated devices' share of this tick, for the benchmark
            sim_s, self._sim_cpu_s = self.truth.cpu_s - self._sim_cpu_s, self.truth.cpu_s
        lateness_s = self._wait_for_next_period()
        self.timing.record(lateness_s, compute_s, sim_s)

    def _wait_for_next_period(self) -> float:
        """Sleep to the next absolute deadline; returns how late the wake-up was (s)."""
        self._deadline += self.period_s
        now = self.clock.now()
        if now > self._deadline:  # overrun: skip what was missed (to the next deadline ahead), never burst
            missed = int((now - self._deadline) / self.period_s) + 1
            self.timing.overruns += missed
            self._deadline += missed * self.period_s
            self._lost_s += missed * self.period_s
        self.clock.sleep_until(self._deadline)
        return max(0.0, self.clock.now() - self._deadline)

    def reset(self) -> None:
        """Clear a latched fault (an explicit operator action); the motors stay off until start()."""
        self.fault, self._unsettled = None, None  # (a fault of a begun task's lift is that latched fault)
        self._estop_requested = False
        self.supervisor.reset()
