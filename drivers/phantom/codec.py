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

COMMAND = 0x01  # host -> bridge: amplifiers, three motor currents, watchdog period
READ = 0x02  # host -> bridge: only ask for the state
STATE = 0x81  # bridge -> host: encoder counts, status, device time, which host frame it answers

FLAG_ENABLE = 0x01  # amplifiers on
FLAG_CLEAR_FAULTS = 0x02  # clear a latched watchdog trip (only honoured together with FLAG_ENABLE)

COMMAND_PAYLOAD = struct.Struct("<BH3h")  # flags, watchdog ms (0 = keep), currents in mA
STATE_PAYLOAD = struct.Struct("<3iBIHH")  # counts, status, device time in us (wraps), ack sequence, rx errors
PAYLOAD_BYTES = {COMMAND: COMMAND_PAYLOAD.size, READ: 0, STATE: STATE_PAYLOAD.size}
MAX_CURRENT_MA = 32767


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
    body = HEADER.pack(SYNC, kind, len(payload), seq & 0xFFFF) + payload
    return body + CRC.pack(crc16(body[2:]))


def encode_command(seq: int, command: Command) -> bytes:
    flags = (FLAG_ENABLE if command.enable else 0) | (FLAG_CLEAR_FAULTS if command.clear_faults else 0)
    currents = tuple(max(-MAX_CURRENT_MA, min(MAX_CURRENT_MA, int(c))) for c in command.currents_ma)
    return encode_frame(COMMAND, seq, COMMAND_PAYLOAD.pack(flags, command.watchdog_ms, *currents))


def encode_state(seq: int, state: State) -> bytes:
    payload = STATE_PAYLOAD.pack(*state.counts, state.status, state.device_time_us & 0xFFFFFFFF,
                                 state.ack_seq & 0xFFFF, state.rx_errors & 0xFFFF)
    return encode_frame(STATE, seq, payload)


def decode_command(payload: bytes) -> Command:
    flags, watchdog_ms, *currents = COMMAND_PAYLOAD.unpack(payload)
    return Command(bool(flags & FLAG_ENABLE), bool(flags & FLAG_CLEAR_FAULTS), watchdog_ms, tuple(currents))


def decode_state(payload: bytes) -> State:
    c1, c2, c3, status, time_us, ack, errors = STATE_PAYLOAD.unpack(payload)
    return State((c1, c2, c3), status, time_us, ack, errors)


class FrameDecoder:
    """Turns a byte stream into frames; skips garbage, rejects frames whose length, type or CRC is wrong."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.discarded_bytes = 0
        self.rejected_frames = 0

    def feed(self, data: bytes) -> list[Frame]:
        self._buffer += data
        frames: list[Frame] = []
        while (frame := self._next_frame()) is not None:
            frames.append(frame)
        return frames

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
