"""Reading one request off the wire, as a client may have written it to hurt: bounded before it is parsed.

In order: the frame's size; then a scan of the raw bytes for nesting depth, string length and number length
(CPython turns a 5000-digit integer into a ValueError, and deep nesting into a RecursionError); then the JSON
parser, with hooks that refuse duplicate keys and numbers beyond float range; then the header ("id" and "cmd")
so the sender's role is checked before anything else of the request is looked at; then the arguments. Every
problem is a CommandError with a code and a one-line message, which the server sends back as an error reply.
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ValidationError

from drivers.errors import describe_validation_error
from palpd.bus.messages import COMMAND_ARGS, OBSERVER_COMMANDS
from palpd.bus.security import LOCAL, OPERATOR

MAX_REQUEST_BYTES = 1 << 16  # answered with an error beyond this (the transport cuts frames at MAX_FRAME_BYTES)
MAX_DEPTH = 16  # nested arrays and objects; a request needs 3
MAX_STRING_BYTES = 1024  # as written on the wire, escapes included
MAX_NUMBER_CHARS = 40  # a 64-bit integer has 20; a double needs at most 24
# Strings first, so brackets and digits inside them are not counted; an unterminated string leaves the rest
# to the JSON parser, which refuses it.
_TOKENS = re.compile(rb'"(?:[^"\\]|\\.)*"|[\[\]{}]|-?[0-9][0-9.eE+-]*')


class CommandError(Exception):
    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code, self.message = code, message


@dataclass
class Header:
    """What is known of a request once it parsed as JSON: its id (None unless a string or an integer) and cmd."""

    id: str | int | None
    cmd: str
    body: dict


def read_header(raw: bytes) -> Header:
    """The bounded, parsed request's header; CommandError (bad_request, bad_json) otherwise."""
    check_bounds(raw)
    data = decode_json(raw)
    if not isinstance(data, dict):
        raise CommandError("bad_request", 'request must be a JSON object {"id", "cmd", "args"}')
    request_id = data.get("id")
    if not isinstance(request_id, (str, int)) or isinstance(request_id, bool):
        request_id = None
    cmd = data.get("cmd")
    if not isinstance(cmd, str):
        raise CommandError("bad_request", 'request: cmd: expected the command\'s name, a string')
    return Header(request_id, cmd, data)


def check_bounds(raw: bytes) -> None:
    if len(raw) > MAX_REQUEST_BYTES:
        raise CommandError("bad_request", f"request is {len(raw)} bytes; at most {MAX_REQUEST_BYTES}")
    depth = 0
    for match in _TOKENS.finditer(raw):
        token = match.group()
        first = token[:1]
        if first == b'"':
            if len(token) - 2 > MAX_STRING_BYTES:
                raise CommandError("bad_request", f"a string of {len(token) - 2} bytes; at most {MAX_STRING_BYTES}")
        elif first in (b"[", b"{"):
            depth += 1
            if depth > MAX_DEPTH:
                raise CommandError("bad_request", f"nested deeper than {MAX_DEPTH} levels")
        elif first in (b"]", b"}"):
            depth -= 1
        elif len(token) > MAX_NUMBER_CHARS:
            raise CommandError("bad_request", f"a number of {len(token)} characters; at most {MAX_NUMBER_CHARS}")


def decode_json(raw: bytes) -> Any:
    try:
        text = raw.decode("utf-8")
        data = json.loads(text, object_pairs_hook=_unique_keys, parse_float=_finite_float,
                          parse_constant=_no_constant)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise CommandError("bad_json", f"request is not JSON: {exc}") from None
    try:  # "\ud800" is valid JSON but no character: refused here, not when a log line or journal meets it
        json.dumps(data, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        raise CommandError("bad_request", "a string holds an unpaired surrogate (not Unicode text)") from None
    return data


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    data = dict(pairs)
    if len(data) != len(pairs):
        seen = set()
        duplicate = next(key for key, _ in pairs if key in seen or seen.add(key))
        raise CommandError("bad_request", f"duplicate key {duplicate[:40]!r}")
    return data


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise CommandError("bad_request", f"number {text[:40]} is beyond float range")
    return value


def _no_constant(name: str):
    raise CommandError("bad_json", f"request is not JSON: {name} is not a JSON number")


def check_role(cmd: str, role: str) -> None:
    if role in (OPERATOR, LOCAL) or (role and cmd in OBSERVER_COMMANDS):
        return
    raise CommandError("forbidden", f"{cmd[:40]} needs an operator key")


def parse_args(cmd: str, body: dict) -> BaseModel:
    """The command's validated arguments (the request's other keys are checked here too)."""
    from palpd.bus.messages import Request

    model = COMMAND_ARGS.get(cmd)
    if model is None:
        raise CommandError("unknown_command", f"unknown command {cmd[:40]!r}; commands: {', '.join(COMMAND_ARGS)}")
    try:
        request = Request.model_validate(body, strict=True)
    except ValidationError as exc:
        raise CommandError("bad_request", describe_validation_error("request", exc)) from None
    try:  # from JSON, strict: [1, 2] is a tuple there, "5" is still not a number
        return model.model_validate_json(json.dumps(request.args), strict=True)
    except ValidationError as exc:
        raise CommandError("bad_args", describe_validation_error(f"{cmd} args", exc)) from None
