"""A small MCAP writer and reader (unchunked, JSON messages with JSON-Schema channels, as Foxglove reads).

Written here rather than adding the `mcap` package: the format needs ~100 lines
for what palpd records, and the reader must tolerate a file cut short by a
crash (no DataEnd/Footer), which is exactly what crash recovery reads, and
`seal` closes such a file so any MCAP reader opens it. The tests check every
file against the official `mcap` reader.
Spec: https://mcap.dev/spec — records are opcode (u8), length (u64 LE), content.
"""
from __future__ import annotations

import json
import os
import struct
import time
from pathlib import Path
from typing import Mapping, Sequence

from palpd.bus.messages import SAMPLES_CHANNEL, RawSample

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_DATA_END = 0x01, 0x02, 0x03, 0x04, 0x05, 0x0F
FLUSH_INTERVAL_S = 1.0  # a crash loses at most this much of the recording


def _string(text: str) -> bytes:
    data = text.encode()
    return struct.pack("<I", len(data)) + data


def _record(opcode: int, content: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(content)) + content


class McapWriter:
    """Appends messages; flushes to the OS at least once a second (and on close)."""

    def __init__(self, path: Path, schemas: dict[str, dict], library: str = "palpd") -> None:
        self._file = open(path, "wb")
        self._file.write(MAGIC + _record(OP_HEADER, _string("") + _string(library)))
        self._channels: dict[str, int] = {}
        self._sequence = 0
        self._flushed_at = time.monotonic()
        self._samples_logged_to_s = 0.0
        for channel_id, (topic, schema) in enumerate(schemas.items(), start=1):
            self._add_channel(channel_id, topic, schema)

    def _add_channel(self, channel_id: int, topic: str, schema: dict) -> None:
        schema_bytes = json.dumps(schema).encode()
        self._file.write(_record(OP_SCHEMA, struct.pack("<H", channel_id) + _string(schema.get("title", topic))
                                 + _string("jsonschema") + struct.pack("<I", len(schema_bytes)) + schema_bytes))
        metadata = b""
        self._file.write(_record(OP_CHANNEL, struct.pack("<HH", channel_id, channel_id) + _string(topic)
                                 + _string("json") + struct.pack("<I", len(metadata)) + metadata))
        self._channels[topic] = channel_id

    def write(self, topic: str, payload: dict, log_time_s: float | None = None) -> None:
        self._message(topic, json.dumps(payload).encode(), time.time() if log_time_s is None else log_time_s)
        self.flush_if_due()

    def record_samples(self, batch: Sequence[Mapping]) -> None:
        """Raw servo samples (RawSample-shaped, oldest first), e.g. what the servo ring gathered since the last call.

        Log times keep the samples' robot-time spacing with the newest at now, so
        they interleave with the events in Foxglove's timeline; a batch is moved
        later if needed so log times never run backwards (virtual time runs faster
        than the wall clock).
        """
        samples = [RawSample.model_validate(sample) for sample in batch]  # a malformed ring entry fails here
        if not samples:
            return
        newest_t = samples[-1].t
        end_s = max(time.time(), self._samples_logged_to_s + (newest_t - samples[0].t))
        for sample in samples:
            self._message(SAMPLES_CHANNEL, sample.model_dump_json().encode(), end_s - (newest_t - sample.t))
        self._samples_logged_to_s = end_s
        self.flush_if_due()

    def _message(self, topic: str, data: bytes, log_time_s: float) -> None:
        ns = int(log_time_s * 1e9)
        header = struct.pack("<HIQQ", self._channels[topic], self._sequence & 0xFFFFFFFF, ns, ns)
        self._file.write(_record(OP_MESSAGE, header + data))
        self._sequence += 1

    def flush_if_due(self) -> None:
        if time.monotonic() - self._flushed_at >= FLUSH_INTERVAL_S:
            self.flush()

    def flush(self) -> None:
        self._file.flush()
        self._flushed_at = time.monotonic()

    def close(self) -> None:
        if self._file.closed:
            return
        self._file.write(ENDING)
        self._file.close()


# DataEnd (no CRC), a Footer without summary section, and the closing magic.
ENDING = _record(OP_DATA_END, struct.pack("<I", 0)) + _record(OP_FOOTER, struct.pack("<QQI", 0, 0, 0)) + MAGIC


def _records(data: bytes):
    """(opcode, content start, content end) of every complete record up to the Footer."""
    offset = len(MAGIC)
    while offset + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, offset)
        start, offset = offset + 9, offset + 9 + length
        if offset > len(data) or opcode == OP_FOOTER:
            return
        yield opcode, start, offset


def seal(path: Path) -> bool:
    """End a recording a crash cut short (torn last record dropped), so any MCAP reader opens it.

    True if the file needed it; a closed file, or one without even its header, is left alone.
    """
    data = Path(path).read_bytes()
    records = list(_records(data)) if data.startswith(MAGIC) else []
    if data.endswith(ENDING) or not records or records[0][0] != OP_HEADER:
        return False
    end = max(stop for opcode, _, stop in records if opcode != OP_DATA_END)
    with open(path, "r+b") as handle:
        handle.truncate(end)
        handle.seek(end)
        handle.write(ENDING)
        handle.flush()
        os.fsync(handle.fileno())
    return True


def read_messages(path: Path) -> list[tuple[str, dict]]:
    """(topic, payload) of every complete message, in order; a truncated tail (crash) is ignored."""
    data = Path(path).read_bytes()
    if not data.startswith(MAGIC):
        raise ValueError(f"{path}: not an MCAP file")
    topics: dict[int, str] = {}
    messages = []
    for opcode, start, offset in _records(data):
        if opcode == OP_CHANNEL:
            channel_id, _ = struct.unpack_from("<HH", data, start)
            (topic_len,) = struct.unpack_from("<I", data, start + 4)
            topics[channel_id] = data[start + 8:start + 8 + topic_len].decode()
        elif opcode == OP_MESSAGE:
            (channel_id,) = struct.unpack_from("<H", data, start)
            messages.append((topics[channel_id], json.loads(data[start + 22:offset])))
    return messages
