"""A Python client for a running `palpd serve`: commands over its ROUTER socket, typed events from its PUB socket.

    from palpd.client import Client

    with Client() as daemon:                      # endpoints: bus settings (PALPD_BUS__* overrides them)
        daemon.scan(strategy="active", wait=True)
        print(daemon.estimate().estimate.lumps)

Replies and events are the pydantic models of palpd.bus (their JSON Schemas: `palpd schema`).
A refused command raises CommandRefused (with the daemon's error code); no answer in time, TimeoutError.
"""
from __future__ import annotations

import json
import time
import uuid
from pathlib import Path
from typing import Callable, Iterator

import zmq
from pydantic import ValidationError

from palpd.bus.messages import EVENT_MODELS, Event, FaultMsg
from palpd.bus.replies import REPLY_MODELS, EstimateGetReply, Reply, ScanStartReply, StatusReply
from palpd.errors import PalpdError

# How long a command waits for its reply. scan.start builds the scan's learner before it answers (~1.5 s of
# CPU on a 2-core host, its imports the most): beside a busy process that passed 3 s, and palpctl said
# "no reply" to a daemon that had started the scan. A daemon that is not there still fails within this.
DEFAULT_TIMEOUT_S = 10.0
SCAN_ENDED = ("ready", "fault", "stopped")
FAULT_EVENT_WAIT_S = 0.5  # scan(wait=True): how long a fault event may trail the status that ended the scan


class CommandRefused(PalpdError):
    """The daemon answered {"ok": false}: `code` says why (invalid_state, bad_args, forbidden, ...)."""

    def __init__(self, cmd: str, code: str, message: str) -> None:
        super().__init__(f"{cmd} refused ({code}): {message}")
        self.cmd, self.code, self.message = cmd, code, message


def curve_keys(server_key: str | Path | bytes, key: str | Path) -> dict:
    """Socket options for CURVE: the daemon's public key (file or z85) and this client's key pair file."""
    import zmq.auth

    if isinstance(server_key, bytes):
        server_public = server_key
    else:
        server_public, _ = zmq.auth.load_certificate(str(server_key))
    from palpd.bus.keyfiles import secret_key_problem

    problem = secret_key_problem(key)  # as ssh does: a secret key others can read is refused, not used
    if problem:
        raise ValueError(problem)
    public, secret = zmq.auth.load_certificate(str(key))
    if secret is None:
        raise ValueError(f"{key} holds no secret key (use NAME.key_secret from `palpd keygen`)")
    return {"curve_serverkey": server_public, "curve_publickey": public, "curve_secretkey": secret}


class Client:
    """Commands and events of one daemon. CURVE: pass `server_key` (the daemon's public key) and `key`
    (this client's NAME.key_secret); endpoints default to the bus settings (`config` file, PALPD_ variables)."""

    def __init__(self, commands: str | None = None, events: str | None = None, *, timeout_s: float = DEFAULT_TIMEOUT_S,
                 server_key: str | Path | bytes | None = None, key: str | Path | None = None,
                 config: str | Path | None = None) -> None:
        if commands is None or events is None:
            from palpd.config import load_settings

            bus = load_settings(config).bus
            commands, events = commands or bus.commands, events or bus.events
        if (server_key is None) != (key is None):
            raise ValueError("CURVE needs both server_key (the daemon's public key) and key (this client's)")
        self.commands_endpoint, self.events_endpoint, self.timeout_s = commands, events, timeout_s
        self._curve = curve_keys(server_key, key) if key is not None else {}
        self._context = zmq.Context()
        self._dealer = None
        self.last_fault: FaultMsg | None = None  # the fault event heard while scan(wait=True) waited, if any
        self.heard: dict[str, Event] = {}  # the last event of each topic a wait=True command asked for

    # Lifetime ---------------------------------------------------------------------------------------

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._context.destroy(linger=0)

    def _socket(self, kind: int, endpoint: str) -> zmq.Socket:
        socket = self._context.socket(kind)
        socket.setsockopt(zmq.LINGER, 0)
        for option, value in self._curve.items():
            setattr(socket, option, value)
        try:
            socket.connect(endpoint)
        except zmq.ZMQError as exc:  # a typo in an endpoint, named as such rather than as ZeroMQ's errno
            socket.close()
            raise ValueError(f"{endpoint!r} is not an endpoint to connect to (tcp://HOST:PORT or ipc://PATH): "
                             f"{exc}") from None
        return socket

    # Commands ---------------------------------------------------------------------------------------

    def call(self, cmd: str, **args) -> Reply:
        """One command, its typed reply; CommandRefused or TimeoutError otherwise."""
        if self._dealer is None:
            self._dealer = self._socket(zmq.DEALER, self.commands_endpoint)
            self._dealer.setsockopt(zmq.SNDTIMEO, int(self.timeout_s * 1000))  # a refused CURVE handshake: no peer
        request_id = uuid.uuid4().hex
        try:
            self._dealer.send_json({"id": request_id, "cmd": cmd, "args": args})
        except zmq.Again:
            raise TimeoutError(f"cannot reach {self.commands_endpoint} within {self.timeout_s:g} s "
                               "(are the keys right?)") from None
        return self._reply(cmd, request_id)

    def _reply(self, cmd: str, request_id: str) -> Reply:
        give_up = time.monotonic() + self.timeout_s
        while self._dealer.poll(max(1, int((give_up - time.monotonic()) * 1000))):
            body = json.loads(self._dealer.recv())
            if body.get("id") != request_id:
                continue  # the late answer to an earlier request that timed out
            if not body.get("ok"):
                error = body.get("error") or {}
                raise CommandRefused(cmd, error.get("code", "?"), error.get("message", ""))
            return REPLY_MODELS[cmd].model_validate(body)
        self._dealer.close(linger=0)  # a DEALER with a request in flight is of no more use
        self._dealer = None
        raise TimeoutError(f"no reply from {self.commands_endpoint} within {self.timeout_s:g} s "
                           "(is `palpd serve` running, and are the keys right?)")

    def status(self) -> StatusReply:
        return self.call("status")

    def estimate(self) -> EstimateGetReply:
        """The latest estimate, the session's palpations and the learner's posterior map."""
        return self.call("estimate.get")

    def scan(self, strategy: str = "active", *, wait: bool = False, wait_timeout_s: float | None = None,
             **options) -> ScanStartReply | StatusReply:
        """scan.start (options: max_palpations, seed, center_mm, size_mm, depth_mm, speed_mm_s, palpation, resume).

        wait=True: return the status once the scan has ended (ready, or fault: check `.state`; the fault's
        own event, which says what happened, is then `last_fault`).
        """
        args = {"strategy": strategy, **{k: v for k, v in options.items() if v is not None}}
        if not wait:
            return self.call("scan.start", **args)
        return self._call_and_wait("scan.start", args, wait_timeout_s)

    def _call_and_wait(self, cmd: str, args: dict, timeout_s: float | None, topics: tuple[str, ...] = (),
                       complete: Callable[[dict], bool] = lambda heard: True) -> StatusReply:
        """cmd, then the status once the daemon has left `scanning` (its job ended); the fault and the last
        event of each of `topics` heard on the way are kept in last_fault and heard (complete(heard): all
        the job's events are in)."""
        self.last_fault, self.heard = None, {}
        with self._subscription("status", "fault", *topics) as events:
            self.call(cmd, **args)
            status = self._until_scan_ends(events, timeout_s)
            self._hear_trailing(events, status, complete)
            return status

    def _hear_trailing(self, events: zmq.Socket, status: StatusReply, complete: Callable[[dict], bool]) -> None:
        """The events a job published before it ended may trail the status reply (another socket)."""
        give_up = time.monotonic() + FAULT_EVENT_WAIT_S
        while (status.state == "fault" and self.last_fault is None) or not complete(self.heard):
            if not events.poll(max(0, int(1000 * (give_up - time.monotonic())))):
                return
            self._keep_event(events)

    def _until_scan_ends(self, events: zmq.Socket, timeout_s: float | None) -> StatusReply:
        """Status events (a heartbeat comes every status_interval_s) until the state leaves scanning; a fault
        event on the way is kept (the status names a fault only by its code)."""
        give_up = None if timeout_s is None else time.monotonic() + timeout_s
        current = self.status()
        while current.state not in SCAN_ENDED:
            left_s = None if give_up is None else give_up - time.monotonic()
            if left_s is not None and left_s <= 0:
                raise TimeoutError(f"the scan did not end within {timeout_s:g} s")
            if events.poll(int(1000 * min(1.0, left_s if left_s is not None else 1.0))):
                self._keep_event(events)  # any event may be the end
            current = self.status()  # asked every second even when no event came (events on another endpoint)
        return current

    def _keep_event(self, events: zmq.Socket) -> None:
        """The next event: a fault is kept in last_fault, any other in heard[topic]."""
        topic, payload = events.recv_multipart()[:2]
        model = EVENT_MODELS.get(topic.decode(errors="replace"))
        try:
            event = model.model_validate_json(payload) if model is not None else None
        except ValidationError:
            return  # a newer daemon's event this client cannot read: the status's code still says which fault
        if isinstance(event, FaultMsg):
            self.last_fault = event
        elif event is not None:
            self.heard[topic.decode()] = event

    def stop_scan(self) -> Reply:
        return self.call("scan.stop")

    def estop(self) -> Reply:
        return self.call("estop")

    def reset(self) -> Reply:
        return self.call("reset")

    def probe(self, x_mm: float, y_mm: float, *, wait: bool = False,
              wait_timeout_s: float | None = None) -> Reply | StatusReply:
        """One palpation at (x_mm, y_mm), tissue frame. wait=True: return the status once it has ended, with
        what it read in heard["palpation"] (outcome) and heard["stiffness"] (when a fit held), or last_fault."""
        args = {"xy_mm": [float(x_mm), float(y_mm)]}
        if not wait:
            return self.call("probe.at", **args)
        return self._call_and_wait("probe.at", args, wait_timeout_s, ("palpation", "stiffness"), _reading_heard)

    def bias(self, *, wait: bool = False, wait_timeout_s: float | None = None) -> Reply | StatusReply:
        """Tare the force sensor out of contact (the arm moves clear first: a short job). wait=True: return
        the status once the daemon is idle again, so the next command is not refused as busy."""
        if not wait:
            return self.call("bias")
        return self._call_and_wait("bias", {}, wait_timeout_s)

    # Events -----------------------------------------------------------------------------------------

    def _subscription(self, *topics: str) -> zmq.Socket:
        socket = self._socket(zmq.SUB, self.events_endpoint)
        for topic in topics or ("",):
            socket.subscribe(topic)
        return socket

    def events(self, *topics: str, timeout_s: float | None = None,
               stop: Callable[[], bool] | None = None) -> Iterator[Event]:
        """Events as they are published (Status, Palpation, Stiffness, Estimate, FaultMsg), all topics by default.

        Ends when no event came for timeout_s (None: never), or once stop() is true (asked at least every
        0.25 s). A status heartbeat comes at least every second, so a status subscriber always hears from a
        live daemon. One iterator is one subscription: a new one hears nothing published while it connects
        (ZeroMQ's slow joiner), so a long watch keeps one iterator rather than starting one per timeout.
        """
        with self._subscription(*topics) as socket:
            while _poll_in_slices(socket, timeout_s, stop):
                topic, payload = socket.recv_multipart()[:2]
                model = EVENT_MODELS.get(topic.decode(errors="replace"))
                if model is None:
                    continue
                try:
                    yield model.model_validate_json(payload)
                except ValidationError:
                    continue  # a newer daemon's field this client does not know: skip, do not die


POLL_SLICE_S = 0.25


def _reading_heard(heard: dict) -> bool:
    """A palpation's events are in: its palpation, and its stiffness unless the palpation says none follows."""
    palpation = heard.get("palpation")
    return palpation is not None and (palpation.rejected is not None or "stiffness" in heard)


def _poll_in_slices(socket: zmq.Socket, timeout_s: float | None, stop: Callable[[], bool] | None = None) -> bool:
    """socket.poll(timeout) in short slices, so a waiting client hears Ctrl-C or SIGINT within a slice whatever
    the poll does with the interrupted call; True when a message is there, False at the timeout or once
    stop() is true."""
    give_up = None if timeout_s is None else time.monotonic() + timeout_s
    while True:
        if stop is not None and stop():
            return False
        left_s = POLL_SLICE_S if give_up is None else min(POLL_SLICE_S, give_up - time.monotonic())
        if left_s <= 0:
            return False
        if socket.poll(max(1, int(left_s * 1000))):
            return True
