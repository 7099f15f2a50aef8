"""The Net F/T RDT client against the simulated box over UDP loopback."""
import socket
import threading
import time

import pytest

import drivers
from drivers.clock import RealClock
from drivers.errors import DriverInitializationError, DriverTimeoutError
from drivers.interfaces import SAMPLE_GAP, SAMPLE_INVALID
from drivers.nano17 import rdt
from drivers.sim.netft_server import STATUS_SATURATED, NetFtEndpoint
from drivers.sim.scene import Scene
from drivers.sim.servers import SimulatorHost
from drivers.sim.world import SimWorld

TIMEOUT_S = 0.1


@pytest.fixture
def box():
    world = SimWorld(Scene(name="t", sensor={"noise_n": 0.0, "bias_n": 0.5}), RealClock(), seed=3)
    host = SimulatorHost(world)
    endpoint = host.add(NetFtEndpoint(world, port=0))
    stop = threading.Event()
    thread = threading.Thread(target=host.serve, args=(stop,), daemon=True)
    thread.start()
    yield world, endpoint
    stop.set()
    thread.join(2)
    host.close()


def test_streams_the_simulated_load_in_newtons(box):
    world, endpoint = box
    with drivers.open_sensor(endpoint.url, timeout_s=TIMEOUT_S) as sensor:
        sample = sensor.read()
        expected = world.sensor_wrench()  # no contact: the bias alone, in N and N*mm
        assert sample.force_n == pytest.approx(expected[:3], abs=1e-5)
        assert sample.torque_n_mm == pytest.approx(expected[3:], abs=1e-3)
        assert sample.flags == 0 and sample.status == 0
        sensor.bias()
        time.sleep(0.02)
        assert sensor.read().force_n == pytest.approx((0.0, 0.0, 0.0), abs=1e-5)


def test_sequence_gaps_are_counted_and_flagged(box):
    _, endpoint = box
    with drivers.open_sensor(endpoint.url, timeout_s=TIMEOUT_S) as sensor:
        sensor.read()
        endpoint.skip(5)
        time.sleep(0.01)
        assert sensor.read().flags & SAMPLE_GAP and sensor.gaps == 5
        time.sleep(0.01)
        assert not sensor.read().flags & SAMPLE_GAP


def test_status_bits_are_surfaced_and_mark_the_sample_invalid(box):
    world, endpoint = box
    world.sensor._bias = (0.0, 0.0, 60.0, 0.0, 0.0, 0.0)  # beyond the 35 N range
    with drivers.open_sensor(endpoint.url, timeout_s=TIMEOUT_S) as sensor:
        time.sleep(0.01)
        sample = sensor.read()
        assert sample.status == STATUS_SATURATED and sample.flags & SAMPLE_INVALID


def test_a_stalled_box_is_detected_within_one_timeout(box):
    _, endpoint = box
    with drivers.open_sensor(endpoint.url, timeout_s=TIMEOUT_S) as sensor:
        sensor.read()
        endpoint.stalled = True
        started = time.monotonic()
        with pytest.raises(DriverTimeoutError, match="unplugged or stalled"):
            while True:
                sensor.read()
                time.sleep(0.001)
        assert time.monotonic() - started < TIMEOUT_S + 0.05


def test_buffered_stream_packs_several_records_per_datagram(box):
    _, endpoint = box
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
        client.settimeout(1.0)
        client.sendto(rdt.encode_request(rdt.BUFFERED_STREAM, 8), endpoint.address)
        records = rdt.decode_records(client.recv(65536))
        assert len(records) == 4 and [r[0] for r in records] == [1, 2, 3, 4]


def test_no_box_there_fails_at_once_naming_it():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as unused:
        unused.bind(("127.0.0.1", 0))
        port = unused.getsockname()[1]
    started = time.monotonic()
    with pytest.raises((DriverTimeoutError, drivers.DriverOperationError), match=f"127.0.0.1:{port}"):
        drivers.open_sensor(f"netft://127.0.0.1:{port}", timeout_s=TIMEOUT_S)
    assert time.monotonic() - started < TIMEOUT_S + 0.1
    with pytest.raises(DriverInitializationError, match="netft://HOST"):
        drivers.open_sensor("netft://")
