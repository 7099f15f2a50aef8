"""A Net F/T RDT client over UDP: the Nano17 through ATI's Net F/T box.

The box calibrates on its own and streams counts; the client starts the
stream, keeps the newest record, counts sequence gaps, passes the status word
on and flags what it cannot vouch for. No record for a whole timeout raises
DriverTimeoutError: a stalled or unplugged box never hangs the caller.
"""
from __future__ import annotations

import select
import socket
import time
from urllib.parse import urlsplit

from drivers.errors import DriverInitializationError, DriverOperationError, DriverTimeoutError
from drivers.interfaces import SAMPLE_GAP, SAMPLE_INVALID, SAMPLE_REPEAT, SAMPLE_STALE, ForceSample, ForceSensor
from drivers.nano17 import rdt


class _HostClock:
    def now(self) -> float:
        return time.monotonic()


class NetFtSensor(ForceSensor):
    def __init__(self, host: str, port: int = rdt.PORT, counts_per_force: float = rdt.DEFAULT_COUNTS_PER_UNIT,
                 counts_per_torque: float = rdt.DEFAULT_COUNTS_PER_UNIT, timeout_s: float = 0.05,
                 stale_after_s: float = 0.01, clock=None) -> None:
        self.address, self.timeout_s, self.stale_after_s = (host, port), timeout_s, stale_after_s
        self.clock = clock or _HostClock()
        self._force_scale = 1.0 / counts_per_force
        self._torque_scale = 1000.0 / counts_per_torque  # the box gives N*m; palpd works in N*mm
        self.gaps = 0
        self._last: tuple | None = None
        self._last_wall_s = 0.0
        self._name = f"netft://{host}:{port}"
        self._gap_pending = False
        self._handed_out = False
        try:
            self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._socket.connect(self.address)
            self._socket.setblocking(False)
        except OSError as exc:
            raise DriverInitializationError(f"netft://{host}:{port}: cannot reach the Net F/T: {exc}") from exc
        self._send(rdt.STREAM)
        self._wait_for_records(self.timeout_s)

    def bias(self) -> None:
        """Ask the box to zero itself (software bias) on its current reading."""
        self._send(rdt.SET_SOFTWARE_BIAS)

    def read(self) -> ForceSample:
        fresh = self._drain() or not self._handed_out  # a record no read has returned yet is new
        self._handed_out = True
        if not fresh:
            silent_s = time.monotonic() - self._last_wall_s
            if silent_s > self.timeout_s:
                raise DriverTimeoutError(f"{self._name}: no Net F/T record for {silent_s * 1000:.0f} ms "
                                         f"(timeout {self.timeout_s * 1000:.0f} ms; unplugged or stalled?)")
        _, _, status, counts = self._last
        flags = (0 if status == 0 else SAMPLE_INVALID) | (0 if fresh else SAMPLE_REPEAT)
        if time.monotonic() - self._last_wall_s > self.stale_after_s:
            flags |= SAMPLE_STALE
        if self._gap_pending:
            flags |= SAMPLE_GAP
            self._gap_pending = False
        f, t = self._force_scale, self._torque_scale
        return ForceSample(self.clock.now(), (counts[0] * f, counts[1] * f, counts[2] * f),
                           (counts[3] * t, counts[4] * t, counts[5] * t), flags, status)

    def close(self) -> None:
        try:
            self._send(rdt.STOP)
        except DriverOperationError:
            pass
        self._socket.close()

    def _send(self, command: int) -> None:
        try:
            self._socket.send(rdt.encode_request(command))
        except OSError as exc:
            raise DriverOperationError(f"{self._name}: send failed: {exc}") from exc

    def _drain(self) -> bool:
        """Take every datagram waiting; True when a new record arrived."""
        fresh = False
        while True:
            try:
                data = self._socket.recv(65536)
            except BlockingIOError:
                return fresh
            except OSError as exc:  # e.g. ICMP port unreachable: nobody listens there any more
                raise DriverOperationError(f"{self._name}: {exc}") from exc
            for record in rdt.decode_records(data):
                self._take(record)
                fresh = True

    def _take(self, record: tuple) -> None:
        if self._last is not None:
            missed = (record[0] - self._last[0] - 1) & 0xFFFFFFFF
            if 0 < missed < 0x80000000:
                self.gaps += missed
                self._gap_pending = True
        self._last = record
        self._last_wall_s = time.monotonic()

    def _wait_for_records(self, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while (remaining := deadline - time.monotonic()) > 0:
            if select.select([self._socket], [], [], remaining)[0] and self._drain():
                return
        raise DriverTimeoutError(f"{self._name}: no Net F/T record within "
                                 f"{timeout_s * 1000:.0f} ms (unplugged or stalled?)")


def open_netft_sensor(url: str, clock=None, counts_per_force: float = rdt.DEFAULT_COUNTS_PER_UNIT,
                      counts_per_torque: float = rdt.DEFAULT_COUNTS_PER_UNIT, timeout_s: float = 0.05,
                      stale_after_s: float = 0.01, **_ignored) -> NetFtSensor:
    """``netft://HOST[:PORT]`` (port 49152 by default)."""
    parts = urlsplit(url)
    if not parts.hostname:
        raise DriverInitializationError(f"{url}: expected netft://HOST[:PORT]")
    try:
        port = parts.port or rdt.PORT
    except ValueError:
        raise DriverInitializationError(f"{url}: the port must be a number") from None
    return NetFtSensor(parts.hostname, port, counts_per_force, counts_per_torque, timeout_s, stale_after_s, clock)
