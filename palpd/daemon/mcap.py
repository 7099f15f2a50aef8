"""Recordings: MCAP files written by the official `mcap` Writer (chunked, zstd-compressed, indexed, JSON-Schema
channels, as Foxglove and every MCAP tool read them).

The chunk under way is finished and flushed to the OS at least once a second, so
a crash loses at most that second of the recording (the palpation journal, fsynced
per palpation, loses nothing). A file a crash cut short has no summary: `seal`
rewrites what it holds (every complete chunk) into a properly indexed file, so
`mcap.reader.make_reader` reads every recording, including a recovered one.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Mapping, Sequence

from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from palpd.bus.messages import SAMPLES_CHANNEL, RawSample
from palpd.files import open_for_writing

MAGIC = b"\x89MCAP0\r\n"
FLUSH_INTERVAL_S = 1.0  # a crash loses at most this much of the recording
CHUNK_BYTES = 1 << 20  # a chunk also ends when it grows this big (before a second is up)


class McapWriter:
    """Appends JSON messages to channels named by topic; finishes a chunk at least once a second."""

    def __init__(self, path: Path, schemas: dict[str, dict], library: str = "palpd") -> None:
        self._file = open_for_writing(path, "wb")
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library=library)
        self._channels = {topic: self._register(topic, schema) for topic, schema in schemas.items()}
        self._sequence = 0
        self._flushed_at = time.monotonic()
        self._samples_logged_to_s = 0.0

    def _register(self, topic: str, schema: dict) -> int:
        schema_id = self._writer.register_schema(name=schema.get("title", topic), encoding="jsonschema",
                                                 data=json.dumps(schema).encode())
        return self._writer.register_channel(topic=topic, message_encoding="json", schema_id=schema_id)

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
        self._writer.add_message(channel_id=self._channels[topic], log_time=ns, data=data, publish_time=ns,
                                 sequence=self._sequence & 0xFFFFFFFF)
        self._sequence += 1

    def flush_if_due(self) -> None:
        if time.monotonic() - self._flushed_at >= FLUSH_INTERVAL_S:
            self.flush()

    def flush(self) -> None:
        """Finish the chunk under way and hand it to the OS."""
        self._writer.flush()
        self._flushed_at = time.monotonic()

    def close(self) -> None:
        if self._file.closed:
            return
        try:
            self._writer.finish()  # the last chunk, then the summary: indexes, statistics, footer
        finally:
            self._file.close()

    def abandon(self) -> None:
        """After a storage error: close the file as it is (a restart seals what it holds), raising nothing."""
        try:
            self._file.close()
        except OSError:
            pass


def is_closed(path: Path) -> bool:
    """True when the file has its summary (chunk indexes): it was closed, or sealed."""
    try:
        with open(path, "rb") as handle:
            summary = make_reader(handle).get_summary()
    except Exception:  # no footer, a torn summary...: the reader raises its own types (McapError, struct.error)
        return False
    return summary is not None and bool(summary.chunk_indexes or not summary.statistics.message_count)


def _complete_records(path: Path) -> tuple[dict[int, Schema], dict[int, Channel], list[Message]]:
    """Schemas, channels and messages of every complete chunk, in file order; a torn tail is where it stops."""
    schemas, channels, messages = {}, {}, []
    with open(path, "rb") as handle:
        try:
            for record in StreamReader(handle).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    messages.append(record)
        except Exception:  # the torn tail: EndOfFile, a bad CRC, a bogus record length... (the reader's own types)
            pass
    return schemas, channels, messages


def seal(path: Path) -> bool:
    """Rewrite a recording a crash cut short (every complete chunk kept) as a closed, indexed file.

    True if the file needed it; a closed file is left alone, and so is one without even its header.
    """
    path = Path(path)
    with open(path, "rb") as handle:
        if handle.read(len(MAGIC)) != MAGIC or is_closed(path):
            return False
    schemas, channels, messages = _complete_records(path)
    temporary = path.with_name(f".{path.name}.sealing")
    try:
        _rewrite(temporary, schemas, channels, messages)
    except OSError:
        temporary.unlink(missing_ok=True)  # a full disk: no half-sealed copy left beside the original
        raise
    os.replace(temporary, path)
    return True


def _rewrite(temporary: Path, schemas, channels, messages) -> None:
    with open_for_writing(temporary, "wb") as handle:
        writer = Writer(handle, chunk_size=CHUNK_BYTES, compression=CompressionType.ZSTD)
        writer.start(profile="", library="palpd (sealed after a crash)")
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in schemas.items()}
        channel_ids = {cid: writer.register_channel(c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0),
                                                    c.metadata) for cid, c in channels.items()}
        for m in messages:
            writer.add_message(channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()
        handle.flush()
        os.fsync(handle.fileno())


def read_messages(path: Path) -> list[tuple[str, dict]]:
    """(topic, payload) of every complete message, in file order; a torn tail (crash) is ignored."""
    _, channels, messages = _complete_records(Path(path))
    return [(channels[m.channel_id].topic, json.loads(m.data)) for m in messages]
