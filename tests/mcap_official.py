"""Recordings read back with the official `mcap` package's readers, as Foxglove and the mcap tools read them."""
from __future__ import annotations

import json
from pathlib import Path

from mcap.reader import NonSeekingReader, make_reader


def read_closed(path: Path) -> dict:
    """A closed file through the seeking reader (summary first, as Foxglove opens files): header, summary,
    topic -> JSON Schema of every channel, and (topic, payload, log_time) of every message in file order."""
    with open(path, "rb") as handle:
        reader = make_reader(handle)
        header, summary = reader.get_header(), reader.get_summary()
        assert summary is not None, f"{path} has no summary"
        schemas = {channel.topic: json.loads(summary.schemas[channel.schema_id].data)
                   for channel in summary.channels.values()}
        assert all(summary.schemas[c.schema_id].encoding == "jsonschema" and c.message_encoding == "json"
                   for c in summary.channels.values())
        messages = [(channel.topic, json.loads(message.data), message.log_time)
                    for _, channel, message in reader.iter_messages(log_time_order=False)]
    return {"header": header, "summary": summary, "schemas": schemas, "messages": messages}


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
