"""The servo process: it opens the bench itself and runs the 1 kHz loop, sharing no GIL with the daemon.

Samples go out through the shared-memory ring every tick; the pipe carries one
message per task (never per tick): the parent sends a picklable task and gets
back the finished task, or the latched fault, with the loop's state. The
e-stop is a flag in shared memory the loop reads every tick.

On the wall clock the loop never stops ticking: between tasks it holds the last
setpoint while the motors are on (the arm must not sag onto the tissue while
the parent fits a palpation) and writes zero current while they are off, so the
bridge watchdog stays fed and the supervisor keeps watching. In simulated time
nothing happens between tasks: virtual time only passes when the loop sleeps,
so the idle process just waits for the next task (and beats its heart), which
keeps simulated scans deterministic.
"""
from __future__ import annotations

import ctypes
import signal
import sys

from palpd.control.ring import FLAG_FAULT, FLAG_MOTORS_ON, FLAG_TASK, SampleRing
from palpd.errors import PalpdError, ScanFault
from palpd.threads import pin_blas_to_one_thread

IDLE_BEAT_S = 0.05
PR_SET_PDEATHSIG = 1


def servo_main(conn, ring_name: str, settings, scene, seed: int, realtime: bool) -> None:
    """Entry point of the child (multiprocessing spawn)."""
    pin_blas_to_one_thread()  # inherited from a palpd parent already; also when a script started us
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the parent, which tells us to quit
    signal.signal(signal.SIGTERM, _exit_on_signal)
    _die_with_parent()
    ring = SampleRing.attach(ring_name)
    try:
        bench = _open(conn, ring, settings, scene, seed, realtime)
        if bench is not None:
            ServoProcess(conn, ring, bench, realtime).serve()
    finally:
        ring.close()
        conn.close()


def _open(conn, ring: SampleRing, settings, scene, seed, realtime):
    from drivers.errors import DriverError
    from palpd.bench import open_bench

    try:
        bench = open_bench(settings, scene, seed=seed, realtime=realtime)
    except (PalpdError, DriverError) as exc:
        conn.send(("error", exc, None))
        return None
    except Exception as exc:  # anything else would only show as "servo process exited": say what it was
        conn.send(("error", PalpdError(f"cannot open the bench: {type(exc).__name__}: {exc}"), None))
        return None
    from palpd.control.realtime import prepare_realtime, scheduling

    notes = []
    if realtime:  # a virtual-time loop runs flat out: it must not do so at real-time priority
        notes = prepare_realtime()
        for note in notes:
            print(f"palpd: servo: {note}", file=sys.stderr, flush=True)
    got = scheduling() if realtime else f"{scheduling()} (virtual time runs flat out: no real-time priority)"
    ring.beat(bench.clock.now(), 0, 0)  # the clock is readable before the first tick
    conn.send(("ready", {"frame": bench.frame, "tissue_size_mm": bench.tissue_size_mm,
                         "period_s": bench.servo.period_s, "realtime_notes": notes, "scheduling": got}, None))
    return bench


class ServoProcess:
    def __init__(self, conn, ring: SampleRing, bench, realtime: bool) -> None:
        self.conn, self.ring, self.bench, self.realtime = conn, ring, bench, realtime
        self.servo = bench.servo
        self.servo.estop_input = ring
        self.servo.wind_down_input = ring
        self.servo.tick_hook = self._publish
        self._task_running = False
        self._settling = None  # a task begun by RemoteServo.begin, until it settles and is sent back
        self._sent_settled = False

    def _publish(self, tick) -> None:
        servo = self.servo
        flags = (FLAG_MOTORS_ON if servo.motors_on else 0) | (FLAG_FAULT if servo.fault else 0) | \
                (FLAG_TASK if self._task_running else 0)
        self.ring.write(tick, flags)
        self.ring.beat(tick.t_s, servo.timing.ticks + 1, servo.timing.overruns)
        task = self._settling
        if task is not None and task.settled and not task.done:
            # Its result is final: back to the parent now, which fits it while this loop finishes the task
            # (a palpation's lift to clearance), supervised as ever; the end, or its fault, follows as the
            # usual reply. In virtual time this puts the parent's work beside the loop's on the other core.
            self._settling, self._sent_settled = None, True
            self.conn.send(("ok", {"task": task, "fault": None, "settled": True}, self._state()))

    def serve(self) -> None:
        try:
            while True:
                message = self._next_message()
                if message is not None and not self._handle(*message):
                    return
        except (EOFError, BrokenPipeError, ConnectionResetError):
            return  # the parent is gone: stop, motors off
        finally:
            self._faulted(self.servo.stop)  # parked at the rest pose before power-off, even when the parent is gone
            self.servo.robot.close()
            self.servo.sensor.close()

    def _next_message(self):
        """The next command; until it comes, tick (wall clock) or wait with a heartbeat (virtual time)."""
        if not self.realtime:
            # The robot time the parent reads stays the last tick's: the virtual clock has run on by the
            # loop's last sleep, and whether a beat had come before the parent asked made a scan's
            # robot time differ by milliseconds from run to run.
            while not self.conn.poll(IDLE_BEAT_S):
                self.ring.beat(None, self.servo.timing.ticks, self.servo.timing.overruns)
                self.conn.poll(self.servo.period_s)  # a link that fails at once must not spin the loop
            return self.conn.recv()
        while not self.conn.poll(0):
            try:
                self.servo.idle_tick()
            except ScanFault:  # latched, motors off; the parent learns it with its next request
                # The loop is alive even with no robot to tick with (a lost link): its heartbeat says so, or
                # the parent would take it for hung (servo_lost, "no heartbeat") instead of naming the link.
                self.ring.beat(None, self.servo.timing.ticks, self.servo.timing.overruns)
                self.conn.poll(self.servo.period_s)  # a link that fails at once must not spin the loop
        return self.conn.recv()

    def _handle(self, command: str, *args) -> bool:
        servo, payload, kind = self.servo, None, "ok"
        if command == "run":
            payload, kind = self._run(*args)
        elif command == "start":
            payload = self._faulted(servo.start)
        elif command == "stop":
            payload = self._faulted(servo.stop)
        elif command == "reset":
            servo.reset()
        elif command == "tare":
            servo.forces.tare(args[0])
        elif command == "timing":
            payload = servo.timing.summary()
        elif command == "state":
            pass  # the reply carries the state (a fault latched between tasks)
        elif command == "timing_reset":
            servo.timing.reset()
        elif command != "quit":
            kind, payload = "error", PalpdError(f"servo process: unknown command {command!r}")
        self.conn.send((kind, payload, self._state()))
        return command != "quit"

    def _run(self, task, timeout_s: float, early: bool = False):
        """The finished task back, and the fault's message if safety stopped it. `early` (RemoteServo.begin):
        the task is sent back once more before that, when it has settled (_publish); not on the wall clock,
        where a mid-task send would cost the tick it falls in its deadline."""
        self._task_running, self._sent_settled = True, False
        self._settling = task if early and not self.realtime else None
        fault = None
        try:
            self.servo.run(task, timeout_s)
        except ScanFault as exc:
            fault = str(exc)
        finally:
            self._task_running, self._settling = False, None
        if self._sent_settled:  # the parent has the task as it settled: only what came after that
            return {"lift_end": task.lift_end(), "fault": fault}, "ok"
        return {"task": task, "fault": fault}, "ok"

    def _faulted(self, action):
        """Run a motion (start homes, stop parks) as a task: None, or the fault's message if safety stopped it."""
        self._task_running = True
        try:
            action()
        except ScanFault as exc:
            return str(exc)
        finally:
            self._task_running = False
        return None

    def _state(self) -> dict:
        servo, world = self.servo, self.bench.world
        return {"fault": servo.fault, "last_tick": servo.last_tick, "max_contact_force_n": servo.max_contact_force_n,
                "motors_on": servo.motors_on, "bias_n": servo.forces.bias_n, "sensor": servo.health.summary(),
                "amplifiers_on": world.amplifiers_on if world is not None else None,
                "true_max_contact_force_n": servo.true_max_contact_force_n,
                "true_max_indentation_mm": servo.true_max_indentation_mm}


def _exit_on_signal(signum, frame) -> None:
    raise SystemExit(128 + signum)  # unwinds through serve(): motors off on the way out


def _die_with_parent() -> None:
    """Linux: SIGTERM when the parent dies (kill -9 included), so the loop never outlives its daemon."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):
        pass  # elsewhere the closed pipe tells us at the next message
