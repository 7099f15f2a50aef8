"""pyusb transport: the bridge board's bulk IN/OUT endpoints, found by vendor and product id."""
from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

from drivers.errors import DriverInitializationError, DriverOperationError, DriverTimeoutError
from drivers.transport import Transport

PACKET_BYTES = 64


def parse_usb_url(url: str) -> tuple[int, int, str | None]:
    """usb://VID:PID[?serial=SN] with hexadecimal ids -> (vid, pid, serial)."""
    parts = urlsplit(url)
    try:
        vid_text, pid_text = parts.netloc.split(":")
        vid, pid = int(vid_text, 16), int(pid_text, 16)
    except ValueError:
        raise DriverInitializationError(f"{url}: expected usb://VID:PID with hexadecimal ids, e.g. usb://1209:7a10") from None
    return vid, pid, parse_qs(parts.query).get("serial", [None])[0]


class UsbTransport(Transport):
    def __init__(self, url: str, timeout_s: float = 0.05, backend=None) -> None:
        import usb.core
        import usb.util

        self.url, self._usb = url, usb
        self._timeout_ms = max(1, int(timeout_s * 1000))
        vid, pid, serial_number = parse_usb_url(url)
        wanted = {"idVendor": vid, "idProduct": pid}
        if serial_number is not None:
            wanted["serial_number"] = serial_number
        try:
            device = usb.core.find(backend=backend, **wanted)
        except (usb.core.NoBackendError, usb.core.USBError, ValueError) as exc:
            raise DriverInitializationError(f"{url}: cannot search the USB bus: {exc}") from exc
        if device is None:
            extra = f" with serial {serial_number}" if serial_number else ""
            raise DriverInitializationError(f"{url}: no USB device {vid:04x}:{pid:04x}{extra} found")
        self._device = device
        self._out, self._in = self._bulk_endpoints(device)

    def _bulk_endpoints(self, device):
        usb = self._usb
        try:
            device.set_configuration()
            interface = device.get_active_configuration()[(0, 0)]
        except usb.core.USBError as exc:
            raise DriverInitializationError(f"{self.url}: cannot configure the device: {exc}") from exc

        def direction(d):
            return lambda ep: usb.util.endpoint_direction(ep.bEndpointAddress) == d \
                and usb.util.endpoint_type(ep.bmAttributes) == usb.util.ENDPOINT_TYPE_BULK

        out = usb.util.find_descriptor(interface, custom_match=direction(usb.util.ENDPOINT_OUT))
        inp = usb.util.find_descriptor(interface, custom_match=direction(usb.util.ENDPOINT_IN))
        if out is None or inp is None:
            raise DriverInitializationError(f"{self.url}: interface 0 lacks a bulk IN and a bulk OUT endpoint")
        return out, inp

    def write(self, data: bytes) -> None:
        try:
            self._device.write(self._out.bEndpointAddress, data, self._timeout_ms)
        except self._usb.core.USBTimeoutError as exc:
            raise DriverTimeoutError(f"{self.url}: write did not finish within {self._timeout_ms} ms") from exc
        except self._usb.core.USBError as exc:
            raise DriverOperationError(f"{self.url}: write failed (device unplugged?): {exc}") from exc

    def read(self, timeout_s: float) -> bytes:
        try:
            return bytes(self._device.read(self._in.bEndpointAddress, PACKET_BYTES, max(1, int(timeout_s * 1000))))
        except self._usb.core.USBTimeoutError:
            return b""
        except self._usb.core.USBError as exc:
            raise DriverOperationError(f"{self.url}: read failed (device unplugged?): {exc}") from exc

    def close(self) -> None:
        self._usb.util.dispose_resources(self._device)
