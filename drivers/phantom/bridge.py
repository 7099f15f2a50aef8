"""The host side of the Phantom bridge: a Robot that speaks the codec over any transport.

Every host frame is answered by one STATE frame carrying the sequence number it
answers, so a late reply to an earlier request is recognised and dropped. No
answer within the timeout raises DriverTimeoutError: a stalled or unplugged
bridge is detected within one timeout, never waited on forever.
"""
from __future__ import annotations

import time

from drivers.errors import DriverOperationError, DriverTimeoutError
from drivers.interfaces import JointState, Robot
from drivers.phantom import codec, model
from drivers.transport import Transport, open_transport


class _MonotonicClock:
    def now(self) -> float:
        return time.monotonic()


class BridgeRobot(Robot):
    def __init__(self, transport: Transport, clock=None, watchdog_s: float = 0.25, timeout_s: float = 0.05,
                 current_limit_a: float = model.PEAK_CURRENT_A) -> None:
        self.transport, self.clock = transport, clock or _MonotonicClock()
        self.watchdog_ms = max(1, min(0xFFFF, round(watchdog_s * 1000)))
        self.timeout_s = timeout_s
        self.thermal = model.ThermalLimit(peak_a=min(current_limit_a, model.PEAK_CURRENT_A))
        self.decoder = codec.FrameDecoder()
        self.state: codec.State | None = None
        self._seq = 0
        self._enabled = False
        self._last_write_s: float | None = None

    def enable(self) -> None:
        self._send_command(True, (0.0, 0.0, 0.0), clear_faults=True)
        self._enabled = True

    def disable(self) -> None:
        self._enabled = False
        self._send_command(False, (0.0, 0.0, 0.0))

    def write(self, currents_a: model.Vec3) -> None:
        now = self.clock.now()
        dt = 0.0 if self._last_write_s is None else now - self._last_write_s
        self._last_write_s = now
        self._send_command(self._enabled, self.thermal.limit(currents_a, dt))

    def read(self) -> JointState:
        state = self._exchange(codec.encode_frame(codec.READ, self._next_seq()))
        return JointState(self.clock.now(), state.counts, model.counts_to_angles(state.counts), state.status,
                          state.device_time_us * 1e-6)

    def close(self) -> None:
        try:
            self.disable()
        finally:
            self.transport.close()

    def _send_command(self, enable: bool, currents_a: model.Vec3, clear_faults: bool = False) -> None:
        i0, i1, i2 = currents_a
        milliamps = (round(1000.0 * i0), round(1000.0 * i1), round(1000.0 * i2))
        command = codec.Command(enable, clear_faults, self.watchdog_ms, milliamps)
        self._exchange(codec.encode_command(self._next_seq(), command))

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFFFF
        return self._seq

    def _exchange(self, frame: bytes) -> codec.State:
        """Send one frame and wait for the STATE that answers it."""
        transport = self.transport
        transport.write(frame)
        remaining = self.timeout_s
        deadline = time.monotonic() + remaining
        while remaining > 0:
            for received in self.decoder.feed(transport.read(remaining)):
                if received.kind != codec.STATE:
                    continue
                state = codec.decode_state(received.payload)
                if state.ack_seq == self._seq:
                    self.state = state
                    return state
            remaining = deadline - time.monotonic()
        raise DriverTimeoutError(f"{transport.url}: the bridge did not answer within "
                                 f"{self.timeout_s * 1000:.0f} ms (unplugged or stalled?)")


def open_bridge_robot(url: str, clock=None, watchdog_s: float = 0.25, timeout_s: float = 0.05,
                      current_limit_a: float = model.PEAK_CURRENT_A, **transport_options) -> BridgeRobot:
    """Open the transport url names and talk to the bridge behind it; fails at once if it does not answer."""
    transport = open_transport(url, timeout_s=timeout_s, **transport_options)
    robot = BridgeRobot(transport, clock, watchdog_s, timeout_s, current_limit_a)
    try:
        robot.read()
    except (DriverTimeoutError, DriverOperationError):
        transport.close()
        raise
    return robot
