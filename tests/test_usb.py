"""The real pyusb code paths (find, descriptors, strings, bulk transfers, timeouts) against the simulated bridge board."""
import threading
import time

import pytest
import usb.core
import usb.util

import drivers
from drivers.clock import RealClock
from drivers.errors import DriverInitializationError, DriverOperationError, DriverTimeoutError
from drivers.interfaces import STATUS_AMPLIFIERS_ON, STATUS_WATCHDOG_TRIPPED
from drivers.phantom import codec
from drivers.sim.bridge_device import BridgeDevice
from drivers.sim.scene import Scene
from drivers.sim.usb_backend import EP_IN, EP_OUT, SimUsbBoard, get_backend
from drivers.sim.world import SimWorld

TIMEOUT_S = 0.1
URL = "usb://1209:7a10?serial=SIM0001"


@pytest.fixture
def board():
    world = SimWorld(Scene(name="t", tissue={"stiffness_n_per_mm": 0.2}), RealClock())
    return SimUsbBoard(BridgeDevice(world))


def open_usb_robot(board, url=URL, **options):
    return drivers.open_robot(url, backend=get_backend(board), timeout_s=TIMEOUT_S, **options)


def test_pyusb_finds_the_board_and_reads_its_strings_and_endpoints(board):
    backend = get_backend(board, SimUsbBoard(board.bridge, serial_number="OTHER", address=2))
    assert len(list(usb.core.find(find_all=True, backend=backend, idVendor=0x1209, idProduct=0x7A10))) == 2
    device = usb.core.find(backend=backend, idVendor=0x1209, serial_number="OTHER")
    assert device.address == 2 and device.product == "Phantom bridge (simulated)"
    assert usb.core.find(backend=backend, idVendor=0x1209, serial_number="NOPE") is None
    device.set_configuration()
    interface = device.get_active_configuration()[(0, 0)]
    assert [ep.bEndpointAddress for ep in interface] == [EP_OUT, EP_IN]
    assert all(usb.util.endpoint_type(ep.bmAttributes) == usb.util.ENDPOINT_TYPE_BULK for ep in interface)


def test_bulk_transfers_carry_frames_and_an_empty_endpoint_times_out(board):
    device = usb.core.find(backend=get_backend(board), idVendor=0x1209, idProduct=0x7A10)
    device.set_configuration()
    assert device.write(EP_OUT, codec.encode_frame(codec.READ, 7), 100) == codec.OVERHEAD_BYTES
    (frame,) = codec.FrameDecoder().feed(bytes(device.read(EP_IN, 64, 100)))
    assert frame.kind == codec.STATE and codec.decode_state(frame.payload).ack_seq == 7
    started = time.monotonic()
    with pytest.raises(usb.core.USBTimeoutError):
        device.read(EP_IN, 64, 30)
    assert 0.025 < time.monotonic() - started < 0.2


def test_the_bridge_robot_drives_the_motors_over_usb(board):
    world = board.bridge.world
    with open_usb_robot(board) as robot:
        robot.enable()
        robot.write((0.0, 0.4, -0.2))
        assert world.amplifiers_on and world.currents_a == pytest.approx((0.0, 0.4, -0.2))
        state = robot.read()
        assert state.status & STATUS_AMPLIFIERS_ON and state.device_t_s > 0
        robot.disable()
        assert robot.read().status & STATUS_AMPLIFIERS_ON == 0 and world.currents_a == (0.0, 0.0, 0.0)


def test_the_watchdog_trips_over_usb_when_the_host_goes_silent(board):
    with open_usb_robot(board, watchdog_s=0.03) as robot:
        robot.enable()
        robot.write((0.3, 0.3, 0.3))
        time.sleep(0.06)
        assert robot.read().status & STATUS_WATCHDOG_TRIPPED
        assert board.bridge.world.currents_a == (0.0, 0.0, 0.0)


def test_a_stalled_board_is_detected_within_one_timeout(board):
    robot = open_usb_robot(board)
    board.bridge.stalled = True
    started = time.monotonic()
    with pytest.raises(DriverTimeoutError, match="did not answer within 100 ms"):
        robot.read()
    assert TIMEOUT_S <= time.monotonic() - started < TIMEOUT_S + 0.05
    board.bridge.stalled = False
    robot.read()  # late replies are told apart by their sequence number
    robot.close()


def test_an_unplugged_board_is_detected_within_one_timeout_even_mid_read(board):
    robot = open_usb_robot(board)
    board.bridge.stalled = True  # the read below waits on the bulk IN endpoint when the cable goes
    threading.Timer(0.02, board.unplug).start()
    started = time.monotonic()
    with pytest.raises(DriverOperationError, match="device unplugged"):
        robot.read()
    assert time.monotonic() - started < TIMEOUT_S
    with pytest.raises(DriverOperationError):
        robot.write((0.0, 0.0, 0.0))
    robot.transport.close()
    with pytest.raises(DriverInitializationError, match="no USB device 1209:7a10 with serial SIM0001 found"):
        open_usb_robot(board)


def test_an_absent_or_misnamed_device_fails_at_once_naming_it(board):
    for url, fragment in [("usb://1209:7a11", "no USB device 1209:7a11 found"),
                          ("usb://1209", "expected usb://VID:PID"), ("usb://zz:7a10", "hexadecimal")]:
        with pytest.raises(DriverInitializationError, match=fragment):
            open_usb_robot(board, url)
