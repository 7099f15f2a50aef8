"""The host side of the Phantom bridge: a Robot that speaks the codec over any transport.

Every host frame is answered by one STATE frame carrying the sequence number it
answers, so a late reply to an earlier request is recognised and dropped. No
answer within the timeout raises DriverTimeoutError: a stalled or unplugged
bridge is detected within one timeout, never waited on forever.

One wire exchange per servo tick: write() sends the COMMAND without waiting; its
STATE is collected by the next read() and is that tick's reading, as long as it
is younger than reply_fresh_s (so the round trip overlaps the servo's sleep); a
tick that comes late (the host was descheduled) reads afresh instead of acting
on an old state.
"""
from __future__ import annotations

import time

from drivers.errors import DriverOperationError, DriverTimeoutError
from drivers.interfaces import JointState, Robot
from drivers.phantom import codec, model
from drivers.transport import Transport, open_transport

DEFAULT_WATCHDOG_S = 10.0  # host silence after which the bridge cuts the amplifiers (it holds before that)
DEFAULT_HOLD_AFTER_S = 0.0015  # host silence after which the bridge ramps to the hold currents
DEFAULT_HOLD_RAMP_S = 0.001
DEFAULT_REPLY_FRESH_S = 0.0015  # a COMMAND's reply younger than this is the next tick's reading
NO_CURRENT = (0.0, 0.0, 0.0)


class _MonotonicClock:
    def now(self) -> float:
        return time.monotonic()


def _us(seconds: float) -> int:
    return max(1, min(0xFFFF, round(seconds * 1e6)))


class BridgeRobot(Robot):
    def __init__(self, transport: Transport, clock=None, watchdog_s: float = DEFAULT_WATCHDOG_S,
                 timeout_s: float = 0.05, current_limit_a: float = model.PEAK_CURRENT_A,
                 hold_after_s: float = DEFAULT_HOLD_AFTER_S, hold_ramp_s: float = DEFAULT_HOLD_RAMP_S,
                 reply_fresh_s: float = DEFAULT_REPLY_FRESH_S) -> None:
        self.transport, self.clock = transport, clock or _MonotonicClock()
        self.watchdog_ms = max(1, min(0xFFFF, round(watchdog_s * 1000)))
        self.hold_after_us, self.hold_ramp_us = _us(hold_after_s), _us(hold_ramp_s)
        self.timeout_s = timeout_s
        self.reply_fresh_s = reply_fresh_s
        self.thermal = model.ThermalLimit(peak_a=min(current_limit_a, model.PEAK_CURRENT_A))
        self.decoder = codec.FrameDecoder()
        self.state: codec.State | None = None
        self.exchanges = 0  # wire round trips so far (one per servo tick when the ticks are on time)
        self._seq = 0
        self._enabled = False
        self._last_write_s: float | None = None
        self._awaited: tuple[int, float] | None = None  # (sequence, host time) of the command whose reply is due
        self._reading: tuple[codec.State, float] | None = None  # a reply in hand, with when it was sampled

    def enable(self) -> None:
        sent_s = self.clock.now()
        self._exchange(self._command_frame(True, NO_CURRENT, NO_CURRENT, clear_faults=True))
        self._reading = (self.state, sent_s)  # the first tick's reading
        self._enabled = True

    def disable(self) -> None:
        self._enabled = False
        self._awaited = self._reading = None
        self._exchange(self._command_frame(False, NO_CURRENT, NO_CURRENT))

    def write(self, currents_a: model.Vec3, hold_a: model.Vec3 | None = None) -> None:
        """Send the command; its reply, the state as the bridge applied it, is collected by the next read(),
        so the round trip overlaps the servo's sleep instead of lengthening its tick."""
        now = self.clock.now()
        dt = 0.0 if self._last_write_s is None else now - self._last_write_s
        self._last_write_s = now
        self._send(self._command_frame(self._enabled, self.thermal.limit(currents_a, dt), hold_a or NO_CURRENT))
        self._awaited, self._reading = (self._seq, now), None

    def read(self) -> JointState:
        """The last command's reply while it is fresh (sampled when the command went out), else a READ."""
        if self._awaited is not None:
            seq, sent_s = self._awaited
            self._awaited = None
            self._reading = (self._await(seq), sent_s)
        reading, self._reading = self._reading, None
        if reading is not None and self.clock.now() - reading[1] <= self.reply_fresh_s:
            return self._joint_state(*reading)
        return self._joint_state(self._exchange(codec.encode_frame(codec.READ, self._next_seq())), self.clock.now())

    def close(self) -> None:
        try:
            self.disable()
        finally:
            self.transport.close()

    def _joint_state(self, state: codec.State, t_s: float) -> JointState:
        counts = state.counts
        return JointState(t_s, counts, model.counts_to_angles(counts), state.status, state.device_time_us * 1e-6)

    def _command_frame(self, enable: bool, currents_a: model.Vec3, hold_a: model.Vec3,
                       clear_faults: bool = False) -> bytes:
        i0, i1, i2 = currents_a
        h0, h1, h2 = hold_a
        return codec.encode_command_values(
            self._next_seq(), enable, clear_faults, self.watchdog_ms, self.hold_after_us, self.hold_ramp_us,
            round(1000.0 * i0), round(1000.0 * i1), round(1000.0 * i2),
            round(1000.0 * h0), round(1000.0 * h1), round(1000.0 * h2))

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFFFF
        return self._seq

    def _send(self, frame: bytes) -> None:
        self.transport.write(frame)
        self.exchanges += 1

    def _exchange(self, frame: bytes) -> codec.State:
        """Send one frame and wait for the STATE that answers it (a reply still due is then dropped unread)."""
        self._awaited = None
        self._send(frame)
        return self._await(self._seq)

    def _await(self, seq: int) -> codec.State:
        """The STATE answering frame `seq`, within timeout_s; late answers to earlier frames are dropped."""
        transport = self.transport
        remaining = self.timeout_s
        deadline = time.monotonic() + remaining
        data = transport.read(remaining)
        whole = codec.parse_state_frame(data) if not self.decoder.pending else None
        if whole is not None and whole[1].ack_seq == seq:  # the usual case: the answer, whole and alone
            self.state = whole[1]
            return self.state
        while True:
            for received in self.decoder.feed(data):
                if received.kind != codec.STATE:
                    continue
                state = codec.decode_state(received.payload)
                if state.ack_seq == seq:
                    self.state = state
                    return state
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            data = transport.read(remaining)
        raise DriverTimeoutError(f"{transport.url}: the bridge did not answer within "
                                 f"{self.timeout_s * 1000:.0f} ms (unplugged or stalled?)")


def open_bridge_robot(url: str, clock=None, watchdog_s: float = DEFAULT_WATCHDOG_S, timeout_s: float = 0.05,
                      current_limit_a: float = model.PEAK_CURRENT_A, hold_after_s: float = DEFAULT_HOLD_AFTER_S,
                      hold_ramp_s: float = DEFAULT_HOLD_RAMP_S, reply_fresh_s: float = DEFAULT_REPLY_FRESH_S,
                      **transport_options) -> BridgeRobot:
    """Open the transport url names and talk to the bridge behind it; fails at once if it does not answer."""
    transport = open_transport(url, timeout_s=timeout_s, **transport_options)
    robot = BridgeRobot(transport, clock, watchdog_s, timeout_s, current_limit_a, hold_after_s, hold_ramp_s,
                        reply_fresh_s)
    try:
        robot.read()
    except (DriverTimeoutError, DriverOperationError):
        transport.close()
        raise
    return robot
