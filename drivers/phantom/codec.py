"""The Phantom bridge protocol (PROTOCOL.md): frames with sequence numbers and a CRC.

Both ends use this module: the host driver (drivers/phantom/bridge.py) and the
simulated bridge (drivers/sim/bridge_device.py). The decoder resynchronises
after garbage by hunting for the next sync word and drops corrupted frames.
"""
from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass

SYNC = b"\xa5\x5a"
HEADER = struct.Struct("<2sBBH")  # sync, type, payload length, sequence
CRC = struct.Struct("<H")
OVERHEAD_BYTES = HEADER.size + CRC.size

COMMAND = 0x01  # host -> bridge: amplifiers, three motor currents, the hold currents, watchdog timings
READ = 0x02  # host -> bridge: only ask for the state
STATE = 0x81  # bridge -> host: encoder counts, status, device time, which host frame it answers

FLAG_ENABLE = 0x01  # amplifiers on
FLAG_CLEAR_FAULTS = 0x02  # clear a latched watchdog trip (only honoured together with FLAG_ENABLE)

# flags, watchdog ms (0 = keep), hold after us (0 = keep), hold ramp us (0 = keep), currents, hold currents (mA)
COMMAND_PAYLOAD = struct.Struct("<BHHH3h3h")
STATE_PAYLOAD = struct.Struct("<3iBIHH")  # counts, status, device time in us (wraps), ack sequence, rx errors
PAYLOAD_BYTES = {COMMAND: COMMAND_PAYLOAD.size, READ: 0, STATE: STATE_PAYLOAD.size}
MAX_CURRENT_MA = 32767
# Header and payload packed in one call: both ends build a frame every servo tick.
_COMMAND_BODY = struct.Struct(HEADER.format + COMMAND_PAYLOAD.format[1:])
_STATE_BODY = struct.Struct(HEADER.format + STATE_PAYLOAD.format[1:])


@dataclass(frozen=True, slots=True)
class Frame:
    kind: int
    seq: int
    payload: bytes


@dataclass(frozen=True, slots=True)
class Command:
    enable: bool
    clear_faults: bool
    watchdog_ms: int
    currents_ma: tuple[int, int, int]
    hold_after_us: int = 0  # host silence after which the bridge ramps to hold_ma (0 keeps the bridge's)
    hold_ramp_us: int = 0  # how long that ramp takes (0 keeps the bridge's)
    hold_ma: tuple[int, int, int] = (0, 0, 0)  # what a silent host leaves on: gravity compensation at this pose


@dataclass(frozen=True, slots=True)
class State:
    counts: tuple[int, int, int]
    status: int
    device_time_us: int
    ack_seq: int
    rx_errors: int


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), computed in C by binascii."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode_frame(kind: int, seq: int, payload: bytes = b"") -> bytes:
    return _sealed(HEADER.pack(SYNC, kind, len(payload), seq & 0xFFFF) + payload)


def _sealed(body: bytes) -> bytes:
    """body + its CRC (over everything after the sync word)."""
    return body + CRC.pack(binascii.crc_hqx(body[2:], 0xFFFF))


def _clamp_ma(current: int) -> int:
    return MAX_CURRENT_MA if current > MAX_CURRENT_MA else -MAX_CURRENT_MA if current < -MAX_CURRENT_MA else current


def encode_command(seq: int, command: Command) -> bytes:
    i0, i1, i2 = command.currents_ma
    h0, h1, h2 = command.hold_ma
    return encode_command_values(seq, command.enable, command.clear_faults, command.watchdog_ms, command.hold_after_us,
                                 command.hold_ramp_us, int(i0), int(i1), int(i2), int(h0), int(h1), int(h2))


def encode_state(seq: int, state: State) -> bytes:
    c0, c1, c2 = state.counts
    return _sealed(_STATE_BODY.pack(SYNC, STATE, STATE_PAYLOAD.size, seq & 0xFFFF, c0, c1, c2, state.status,
                                    state.device_time_us & 0xFFFFFFFF, state.ack_seq & 0xFFFF,
                                    state.rx_errors & 0xFFFF))


def encode_command_values(seq: int, enable: bool, clear_faults: bool, watchdog_ms: int, hold_after_us: int,
                          hold_ramp_us: int, i0: int, i1: int, i2: int, h0: int, h1: int, h2: int) -> bytes:
    """encode_command without building a Command: the host sends one every servo tick."""
    flags = (FLAG_ENABLE if enable else 0) | (FLAG_CLEAR_FAULTS if clear_faults else 0)
    c = _clamp_ma
    return _sealed(_COMMAND_BODY.pack(SYNC, COMMAND, COMMAND_PAYLOAD.size, seq & 0xFFFF, flags, watchdog_ms,
                                      hold_after_us, hold_ramp_us, c(i0), c(i1), c(i2), c(h0), c(h1), c(h2)))


def decode_command(payload: bytes) -> Command:
    flags, watchdog_ms, hold_after_us, hold_ramp_us, i0, i1, i2, h0, h1, h2 = COMMAND_PAYLOAD.unpack(payload)
    return Command(bool(flags & FLAG_ENABLE), bool(flags & FLAG_CLEAR_FAULTS), watchdog_ms, (i0, i1, i2),
                   hold_after_us, hold_ramp_us, (h0, h1, h2))


def decode_state(payload: bytes) -> State:
    c1, c2, c3, status, time_us, ack, errors = STATE_PAYLOAD.unpack(payload)
    return State((c1, c2, c3), status, time_us, ack, errors)


_STATE_FRAME = struct.Struct(_STATE_BODY.format + "H")  # a whole STATE frame, CRC included
STATE_FRAME_BYTES = _STATE_FRAME.size


def parse_state_frame(data: bytes) -> tuple[int, State] | None:
    """(sequence, State) if data is exactly one valid STATE frame, else None (then use a FrameDecoder).

    The host's fast path: one reply per exchange almost always arrives whole and alone."""
    if len(data) != STATE_FRAME_BYTES:
        return None
    sync, kind, length, seq, c0, c1, c2, status, time_us, ack, errors, crc = _STATE_FRAME.unpack(data)
    if sync != SYNC or kind != STATE or length != STATE_PAYLOAD.size \
            or crc != binascii.crc_hqx(data[2:STATE_FRAME_BYTES - CRC.size], 0xFFFF):
        return None
    return seq, State((c0, c1, c2), status, time_us, ack, errors)


class FrameDecoder:
    """Turns a byte stream into frames; skips garbage, rejects frames whose length, type or CRC is wrong."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.discarded_bytes = 0
        self.rejected_frames = 0

    @property
    def pending(self) -> bool:
        """Bytes of an unfinished frame are waiting for the rest."""
        return bool(self._buffer)

    def feed(self, data: bytes) -> list[Frame]:
        frames: list[Frame] = []
        offset = 0 if self._buffer else self._whole_frames(bytes(data), frames)
        if offset < len(data):
            self._buffer += data[offset:] if offset else data
            while (frame := self._next_frame()) is not None:
                frames.append(frame)
        return frames

    @staticmethod
    def _whole_frames(data: bytes, frames: list[Frame]) -> int:
        """Fast path for a healthy link: valid frames back to back from the first byte, parsed in place.

        Stops at the first thing that is not a whole valid frame and returns its offset; the
        buffered path takes over from there, so garbage and partial frames are handled as always.
        """
        offset, size, header_bytes = 0, len(data), HEADER.size
        while size - offset >= header_bytes:
            sync, kind, length, seq = HEADER.unpack_from(data, offset)
            end = offset + header_bytes + length
            if sync != SYNC or PAYLOAD_BYTES.get(kind) != length or end + CRC.size > size \
                    or CRC.unpack_from(data, end)[0] != binascii.crc_hqx(data[offset + 2:end], 0xFFFF):
                break
            frames.append(Frame(kind, seq, data[offset + header_bytes:end]))
            offset = end + CRC.size
        return offset

    def _next_frame(self) -> Frame | None:
        buffer = self._buffer
        while True:
            start = buffer.find(SYNC)
            if start < 0:  # keep a trailing first sync byte: the rest of the word may follow
                self._discard(len(buffer) - (1 if buffer.endswith(SYNC[:1]) else 0))
                return None
            self._discard(start)
            if len(buffer) < HEADER.size:
                return None
            _, kind, length, seq = HEADER.unpack_from(buffer)
            if PAYLOAD_BYTES.get(kind) != length:  # unknown type or wrong length: not a frame start
                self._reject()
                continue
            end = HEADER.size + length
            if len(buffer) < end + CRC.size:
                return None
            if CRC.unpack_from(buffer, end)[0] != crc16(bytes(buffer[2:end])):
                self._reject()
                continue
            frame = Frame(kind, seq, bytes(buffer[HEADER.size:end]))
            del buffer[:end + CRC.size]
            return frame

    def _discard(self, count: int) -> None:
        if count > 0:
            del self._buffer[:count]
            self.discarded_bytes += count

    def _reject(self) -> None:
        """Skip this sync word's first byte and hunt again: a real frame may start inside."""
        self.rejected_frames += 1
        self._discard(1)
