"""The published JSON Schemas (`palpd schema`, docs/protocol.md, MCAP and Foxglove channels).

Each carries `$schema` (draft 2020-12), an `$id` naming palpd's schema
version, a title and a description (the model's docstring; field docstrings
describe the fields).
"""
from __future__ import annotations

from pydantic import BaseModel

from palpd.bus.messages import COMMAND_ARGS, EVENT_MODELS, SCHEMA_VERSION, ErrorReply, Request
from palpd.bus.replies import REPLY_MODELS

DRAFT = "https://json-schema.org/draft/2020-12/schema"


def published_schema(name: str, model: type[BaseModel], mode: str = "serialization") -> dict:
    """mode "serialization" for what palpd sends (every field always present, so required),
    "validation" for what it receives (fields with defaults may be left out)."""
    schema = model.model_json_schema(mode=mode)
    return {"$schema": DRAFT, "$id": f"urn:palpd:schema:v{SCHEMA_VERSION}:{name}", **schema}


def all_schemas() -> dict[str, dict]:
    """Every event topic, the request, the error reply, each command's args and each command's reply."""
    sent: dict[str, type[BaseModel]] = {**EVENT_MODELS, "error": ErrorReply}
    sent |= {f"reply.{cmd}": model for cmd, model in REPLY_MODELS.items()}
    received: dict[str, type[BaseModel]] = {"request": Request}
    received |= {f"{cmd}.args": model for cmd, model in COMMAND_ARGS.items()}
    schemas = {name: published_schema(name, model) for name, model in sent.items()}
    schemas |= {name: published_schema(name, model, "validation") for name, model in received.items()}
    order = list(EVENT_MODELS) + ["request", "error"] + [f"{c}.args" for c in COMMAND_ARGS] \
        + [f"reply.{c}" for c in REPLY_MODELS]
    return {name: schemas[name] for name in order}
