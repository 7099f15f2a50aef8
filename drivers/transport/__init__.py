"""Byte transports chosen by URL, through a registry of lazily imported modules.

``usb://VID:PID[?serial=SN]`` (pyusb bulk endpoints), ``serial:///dev/ttyUSB0?baud=N``
and any other pyserial URL (``socket://host:port``, ``loop://``, ``spy://``,
``rfc2217://``), and ``sim://`` (the simulated bridge in this process). A
missing library or an absent device fails at open with one line naming what
was looked for; reads and writes time out instead of hanging.
"""
from __future__ import annotations

import abc
from urllib.parse import urlsplit

from drivers.errors import DriverInitializationError

# scheme -> (module, class). pyserial handles every URL it knows under its own scheme.
TRANSPORTS: dict[str, tuple[str, str]] = {
    "usb": ("drivers.transport.usb", "UsbTransport"),
    "serial": ("drivers.transport.serialport", "SerialTransport"),
    "socket": ("drivers.transport.serialport", "SerialTransport"),
    "rfc2217": ("drivers.transport.serialport", "SerialTransport"),
    "loop": ("drivers.transport.serialport", "SerialTransport"),
    "spy": ("drivers.transport.serialport", "SerialTransport"),
    "sim": ("drivers.sim.bridge_device", "SimBridgeTransport"),
}
DEFAULT_TIMEOUT_S = 0.05


class Transport(abc.ABC):
    """A bidirectional byte pipe with timeouts; framing is the codec's business."""

    url: str

    @abc.abstractmethod
    def write(self, data: bytes) -> None:
        """Send all of data or raise DriverTimeoutError / DriverOperationError."""

    @abc.abstractmethod
    def read(self, timeout_s: float) -> bytes:
        """Whatever bytes arrive within timeout_s (at least one), or b"" when none did."""

    def close(self) -> None:
        """Release the device."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def scheme_of(url: str) -> str:
    return urlsplit(url).scheme or url


def open_transport(url: str, timeout_s: float = DEFAULT_TIMEOUT_S, **options) -> Transport:
    """Open the transport url names; options go to its class (e.g. a pyusb backend, a simulated world)."""
    from drivers import load_backend  # late: drivers/__init__ imports this package's registry

    scheme = scheme_of(url)
    if scheme not in TRANSPORTS:
        raise DriverInitializationError(
            f"no transport for {url!r}; known schemes: {', '.join(sorted(TRANSPORTS))}"
        )
    return load_backend(*TRANSPORTS[scheme])(url, timeout_s=timeout_s, **options)
