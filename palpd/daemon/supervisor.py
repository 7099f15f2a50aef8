"""The daemon supervisor: bus, commands, recorder, lifecycle and sd_notify, on one thread that never blocks.

Lifecycle: configure -> ready -> scanning -> (ready | fault) ... -> stopped.
The servo loop runs in its own process; the ScanWorker thread feeds it tasks;
this loop only polls sockets, so status and estimate.get answer at once even
mid-palpation.
"""
from __future__ import annotations

import logging
import signal
import time

import zmq

from palpd.bus.commands import CommandServer
from palpd.bus.messages import SCHEMA_VERSION, recording_schemas
from palpd.bus.publisher import EventPublisher
from palpd.bus.security import Security
from palpd.daemon import handlers, storage
from palpd.daemon.jobs import OLDER_SESSIONS, resolved_scan
from palpd.daemon.learning import make_estimator, scan_settings
from palpd.daemon.mcap import McapWriter, seal
from palpd.daemon.notify import Notifier
from palpd.daemon.samples import SampleDrain
from palpd.daemon.session import ensure_writable, find_unfinished, state_directory
from palpd.daemon.storage_faults import StorageFaults
from palpd.daemon.viewers import open_viewers
from palpd.daemon.worker import WORKER_ENDPOINT, ScanWorker
from palpd.errors import PalpdError
from palpd.files import is_storage_error

POLL_MS = 100
QUIT_GRACE_S = 5.0
log = logging.getLogger("palpd.daemon")


class Supervisor(StorageFaults):
    def __init__(self, settings, bench, reopen_bench=None, security: Security | None = None) -> None:
        self.settings, self.bench = settings, bench
        self.reopen_bench = reopen_bench  # a new servo process after servo_lost (reset)
        self.security = security or Security.from_settings(settings.bus)
        self.storage_cause = ""  # the latched `storage` fault's one line ("" when there is none)
        self._storage_warning = ""
        self._recovered = False
        self.sessions_dir = state_directory(settings.daemon.state_dir) / "sessions"
        try:
            ensure_writable(self.sessions_dir.parent)
        except PalpdError as exc:
            if not is_storage_error(exc):
                raise
            self.storage_cause = f"state directory: {exc}"  # comes up in a fault state that says so (open)
        self.notifier = Notifier()
        self.context = zmq.Context()
        self.state, self.message = "configure", ""
        self.session, self.job, self.recording = None, None, None
        self.probe_session = None  # single palpations (probe.at) of this run, journaled like a scan's
        self._estimator = None  # the whole tissue's, made when first asked for (learning.py)
        self.samples = SampleDrain()
        self.last_estimate = None
        self.last_map = None  # the learner's posterior grid (reply.estimate.get's map), made by the worker
        self.viewers = []  # the live web view and the Foxglove stream: they see every event
        self._terminating = False
        self._last_watchdog = 0.0
        self._last_status_s = 0.0
        self._now_s = 0.0
        self._settling_since: float | None = None  # a category-0 stop: recording until the arm is at rest

    @property
    def estimator(self):
        """The current session's estimator; before any, the whole tissue's (made on first use)."""
        if self._estimator is None:
            self._estimator = make_estimator(self.settings, None, self.bench.tissue_size_mm)
        return self._estimator

    @estimator.setter
    def estimator(self, estimator) -> None:
        self._estimator = estimator

    # Start and stop -----------------------------------------------------------------------------

    def open(self, announce=None) -> None:
        """Bind every endpoint; then announce() (the start-up log lines: nothing is said before a refusal,
        which stays one line), then start the worker, recover and go ready."""
        self._bind()
        if announce is not None:
            announce()
        self._log_endpoints()
        self.inbox = self.context.socket(zmq.PULL)
        self.inbox.bind(WORKER_ENDPOINT)
        self.worker = ScanWorker(self.context, self.bench, self.settings)
        self.worker.start()
        if not self.storage_cause:
            self.recover_storage()
        if self.storage_cause:
            self.storage_fault()  # up and answering status, which names the cause; reset retries once space is back
        else:
            self.set_state("ready", "recovered an unfinished session" if self.session else "")
        self.notifier.ready(self.status_line())

    def _bind(self) -> None:
        self.security.start(self.context)
        try:
            self.events = EventPublisher(self.context, self.settings.bus.events,
                                         self.settings.bus.high_water_mark, self.security)
            self.commands = CommandServer(self.context, self.settings.bus.commands, self.security)
            self.viewers = open_viewers(self.settings.daemon, self.bench.tissue_size_mm)
        except zmq.ZMQError as exc:
            self.close()
            raise PalpdError(f"bus: cannot bind: {exc}") from None
        except PalpdError:
            self.close()
            raise

    def _log_endpoints(self) -> None:
        bus = self.settings.bus
        curve = "CURVE" if self.security.secret_key is not None else "loopback/ipc only, no CURVE"
        log.info("events (PUB) on %s, commands (ROUTER) on %s (%s)", bus.events, bus.commands, curve)
        for viewer in self.viewers:
            log.info("%s on %s", viewer.what, viewer.url)
        if not self.settings.daemon.foxglove:
            log.info("Foxglove live server off (daemon.foxglove = \"127.0.0.1:8765\" turns it on)")
        log.info("servo process: %s", self.bench.servo.scheduling)
        log.info("sessions in %s", self.sessions_dir)

    def _recover(self) -> None:
        session = find_unfinished(self.sessions_dir)
        if session is None:
            self._recovered = True
            return
        self._seal_recordings(session)
        self.session, self._recovered = session, True
        log.info("session %s is unfinished (%d palpations journaled): `scan.start {\"resume\": true}` continues it",
                 session.name, len(session.entries))
        scan = session.meta["scan"] = resolved_scan(OLDER_SESSIONS | session.meta["scan"], self.bench.tissue_size_mm,
                                                    self.settings)
        self.estimator = make_estimator(scan_settings(self.settings, scan), scan, self.bench.tissue_size_mm)
        for entry in session.entries:  # the learner relearns the journal in order: where it left off
            self.estimator.observe(entry["xy_mm"], entry["stiffness_n_per_mm"], entry["stiffness_sd_n_per_mm"] or 0.0,
                                   entry.get("target_xy_mm"), entry.get("outcome"),
                                   entry.get("stiffness_bound_n_per_mm"))
        self.publish("estimate", self.now(), **self.estimator.estimate())
        self.show_map(self.estimator.posterior_map())
        for viewer in self.viewers:
            viewer.probes(handlers.probe_records(session.entries), session.name)

    @staticmethod
    def _seal_recordings(session) -> None:
        for recording in session.path.glob("recording-*.mcap"):
            if seal(recording):  # the crashed run's file, ended properly so Foxglove opens it
                log.warning("session %s: %s was cut short; sealed what it held", session.name, recording.name)

    def close(self) -> None:
        for viewer in self.viewers:
            viewer.close()
        self.viewers = []
        for name in ("commands", "events", "inbox"):
            if hasattr(self, name):
                getattr(self, name).close()
        self.security.stop()
        self.context.destroy(linger=0)  # closes whatever socket is still open: shutting down never waits
        self.notifier.close()

    # The loop --------------------------------------------------------------------------------------

    def serve(self) -> int:
        signal.signal(signal.SIGTERM, self._on_signal)
        signal.signal(signal.SIGINT, self._on_signal)
        poller = zmq.Poller()
        poller.register(self.commands.socket, zmq.POLLIN)
        poller.register(self.inbox, zmq.POLLIN)
        while not self._terminating:
            self._turn(poller)
        self._shut_down(poller)
        return 0

    def _turn(self, poller) -> None:
        ready = dict(poller.poll(POLL_MS))
        if self.inbox in ready:
            self._drain_worker()
        if self.commands.socket in ready:
            for _ in range(100):  # a burst of requests must not starve the worker's events
                if not self.commands.socket.poll(0):
                    break
                command = self.commands.receive()
                if command is not None:
                    handlers.dispatch(self, command)
        if self.recording is not None:
            self._record(self.samples.drain, self.bench.servo, self.recording)
            self._record(self.recording.flush_if_due)
            if self._settling_since is not None:
                self._close_when_at_rest()
        if self.job is None and self.state == "ready":
            self._check_idle_servo()
        if time.monotonic() - self._last_status_s >= self.settings.daemon.status_interval_s:
            self.publish("status", self.now(), **self.status_fields())  # the heartbeat
        self._ping_watchdog()

    def _check_idle_servo(self) -> None:
        """A fault the servo process latched between jobs (bridge e-stop, lost child) is published at once."""
        fault = self.bench.servo.check_idle()
        if fault is not None:
            self.publish("fault", self.now(), code=fault.code, message=fault.message)
            self.set_state("fault", fault.code)

    def _drain_worker(self) -> None:
        while self.inbox.poll(0):
            message = self.inbox.recv_pyobj()
            if message["kind"] == "event":
                self.publish(message["topic"], message["t"], **message["fields"])
            elif message["kind"] == "map":
                self.show_map(message["map"])
            elif message["kind"] == "storage":  # the worker could not journal a palpation
                self.storage_failed(message["what"], message["error"])
            elif message["kind"] == "job_end":
                handlers.job_ended(self, message["fault"])

    def _ping_watchdog(self) -> None:
        """WATCHDOG=1 only while the servo process's heartbeat (in shared memory) shows its loop is alive."""
        interval = self.notifier.watchdog_interval_s
        if interval is None or self.bench.servo.health_age_s() > interval:
            return
        now = time.monotonic()
        if now - self._last_watchdog >= interval / 2:
            self.notifier.watchdog()
            self._last_watchdog = now

    def _on_signal(self, signum, frame) -> None:
        self._terminating = True
        log.info("%s: stopping", signal.Signals(signum).name)

    def _shut_down(self, poller) -> None:
        """Let the palpation under way finish (or abort it), motors off, recordings flushed."""
        self.notifier.stopping()
        if self.job is not None:
            self.job.stop_reason = "terminated"
            self.worker.request_stop()
            self._wait_for_job(poller, self.settings.daemon.stop_timeout_s)
        if self.job is not None:
            self.bench.servo.request_estop()  # the palpation did not finish in time: trip, motors off
            self._wait_for_job(poller, QUIT_GRACE_S)
        self.worker.quit()
        self.worker.join(QUIT_GRACE_S)
        self.samples.drain(self.bench.servo, self.recording)  # the last ticks, before the ring goes away
        self.bench.servo.close()  # the servo process quits with its motors off
        self._drain_worker()
        if self._settling_since is not None:  # the servo process is gone: nothing more moves that it could record
            self.close_recording()
        self.set_state("stopped", "terminated")
        self.close_recording()
        self.close()

    def _wait_for_job(self, poller, timeout_s: float) -> None:
        give_up = time.monotonic() + timeout_s
        while self.job is not None and time.monotonic() < give_up:
            self._turn(poller)

    # Events, state, recording ------------------------------------------------------------------------

    def publish(self, topic: str, t: float, **fields) -> None:
        event = self.events.publish(topic, t, **fields)
        payload = event.model_dump(mode="json")
        if topic == "estimate":
            self.last_estimate = event
        elif topic == "status":
            self._last_status_s = time.monotonic()
        elif topic == "fault":
            log.error("fault %s: %s", event.code, event.message)
        if self.recording is not None:
            self._record(self.recording.write, topic, payload)
        for viewer in self.viewers:
            viewer.event(topic, payload)

    def show_map(self, posterior: dict | None) -> None:
        self.last_map = posterior
        for viewer in self.viewers:
            viewer.map(posterior)

    def set_state(self, state: str, message: str = "") -> None:
        if (state, message) != (self.state, self.message):
            log.info("state %s -> %s%s", self.state, state, f" ({message})" if message else "")
        self.state, self.message = state, message
        self.publish("status", self.now(), **self.status_fields())
        self.notifier.status(self.status_line())

    def now(self) -> float:
        """Robot time; while a lost servo process's shared memory is being closed (reset starts a new one on
        the worker thread), the last time it showed: a status request or heartbeat must never fail on it."""
        try:
            self._now_s = self.bench.clock.now()
        except (TypeError, ValueError, AttributeError):
            pass
        return self._now_s

    def status_event(self) -> dict:
        """The current status as a `status` event carries it (seq: the latest status event's)."""
        return {"v": SCHEMA_VERSION, "seq": self.events.last_seq("status"), "t": self.now(), **self.status_fields()}

    def status_fields(self) -> dict:
        session = self.session
        total = self.job.planner.expected_total if getattr(self.job, "planner", None) else 0
        return {
            "state": self.state, "message": self.message, "palpations": len(session.entries) if session else 0,
            "session": session.name if session else "", "expected_total": total,
            "resumable": bool(session and self.job is None and session.meta["status"] == "unfinished"),
            "samples_lost": self.samples.lost, "samples_dropped": self.samples.dropped,
        }

    def status_line(self) -> str:
        fields = self.status_fields()
        return f"{fields['state']}: {fields['palpations']} palpations" + (f", {self.message}" if self.message else "")

    def open_recording(self, session) -> None:
        path = session.next_recording()
        self.samples.start(self.bench.servo)
        try:
            self.recording = McapWriter(path, recording_schemas())
        except OSError as exc:
            if not is_storage_error(exc):
                raise
            self.recording = storage.DroppedRecording(self.samples)
            self._recording_failed(exc)
            return
        if self.job is not None:
            self.job.recording = path.name

    def end_recording(self, fault: dict | None) -> None:
        """The scan's recording ends now, or after a category-0 stop (the current cut where the arm was: it
        falls or floats) once the arm is at rest, so the recording holds where it came to lie."""
        if fault is None or fault.get("stop_category") != 0 or self.recording is None:
            self.close_recording()
            return
        self.samples.recent.clear()
        self._settling_since = time.monotonic()

    def _close_when_at_rest(self) -> None:
        tip = self.samples.at_rest(self._settling_since, virtual_time=not self.bench.servo.realtime)
        if tip is None:
            return
        waited_s = time.monotonic() - self._settling_since
        log.info("after the stop the arm came to rest with the tip at (%.1f, %.1f, %.1f) mm, %.1f mm %s the tissue "
                 "surface (%.2f s later); recording closed", *tip, abs(tip[2]), "below" if tip[2] < 0 else "above",
                 waited_s)
        self.close_recording()

    def close_recording(self) -> None:
        self._settling_since = None
        if self.recording is not None:
            self._record(self.samples.drain, self.bench.servo, self.recording)
            self.samples.stop()
            self._record(self.recording.close)
            self.recording = None
