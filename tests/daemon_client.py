"""A test's view of a running `palpd serve`: a real process, driven with nothing but pyzmq and JSON."""
from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path

import zmq

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "config" / "scenes"



def _worker_port_range(low: int = 61000, high: int = 65535) -> tuple[int, int]:
    """Above Linux's ephemeral range (32768-60999), so that a port released here is not taken by some process's
    outgoing connection before the daemon binds it; and a share of it to each pytest-xdist worker, so that two
    workers never pick the same port in the moment between probing it and a daemon binding it (it happened:
    "cannot bind: Address already in use" from a daemon on a port another worker had just probed)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    index = int(worker.removeprefix("gw")) if worker.removeprefix("gw").isdigit() else 0
    share = (high - low + 1) // max(count, 1)
    return low + index * share, low + (index + 1) * share - 1


PORT_RANGE = _worker_port_range()
_pick = random.SystemRandom()  # never a seeded global state (hypothesis seeds `random` inside its examples)
WAKE_MS = 100  # wait_for asks for the status at least this often


def free_loopback_ports(count: int) -> list[int]:
    """Distinct free loopback ports, probed with plain OS sockets: closing one frees its port at once. (A ZeroMQ
    probe closes later, in its context's I/O thread, and a client of that context could connect to it meanwhile:
    a handshake with a dying PUB, and no reply for 30 s.)"""
    probes = []
    try:
        while len(probes) < count:
            probe = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            probes.append(probe)
            try:
                probe.bind(("127.0.0.1", _pick.randint(*PORT_RANGE)))
            except OSError:  # taken: try another
                probes.pop().close()
        return [probe.getsockname()[1] for probe in probes]
    finally:
        for probe in probes:
            probe.close()


class Daemon:
    def __init__(self, tmp_path: Path, scene: str = "paper.toml", realtime: bool = False, env: dict | None = None,
                 args: tuple = ()):
        self.context = zmq.Context()
        events_port, commands_port, http_port = free_loopback_ports(3)
        self.events, self.commands = f"tcp://127.0.0.1:{events_port}", f"tcp://127.0.0.1:{commands_port}"
        self.http = f"http://127.0.0.1:{http_port}/"  # the live view (never the default 8080: others may run one)
        self.state_dir = tmp_path / "state"
        self.env = {**os.environ, "PALPD_BUS__EVENTS": self.events, "PALPD_BUS__COMMANDS": self.commands,
                    "PALPD_DAEMON__HTTP": f"127.0.0.1:{http_port}",
                    "PALPD_DAEMON__STATE_DIR": str(self.state_dir), "PALPD_DAEMON__REALTIME": json.dumps(realtime),
                    "PALPD_DAEMON__SCENE": str(SCENES / scene), **(env or {})}
        self.args = tuple(map(str, args))  # e.g. ("--config", FILE)
        self.process = None
        self._sockets: list[zmq.Socket] = []

    def start(self) -> "Daemon":
        self.process = subprocess.Popen([sys.executable, "-m", "palpd", "serve", *self.args], env=self.env,
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        return self

    def socket(self, kind: int, keys: dict | None = None) -> zmq.Socket:
        socket = self.context.socket(kind)
        socket.setsockopt(zmq.LINGER, 0)
        # A connection whose ZMTP handshake stalls (an accepted connect before the daemon's socket is up) is
        # dropped and retried after 1 s, not after ZeroMQ's default 30 s, the whole of a wait_for.
        socket.setsockopt(zmq.HANDSHAKE_IVL, 1000)
        for option, value in (keys or {}).items():
            setattr(socket, option, value)
        self._sockets.append(socket)
        return socket

    def subscriber(self, *topics: str, keys: dict | None = None) -> zmq.Socket:
        socket = self.socket(zmq.SUB, keys)
        for topic in topics or ("",):
            socket.subscribe(topic)
        socket.connect(self.events)
        return socket

    def dealer(self, keys: dict | None = None) -> zmq.Socket:
        socket = self.socket(zmq.DEALER, keys)
        socket.connect(self.commands)
        return socket

    def call(self, cmd: str, args: dict | None = None, socket=None, timeout_s: float = 20.0) -> dict | None:
        """One request; the reply, or None if none came in time."""
        socket = socket or self.dealer()
        request_id = uuid.uuid4().hex
        socket.setsockopt(zmq.SNDTIMEO, int(timeout_s * 1000))  # a refused handshake leaves no peer to queue for
        try:
            socket.send_json({"id": request_id, "cmd": cmd, "args": args or {}})
        except zmq.Again:
            return None
        give_up = time.monotonic() + timeout_s
        while socket.poll(max(1, int((give_up - time.monotonic()) * 1000))):
            reply = socket.recv_json()
            if reply.get("id") == request_id:
                return reply
        return None

    def wait_for(self, predicate, timeout_s: float = 30.0, what: str = "condition") -> dict:
        """Ask for the status until predicate(status) holds: again whenever the daemon publishes an event, and
        at least every 0.1 s. (Asking back to back kept the daemon answering ~2700 requests a second, a third
        of a core taken from the scan being waited for.)"""
        socket, events = self.dealer(), self.subscriber()  # events: unanswered if the daemon wants CURVE keys
        give_up = time.monotonic() + timeout_s
        while time.monotonic() < give_up:
            reply = self.call("status", socket=socket, timeout_s=min(1.0, max(0.01, give_up - time.monotonic())))
            if reply is not None and predicate(reply):
                return reply
            self.assert_alive()
            if events.poll(WAKE_MS):
                while events.poll(0):
                    events.recv_multipart()
        raise AssertionError(f"timed out waiting for {what}; last status: {reply}")

    def assert_alive(self) -> None:
        if self.process.poll() is not None:
            raise AssertionError(f"daemon exited {self.process.returncode}: {self.process.stderr.read()}")

    def signal(self, signum=signal.SIGTERM) -> None:
        self.process.send_signal(signum)

    def wait(self, timeout_s: float = 30.0) -> int:
        return self.process.wait(timeout_s)

    def close(self) -> None:
        for socket in self._sockets:
            socket.close(linger=0)
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait(10)
        if self.process is not None:
            self.process.stdout.close()
            self.process.stderr.close()
        self.context.term()


def receive(socket: zmq.Socket, timeout_s: float = 20.0):
    """(topic, payload) of the next event, or None."""
    if not socket.poll(int(timeout_s * 1000)):
        return None
    topic, payload = socket.recv_multipart()
    return topic.decode(), json.loads(payload)
