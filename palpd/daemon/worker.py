"""The scan worker: runs scans, probes and tares off the bus thread, as tasks for the servo process.

The servo loop itself runs in its own process (palpd/control/process.py); this
thread only sends it one task at a time and fits what comes back, so neither
the bus nor this thread ever shares a GIL with the loop. It talks to the
supervisor only through an inproc PUSH socket (events and job ends) and a stop
flag, so the bus never waits on the robot. The e-stop and the heartbeat the
supervisor turns into systemd WATCHDOG=1 go straight to the servo process's
shared memory.
"""
from __future__ import annotations

import queue
import threading

import zmq

from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.errors import ScanFault
from palpd.scan import run_scan

WORKER_ENDPOINT = "inproc://palpd-worker"
IDLE_WAIT_S = 0.1


class StoppablePlan:
    """A planner that says "no more" once a stop is requested, so the palpation under way finishes."""

    def __init__(self, inner, stop: threading.Event) -> None:
        self.inner, self.stop = inner, stop
        self.expected_total = inner.expected_total

    def next_probe(self):
        return None if self.stop.is_set() else self.inner.next_probe()

    def observe(self, probe) -> None:
        self.inner.observe(probe)


class ScanWorker(threading.Thread):
    def __init__(self, context: zmq.Context, bench, settings) -> None:
        super().__init__(name="palpd-scan", daemon=True)
        self.context, self.bench, self.settings = context, bench, settings
        self.stop_requested = threading.Event()
        self._jobs: queue.Queue = queue.Queue()
        self._quit = False

    def submit(self, job) -> None:
        """job(worker) runs in this thread; a job returning normally ends with a job_end message."""
        self.stop_requested.clear()
        self._jobs.put(job)

    def request_stop(self) -> None:
        """The job plans nothing more, and the task under way winds down (a slide lifts off at once; a
        discrete palpation finishes)."""
        self.stop_requested.set()
        self.bench.servo.request_wind_down()

    def quit(self) -> None:
        self._quit = True
        self._jobs.put(None)

    def run(self) -> None:
        self.out = self.context.socket(zmq.PUSH)
        self.out.connect(WORKER_ENDPOINT)
        try:
            while not self._quit:
                try:
                    job = self._jobs.get(timeout=IDLE_WAIT_S)
                except queue.Empty:
                    continue
                if job is not None:
                    self._run_job(job)
        finally:
            self._park()  # amplifiers off whatever happened (a lost servo process's bridge holds the arm)
            self.out.close(linger=1000)

    def _park(self) -> None:
        """The servo parks the arm at its rest pose and powers off; a fault on the way is latched there."""
        try:
            self.bench.servo.stop()
        except ScanFault:
            pass

    def _run_job(self, job) -> None:
        fault = None
        if not self.stop_requested.is_set():  # a stop asked for before the job began still holds
            self.bench.servo.request_wind_down(False)
        try:
            job(self)
        except ScanFault:
            pass
        except Exception as exc:  # a bug in a job must not kill the thread that owns the robot
            self._park()
            self.send({"kind": "job_end", "fault": {"code": "internal", "message": repr(exc)[:300]}})
            return
        if self.bench.servo.fault is not None:
            fault = self.bench.servo.fault.as_dict()
        self.send({"kind": "job_end", "fault": fault})

    def send(self, message: dict) -> None:
        self.out.send_pyobj(message)

    def event(self, topic: str, **fields) -> None:
        self.send({"kind": "event", "topic": topic, "t": self.bench.clock.now(), "fields": fields})

    # Jobs -------------------------------------------------------------------------------------------

    def scan(self, settings, planner, on_probe) -> dict:
        return run_scan(self.bench, settings, StoppablePlan(planner, self.stop_requested), on_probe)

    def home(self) -> None:
        """Bring the arm to its rest pose (start() homes it, supervised) and power off there."""
        self.bench.servo.start()
        self.bench.servo.stop()

    def tare(self) -> None:
        p, servo = self.settings.palpation, self.bench.servo
        servo.start()
        try:
            above = (0.0, 0.0, p.clearance_mm)
            servo.run(MoveTo(above, p.travel_speed_mm_s, p.accel_mm_s2))
            hold = HoldAndCollect(p.tare_samples, where=above)
            servo.run(hold)
            servo.forces.tare(hold.samples)
        finally:
            servo.stop()
