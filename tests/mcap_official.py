"""palpd's MCAP files read back with the official `mcap` package (a test-only validator of palpd's own writer)."""
from __future__ import annotations

import json
from pathlib import Path

from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Channel, Schema
from mcap.stream_reader import StreamReader


def read_closed(path: Path) -> dict:
    """A properly closed file through the seeking reader (footer first, as Foxglove opens files)."""
    with open(path, "rb") as handle:
        reader = make_reader(handle)
        header = reader.get_header()
        messages = [(channel.topic, json.loads(message.data), message.log_time)
                    for _, channel, message in reader.iter_messages(log_time_order=False)]
        handle.seek(0)
        return {"header": header, "schemas": channel_schemas(StreamReader(handle)), "messages": messages}


def channel_schemas(stream: StreamReader) -> dict[str, dict]:
    """topic -> JSON Schema of every channel, including those no message was written to."""
    schemas, channels = {}, {}
    for record in stream.records:
        if isinstance(record, Schema):
            assert record.encoding == "jsonschema", record
            schemas[record.id] = json.loads(record.data)
        elif isinstance(record, Channel):
            assert record.message_encoding == "json", record
            channels[record.topic] = schemas[record.schema_id]
    return channels


def read_streaming(path: Path) -> tuple[list[tuple[str, dict]], Exception | None]:
    """Every message the official streaming reader yields, and the error it stops with (None: read to the end)."""
    messages = []
    with open(path, "rb") as handle:
        try:
            for _, channel, message in NonSeekingReader(handle).iter_messages(log_time_order=False):
                messages.append((channel.topic, json.loads(message.data)))
        except Exception as exc:  # the torn tail: EndOfFile, struct.error, a bogus record length...
            return messages, exc
    return messages, None
