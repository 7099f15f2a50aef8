"""The parent's side of the servo process: a bench whose servo loop runs in its own process.

`RemoteServo` has the interface run_scan and palpate use on an in-process
ServoLoop (start, run, stop, forces.tare, fault, last_tick, max_contact_force_n,
reset, request_estop, request_wind_down, timing), so the scan code runs unchanged over it. A dead
or hung child is never waited for: it becomes a latched fault within
UNRESPONSIVE_S.
"""
from __future__ import annotations

import multiprocessing
import sys
import threading
import time
import types
from contextlib import contextmanager

from palpd.bench import Bench, check_reach
from palpd.control.process import servo_main
from palpd.control.contact import measure_noise
from palpd.control.forces import zero_of
from palpd.control.ring import FLAG_FAULT, SampleRing
from palpd.control.safety import Fault
from palpd.errors import PalpdError, ScanFault

START_TIMEOUT_S = 60.0  # spawning a Python and importing numpy on a loaded 2-core machine
UNRESPONSIVE_S = 5.0  # no heartbeat for this long: the loop is hung
QUIT_TIMEOUT_S = 5.0
POLL_S = 0.1


class ServoProcessError(PalpdError):
    """The servo process could not be started or stopped answering."""


def open_servo_bench(settings, scene, seed: int = 0, realtime: bool = False) -> Bench:
    """Start the servo process on the bench open_bench would open here; returns the parent's view of it."""
    realtime = realtime or not settings.robot.url.startswith("sim")  # hardware runs on the wall clock, always
    check_reach(settings, scene)  # here, in one line: a child that cannot place the tissue could only die
    if settings.robot.url.startswith("sim") and scene.tissue.is_3d:
        from drivers.sim.mechanics.table import cached_table

        cached_table(scene)  # here, with its progress bar: a first build takes minutes, the child reads the cache
    context = multiprocessing.get_context("spawn")  # never fork a process that holds ZeroMQ threads
    ring = SampleRing.create()
    ours, theirs = context.Pipe()
    process = context.Process(target=servo_main, args=(theirs, ring.name, settings, scene, seed, realtime),
                              name="palpd-servo", daemon=True)
    try:
        with _callers_main_hidden():
            process.start()
    except BaseException:
        ring.close()  # no child, no RemoteServo to close it: the shared memory would outlive us
        raise
    theirs.close()
    servo = RemoteServo(process, ours, ring)
    try:
        info = servo.call("hello", wait_s=START_TIMEOUT_S)
    except ScanFault as exc:
        servo.close()
        raise ServoProcessError(f"the servo process did not start: {servo.fault.message}") from exc
    except BaseException:
        servo.close()
        raise
    servo.period_s, servo.scheduling, servo.realtime = info["period_s"], info["scheduling"], realtime
    return Bench(servo, RemoteClock(servo), info["frame"], info["tissue_size_mm"])


@contextmanager
def _callers_main_hidden():
    """While the child is spawned, an empty `__main__`: multiprocessing would otherwise have the child run
    the caller's script again (a script without an `if __name__ == "__main__"` guard would start a scan in
    the child, and a script read from stdin cannot be found at all). The child needs only palpd."""
    callers_main = sys.modules["__main__"]
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        yield
    finally:
        sys.modules["__main__"] = callers_main


class RemoteClock:
    """The servo loop's clock, as its last tick wrote it (robot time: virtual in simulation)."""

    def __init__(self, servo: "RemoteServo") -> None:
        self.servo = servo

    def now(self) -> float:
        return self.servo.header()["now_s"]


class RemoteForces:
    def __init__(self, servo: "RemoteServo") -> None:
        self.servo = servo
        self.bias_n = (0.0, 0.0, 0.0)
        self.noise = None

    def tare(self, samples) -> None:
        """The child's ForceReader takes the mean of these samples as the sensor's zero; their noise is
        measured here too (the contact thresholds of the palpations sent to the child scale with it)."""
        self.servo.call("tare", list(samples))
        self.bias_n = zero_of(samples)
        self.noise = measure_noise(samples) or self.noise


class RemoteTiming:
    def __init__(self, servo: "RemoteServo") -> None:
        self.servo = servo

    @property
    def ticks(self) -> int:
        return self.servo.header()["ticks"]

    @property
    def overruns(self) -> int:
        return self.servo.header()["overruns"]

    def reset(self) -> None:
        self.servo.call("timing_reset")

    def summary(self) -> dict:
        """The Bench JSON loop figures, computed in the servo process."""
        return self.servo.call("timing")


class RemoteHealth:
    """The servo process's sensor health (palpd.control.health), as its last reply said."""

    def __init__(self) -> None:
        self.last = {"retares": 0, "max_drift_n": 0.0}

    def summary(self) -> dict:
        return dict(self.last)


class RemoteServo:
    def __init__(self, process, conn, ring: SampleRing) -> None:
        self.process, self.conn, self.ring = process, conn, ring
        self.forces, self.timing, self.health = RemoteForces(self), RemoteTiming(self), RemoteHealth()
        self.fault: Fault | None = None
        self.last_tick = None
        self.max_contact_force_n = 0.0
        self.true_max_contact_force_n: float | None = None
        self.true_max_indentation_mm: float | None = None
        self.motors_on = False
        self.amplifiers_on = None
        self.period_s = 0.001
        self.scheduling = ""  # what the process got ("SCHED_FIFO 80"), said in the start-up log
        self.realtime = False  # on the wall clock (else virtual time: the clock stands still between tasks)
        self._lock = threading.Lock()  # one request at a time (the daemon's worker and its command handlers)
        self._beat, self._beat_seen_at = -1, time.monotonic()
        self._closed = False
        self._begun = None  # a task sent back settled (begin) whose end is still to be read from the pipe
        self._unsettled: str | None = None  # the fault that stopped it after it settled, for settle() to raise

    @property
    def pid(self) -> int:
        return self.process.pid

    def start(self) -> None:
        """Amplifiers on and the arm home, supervised; raises ScanFault if safety stopped the homing."""
        stopped_by = self.call("start")
        if stopped_by is not None:
            raise ScanFault(stopped_by)

    def stop(self) -> None:
        """Park at the rest pose, then motors off; raises ScanFault if safety stopped the park. A dead
        child's arm is already in the bridge watchdog's gravity hold."""
        if self.process.is_alive() and not self._closed:
            try:
                stopped_by = self.call("stop")
            except ScanFault:
                return
            if stopped_by is not None:
                raise ScanFault(stopped_by)

    def reset(self) -> None:
        self.ring.set_estop(False)
        self.call("reset")
        self._unsettled = None  # a fault of a begun task's lift is the latched fault just cleared

    def request_estop(self) -> None:
        """The software e-stop: a flag in shared memory the loop reads before it writes its next command."""
        self.ring.set_estop(True)

    def request_wind_down(self, on: bool = True) -> None:
        """Ask the task under way to end gently (a slide lifts off at once): a flag in shared memory."""
        if self.ring is not None:  # closed: there is no task to ask
            self.ring.set_wind_down(on)

    def run(self, task, timeout_s: float = 120.0) -> None:
        """Run the task in the servo process; the finished task's state is copied back into `task`."""
        self.settle()
        done = self.call("run", task, timeout_s)
        task.__dict__.update(done["task"].__dict__)
        if done["fault"] is not None:
            raise ScanFault(done["fault"])

    def begin(self, task, timeout_s: float = 120.0) -> None:
        """As run, but back as soon as the task has `settled` (a palpation lifting out of the press: its
        record is final), with the task as it was then; the servo process finishes it, supervised as ever,
        while the caller works on the result. In virtual time the loop ticks only while a task runs, so
        without this the parent's fits and the loop's ticks take turns on one core. settle() waits for the
        end (`task.lifted` takes what it added) and raises a fault that came after; so does every later
        request, before its own. A task that ends or faults before it settles returns as from run()."""
        self.settle()
        done = self.call("run", task, timeout_s, True, begins=task)
        task.__dict__.update(done["task"].__dict__)
        if not done.get("settled") and done["fault"] is not None:
            raise ScanFault(done["fault"])

    def settle(self) -> None:
        """The task begun last has ended; raises ScanFault if safety stopped it after it settled."""
        with self._lock:
            self._end_begun()
            fault, self._unsettled = self._unsettled, None
        if fault is not None:
            raise ScanFault(fault)

    def _end_begun(self) -> None:
        """Read the end of the task begun last (under the lock: any request waits for it first)."""
        task, self._begun = self._begun, None
        if task is None:
            return
        kind, payload, state = self._receive(None)
        if state is not None:
            self._take(state)
        task.lifted(payload["lift_end"])
        self._unsettled = payload["fault"]

    def header(self) -> dict:
        """The loop's shared-memory header; after close(), as it was last."""
        if self.ring is not None:
            self._last_header = self.ring.header()
        return self._last_header

    @property
    def lost(self) -> bool:
        """The child is gone (or was killed as hung): only a new servo process helps."""
        return (self.fault is not None and self.fault.code == "servo_lost") or not self.process.is_alive()

    def check_idle(self) -> Fault | None:
        """Between tasks: the fault the loop latched on its own (e-stop, robot status) or a lost child, now."""
        if self._closed:
            return self.fault
        if not self.process.is_alive():
            self._latch_lost(f"servo process exited (code {self.process.exitcode})")
        elif self.health_age_s() > UNRESPONSIVE_S:
            self._latch_lost(f"servo loop showed no heartbeat for {UNRESPONSIVE_S:.0f} s")
        elif self.fault is None and self.ring.last_flags() & FLAG_FAULT:
            try:
                self.call("state")  # the reply's state carries the fault
            except ScanFault:
                pass
        return self.fault

    def read_samples(self, since: int | None):
        """(samples, next index, lost) from the ring since `since` (None: from now on); nothing once closed."""
        if self.ring is None:
            return [], since or 0, 0
        if since is None:
            return [], self.ring.written(), 0
        return self.ring.read_new(since)

    def health_age_s(self) -> float:
        """Seconds since the loop last showed it is alive (ticking, or waiting for work)."""
        beat = self.header()["heartbeat"]
        if beat != self._beat:
            self._beat, self._beat_seen_at = beat, time.monotonic()
        return time.monotonic() - self._beat_seen_at

    def call(self, command: str, *args, wait_s: float | None = None, begins=None):
        """One request and its reply. `begins`: the task of a run sent back settled (begin), whose end is
        then the next reply on the pipe: taken under the same lock, so no other thread's request reads it."""
        with self._lock:
            self._end_begun()
            if command != "hello":
                self._send((command, *args))
            kind, payload, state = self._receive(wait_s)
            if begins is not None and kind != "error" and payload.get("settled"):
                self._begun = begins
        if state is not None:
            self._take(state)
        if kind == "error":
            raise payload
        return payload

    def _send(self, message) -> None:
        if self._closed or not self.process.is_alive():
            self._lost("servo process is not running")
        try:
            self.conn.send(message)
        except (BrokenPipeError, ConnectionResetError, EOFError):
            self._lost("servo process closed its pipe")

    def _receive(self, wait_s: float | None):
        give_up = None if wait_s is None else time.monotonic() + wait_s
        self.health_age_s()
        while not self.conn.poll(POLL_S):
            if not self.process.is_alive():
                self._lost(f"servo process exited (code {self.process.exitcode})")
            if give_up is not None and time.monotonic() > give_up:
                self._lost(f"servo process did not answer within {wait_s:.0f} s")
            if give_up is None and self.health_age_s() > UNRESPONSIVE_S:
                self._lost(f"servo loop showed no heartbeat for {UNRESPONSIVE_S:.0f} s")
        try:
            return self.conn.recv()
        except (EOFError, ConnectionResetError):
            self._lost(f"servo process exited (code {self.process.exitcode})")

    def _take(self, state: dict) -> None:
        self.fault, self.last_tick = state["fault"], state["last_tick"]
        self.max_contact_force_n, self.motors_on = state["max_contact_force_n"], state["motors_on"]
        self.forces.bias_n, self.amplifiers_on = state["bias_n"], state["amplifiers_on"]
        self.health.last = state["sensor"]
        self.true_max_contact_force_n = state["true_max_contact_force_n"]
        self.true_max_indentation_mm = state["true_max_indentation_mm"]

    def _lost(self, why: str):
        """The child is gone or hung: kill it (the bridge watchdog cuts the current), latch, raise."""
        self._latch_lost(why)
        raise ScanFault(f"servo_lost: {why}; motors off")

    def _latch_lost(self, why: str) -> None:
        self.process.kill()
        self._closed = True
        t_s = self.last_tick.t_s if self.last_tick is not None else 0.0
        self.fault = Fault("servo_lost", why, t_s)

    def close(self) -> None:
        """Quit the child (motors off on its way out), or kill it if it does not go within QUIT_TIMEOUT_S."""
        if not self._closed and self.process.is_alive():
            try:
                self.call("quit", wait_s=QUIT_TIMEOUT_S)
            except (ScanFault, PalpdError):
                pass
        self._closed = True
        self.process.join(QUIT_TIMEOUT_S)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(QUIT_TIMEOUT_S)
        self.conn.close()
        if self.ring is not None:
            self.header()
            self.ring.close()
            self.ring = None
