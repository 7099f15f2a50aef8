"""The simulated hardware served over real file descriptors: the bridge over TCP and a pty, Net F/T over UDP.

One SimulatorHost runs everything in one select loop on the wall clock, so a
separate program (or palpd itself) connects to it exactly as to a bench.
Tests run it in a thread; ``palpd simulate`` runs it as its own process.
"""
from __future__ import annotations

import os
import select
import socket
import tty

from drivers.sim.bridge_device import BridgeDevice


class TcpBridgeEndpoint:
    """The bridge on a listening TCP socket (what ``socket://HOST:PORT`` connects to); one client at a time."""

    def __init__(self, device: BridgeDevice, host: str = "127.0.0.1", port: int = 0) -> None:
        self.device = device
        self._listener = socket.create_server((host, port))
        self.address = self._listener.getsockname()[:2]
        self.url = f"socket://{self.address[0]}:{self.address[1]}"
        self._client: socket.socket | None = None
        self.unplugging = False

    def fds(self) -> list:
        if self.unplugging:  # asked from another thread: done here, in the serving thread
            self.unplugging = False
            self._drop_client()
        return [self._listener] + ([self._client] if self._client else [])

    def on_readable(self, fd) -> None:
        if fd is self._listener:
            self._drop_client()
            self._client, _ = self._listener.accept()
            self._client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            return
        try:
            data = self._client.recv(4096)
        except OSError:
            data = b""
        if not data:
            self._drop_client()
            return
        reply = self.device.handle(data)
        if reply:
            self._client.sendall(reply)

    def unplug(self) -> None:
        """Pull the cable: the connection drops at the serving loop's next turn."""
        self.unplugging = True

    def close(self) -> None:
        self._drop_client()
        self._listener.close()

    def _drop_client(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None


class PtyBridgeEndpoint:
    """The bridge behind a pseudo-terminal: the host opens ``serial://<path>`` as if it were a USB-serial adapter."""

    def __init__(self, device: BridgeDevice) -> None:
        self.device = device
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line editing: bytes pass untouched
        self.path = os.ttyname(self._slave)
        self.url = f"serial://{self.path}"
        self.unplugging = False

    def fds(self) -> list:
        if self.unplugging:
            self.unplugging = False
            self.close()
        return [self._master] if self._master is not None else []

    def on_readable(self, fd) -> None:
        try:
            data = os.read(self._master, 4096)
        except OSError:
            return
        reply = self.device.handle(data)
        if reply:
            os.write(self._master, reply)

    def unplug(self) -> None:
        """The adapter disappears at the serving loop's next turn: the host's reads fail."""
        self.unplugging = True

    def close(self) -> None:
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None


class SimulatorHost:
    """Runs endpoints, the world's physics and the bridge watchdog on the wall clock."""

    def __init__(self, world, device: BridgeDevice | None = None) -> None:
        self.world = world
        self.device = device or BridgeDevice(world)
        self.endpoints: list = []

    def add(self, endpoint):
        self.endpoints.append(endpoint)
        return endpoint

    def serve(self, stop, poll_s: float = 0.0005) -> None:
        """Until stop (a threading.Event) is set."""
        while not stop.is_set():
            self.step(poll_s)

    def step(self, timeout_s: float) -> None:
        owners = {id(fd): (fd, e) for e in self.endpoints for fd in e.fds()}
        readable, _, _ = select.select([fd for fd, _ in owners.values()], [], [], timeout_s)
        for fd in readable:
            owners[id(fd)][1].on_readable(fd)
        now = self.world.clock.now()
        self.device.advance(now)
        self.device.check_watchdog(now)
        for endpoint in self.endpoints:
            if hasattr(endpoint, "on_tick"):
                endpoint.on_tick(now)

    def close(self) -> None:
        for endpoint in self.endpoints:
            endpoint.close()
