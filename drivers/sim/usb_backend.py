"""The simulated bridge board on a simulated USB bus: a pyusb backend (``usb.backend.IBackend``).

pyusb's own code runs unchanged on top of it: ``usb.core.find(backend=...)``
enumerates the board by its device descriptor, reads its serial number through
GET_DESCRIPTOR control transfers, sets the configuration, claims interface 0
and moves frames over the two bulk endpoints, with timeouts. Only the layer
under pyusb (what libusb does) is simulated: bulk OUT bytes go to a
BridgeDevice, its replies wait on bulk IN until the host reads them. Pulling
the cable makes every transfer fail as libusb reports a vanished device.
"""
from __future__ import annotations

import errno
import threading
import time
from types import SimpleNamespace

import usb.backend
from usb.core import USBError, USBTimeoutError

VENDOR_ID, PRODUCT_ID = 0x1209, 0x7A10  # pid.codes test range: what usb:// URLs in tests name
EP_OUT, EP_IN = 0x01, 0x81
PACKET_BYTES = 64
LANGID_EN_US = 0x0409
GET_DESCRIPTOR, DESC_TYPE_STRING = 0x06, 0x03
# libusb's error codes, as its pyusb backend raises them
LIBUSB_ERROR_NO_DEVICE, LIBUSB_ERROR_TIMEOUT, LIBUSB_ERROR_PIPE = -4, -7, -9


class SimUsbBoard:
    """One bridge board on the bus: its descriptors, its strings and the bridge firmware behind it."""

    def __init__(self, bridge, serial_number: str = "SIM0001", address: int = 1,
                 vendor_id: int = VENDOR_ID, product_id: int = PRODUCT_ID) -> None:
        self.bridge, self.plugged = bridge, True
        self.strings = {1: "palpd", 2: "Phantom bridge (simulated)", 3: serial_number}
        self.descriptor = SimpleNamespace(
            bLength=18, bDescriptorType=1, bcdUSB=0x0200, bDeviceClass=0xFF, bDeviceSubClass=0,
            bDeviceProtocol=0, bMaxPacketSize0=64, idVendor=vendor_id, idProduct=product_id, bcdDevice=0x0100,
            iManufacturer=1, iProduct=2, iSerialNumber=3, bNumConfigurations=1,
            address=address, bus=1, port_number=address, port_numbers=(address,), speed=2)  # full speed
        self.inbox = bytearray()  # bulk IN data the host has not read yet
        self.ready = threading.Condition()

    def unplug(self) -> None:
        """Pull the cable: every open handle fails from now on; a waiting read wakes up to fail."""
        with self.ready:
            self.plugged = False
            self.ready.notify_all()


def _endpoint(address: int) -> SimpleNamespace:
    return SimpleNamespace(bLength=7, bDescriptorType=5, bEndpointAddress=address, bmAttributes=0x02,  # bulk
                           wMaxPacketSize=PACKET_BYTES, bInterval=0, bRefresh=0, bSynchAddress=0,
                           extra_descriptors=[])


CONFIGURATION = SimpleNamespace(bLength=9, bDescriptorType=2, wTotalLength=9 + 9 + 7 + 7, bNumInterfaces=1,
                                bConfigurationValue=1, iConfiguration=0, bmAttributes=0x80, bMaxPower=50,
                                extra_descriptors=[])
INTERFACE = SimpleNamespace(bLength=9, bDescriptorType=4, bInterfaceNumber=0, bAlternateSetting=0, bNumEndpoints=2,
                            bInterfaceClass=0xFF, bInterfaceSubClass=0, bInterfaceProtocol=0, iInterface=0,
                            extra_descriptors=[])
ENDPOINTS = (_endpoint(EP_OUT), _endpoint(EP_IN))


def _gone() -> USBError:
    return USBError("No such device (it may have been disconnected)", LIBUSB_ERROR_NO_DEVICE, errno.ENODEV)


class SimUsbBackend(usb.backend.IBackend):
    """What pyusb needs from libusb, for the boards plugged into this simulated bus."""

    def __init__(self, boards: list[SimUsbBoard] | None = None) -> None:
        super().__init__()
        self.boards = list(boards or [])
        self.configuration: dict[int, int] = {}  # id(board) -> bConfigurationValue set

    # -- enumeration and descriptors -----------------------------------------------------------
    def enumerate_devices(self):
        return [board for board in self.boards if board.plugged]

    def get_parent(self, dev):
        return None

    def get_device_descriptor(self, dev):
        return dev.descriptor

    def get_configuration_descriptor(self, dev, config):
        if config != 0:
            raise IndexError(f"configuration index {config} out of range")
        return CONFIGURATION

    def get_interface_descriptor(self, dev, intf, alt, config):
        if (intf, alt, config) != (0, 0, 0):
            raise IndexError(f"interface ({intf}, {alt}) out of range")
        return INTERFACE

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        if (intf, alt, config) != (0, 0, 0) or not 0 <= ep < len(ENDPOINTS):
            raise IndexError(f"endpoint {ep} out of range")
        return ENDPOINTS[ep]

    # -- handles and configuration -------------------------------------------------------------
    def open_device(self, dev):
        return self._alive(dev)

    def close_device(self, dev_handle):
        pass

    def set_configuration(self, dev_handle, config_value):
        self.configuration[id(self._alive(dev_handle))] = config_value

    def get_configuration(self, dev_handle):
        return self.configuration.get(id(self._alive(dev_handle)), 0)

    def claim_interface(self, dev_handle, intf):
        self._alive(dev_handle)

    def release_interface(self, dev_handle, intf):
        pass

    def set_interface_altsetting(self, dev_handle, intf, altsetting):
        self._alive(dev_handle)

    # -- transfers -----------------------------------------------------------------------------
    def ctrl_transfer(self, dev_handle, bmRequestType, bRequest, wValue, wIndex, data, timeout):
        """Only what pyusb asks of a vendor-class device: string descriptors (serial number, product)."""
        board = self._alive(dev_handle)
        if bmRequestType != 0x80 or bRequest != GET_DESCRIPTOR or wValue >> 8 != DESC_TYPE_STRING:
            raise USBError("Pipe error", LIBUSB_ERROR_PIPE, errno.EPIPE)  # a stall: request not supported
        index = wValue & 0xFF
        body = LANGID_EN_US.to_bytes(2, "little") if index == 0 else board.strings.get(index, "").encode("utf-16-le")
        descriptor = (bytes((2 + len(body), DESC_TYPE_STRING)) + body)[:len(data)]
        data[:len(descriptor)] = type(data)(data.typecode, descriptor)
        return len(descriptor)

    def bulk_write(self, dev_handle, ep, intf, data, timeout):
        board = self._alive(dev_handle)
        if ep != EP_OUT:
            raise USBError("Pipe error", LIBUSB_ERROR_PIPE, errno.EPIPE)
        reply = board.bridge.handle(data.tobytes())
        with board.ready:
            board.inbox += reply
            board.ready.notify_all()
        return len(data)

    def bulk_read(self, dev_handle, ep, intf, buff, timeout):
        """Up to len(buff) bytes once some are there; USBTimeoutError after timeout ms (0: wait for ever)."""
        board = self._alive(dev_handle)
        if ep != EP_IN:
            raise USBError("Pipe error", LIBUSB_ERROR_PIPE, errno.EPIPE)
        deadline = time.monotonic() + timeout / 1000.0 if timeout else None
        with board.ready:
            while board.plugged and not board.inbox:
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    raise USBTimeoutError("Operation timed out", LIBUSB_ERROR_TIMEOUT, errno.ETIMEDOUT)
                board.ready.wait(remaining)
            self._alive(board)
            count = min(len(buff), len(board.inbox))
            buff[:count] = type(buff)(buff.typecode, board.inbox[:count])
            del board.inbox[:count]
        return count

    def clear_halt(self, dev_handle, ep):
        self._alive(dev_handle)

    def reset_device(self, dev_handle):
        self._alive(dev_handle).inbox.clear()

    def is_kernel_driver_active(self, dev_handle, intf):
        return False

    @staticmethod
    def _alive(board: SimUsbBoard) -> SimUsbBoard:
        if not board.plugged:
            raise _gone()
        return board


def get_backend(*boards: SimUsbBoard) -> SimUsbBackend:
    """As pyusb's backend modules offer it: ``usb.core.find(backend=get_backend(board))``."""
    return SimUsbBackend(list(boards))
