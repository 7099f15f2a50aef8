"""pyserial transports: serial ports and every URL pyserial knows (socket://, loop://, spy://, rfc2217://)."""
from __future__ import annotations

import socket
from urllib.parse import parse_qs, urlsplit

import serial

from drivers.errors import DriverInitializationError, DriverOperationError, DriverTimeoutError
from drivers.transport import Transport

DEFAULT_BAUD = 1_000_000


def pyserial_target(url: str) -> tuple[str, int]:
    """(what pyserial opens, baud rate): serial:///dev/ttyUSB0?baud=N becomes ('/dev/ttyUSB0', N)."""
    parts = urlsplit(url)
    if parts.scheme != "serial":
        return url, DEFAULT_BAUD
    query = parse_qs(parts.query)
    try:
        baud = int(query.get("baud", [DEFAULT_BAUD])[0])
    except ValueError:
        raise DriverInitializationError(f"{url}: baud must be a whole number") from None
    path = parts.netloc + parts.path
    if not path:
        raise DriverInitializationError(f"{url}: no device path (expected serial:///dev/ttyUSB0?baud=N)")
    return path, baud


class SerialTransport(Transport):
    def __init__(self, url: str, timeout_s: float = 0.05) -> None:
        self.url = url
        self._timeout_s = timeout_s
        target, baud = pyserial_target(url)
        try:
            self._port = serial.serial_for_url(target, baudrate=baud, timeout=timeout_s, write_timeout=timeout_s)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise DriverInitializationError(f"{url}: cannot open {target}: {exc}") from exc

    def write(self, data: bytes) -> None:
        try:
            self._port.write(data)
        except serial.SerialTimeoutException as exc:
            raise DriverTimeoutError(f"{self.url}: write did not finish within {self._timeout_s * 1000:.0f} ms") from exc
        except (serial.SerialException, OSError) as exc:
            raise DriverOperationError(f"{self.url}: write failed (device unplugged?): {exc}") from exc

    def read(self, timeout_s: float) -> bytes:
        port = self._port
        try:
            if timeout_s != port.timeout:  # reconfiguring costs a system call: only when it changes
                port.timeout = timeout_s
            data = port.read(max(1, port.in_waiting))
            sock = getattr(port, "_socket", None)
            if data and sock is not None:  # socket:// says only 0 or 1 byte waiting: take the rest in one call
                data += _waiting_on(sock)
            return data
        except (serial.SerialException, OSError) as exc:
            raise DriverOperationError(f"{self.url}: read failed (device unplugged?): {exc}") from exc

    def close(self) -> None:
        self._port.close()


def _waiting_on(sock) -> bytes:
    """What has already arrived on a socket, without waiting (a frame read a byte at a time costs a
    select per byte: hundreds of microseconds a servo tick)."""
    try:
        return sock.recv(4096, socket.MSG_DONTWAIT)
    except BlockingIOError:
        return b""
