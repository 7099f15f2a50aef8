"""Command server: ROUTER socket, JSON requests {"id", "cmd", "args"} with replies that never block.

Every way a request can be wrong becomes an error reply with a code and a
message; nothing a client sends can raise out of here.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from typing import Any

import zmq
from pydantic import BaseModel, ValidationError

from drivers.errors import describe_validation_error
from palpd.bus.messages import COMMAND_ARGS, READ_ONLY_COMMANDS, Request
from palpd.bus.publisher import bind_or_close
from palpd.bus.replies import REPLY_MODELS
from palpd.bus.security import LOCAL, OPERATOR

log = logging.getLogger("palpd.commands")

MAX_MESSAGE_BYTES = 1 << 16  # a bigger message disconnects its sender instead of eating memory
MAX_ERROR_CHARS = 300


class CommandError(Exception):
    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code, self.message = code, message


@dataclass
class Command:
    envelope: list[bytes]  # routing frames to send the reply back
    id: str | int | None
    cmd: str
    args: BaseModel | None
    role: str


class CommandServer:
    def __init__(self, context: zmq.Context, endpoint: str, security) -> None:
        self.security = security
        self.socket = context.socket(zmq.ROUTER)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.MAXMSGSIZE, MAX_MESSAGE_BYTES)
        security.secure(self.socket)
        bind_or_close(self.socket, endpoint)

    def receive(self) -> Command | None:
        """One request parsed and checked; a bad one is answered here and None returned."""
        frames = self.socket.recv_multipart(copy=False)
        envelope = [f.bytes for f in frames[:-1]]
        role = self.security.role_of(_user_id(frames[-1]))
        command = Command(envelope, None, "", None, role)
        try:
            request = parse_request(frames[-1].bytes)
            command.id, command.cmd = request.id, request.cmd
            command.args = parse_args(request)
            check_role(request.cmd, role)
        except CommandError as exc:
            self.fail(command, exc.code, exc.message)
            return None
        return command

    def reply(self, command: Command, **body: Any) -> None:
        """A successful reply, checked against its published schema (reply.CMD) before it goes out."""
        try:
            reply = REPLY_MODELS[command.cmd].model_validate({"id": command.id, "ok": True, **body})
        except ValidationError as exc:  # a bug: say so, and never send what the schema does not promise
            log.error("%s reply breaks its schema: %s", command.cmd, describe_validation_error("reply", exc))
            self.fail(command, "internal", f"{command.cmd}: the daemon's reply broke its schema")
            return
        self._send(command, reply.model_dump_json().encode())

    def fail(self, command: Command, code: str, message: str) -> None:
        if len(message) > MAX_ERROR_CHARS:  # a huge bad value must not come back whole
            message = message[:MAX_ERROR_CHARS] + "..."
        log.debug("%s refused (%s): %s", command.cmd or "request", code, message)
        body = {"id": command.id, "ok": False, "error": {"code": code, "message": message}}
        self._send(command, json.dumps(body).encode())

    def _send(self, command: Command, body: bytes) -> None:
        try:  # ROUTER drops replies to a vanished or saturated peer instead of blocking
            self.socket.send_multipart([*command.envelope, body], zmq.NOBLOCK)
        except zmq.ZMQError:
            pass

    def close(self) -> None:
        self.socket.close(linger=0)


def _user_id(frame: zmq.Frame) -> str | None:
    try:
        return frame.get("User-Id")
    except zmq.ZMQError:
        return None


def parse_request(raw: bytes) -> Request:
    try:
        data = json.loads(raw)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise CommandError("bad_json", f"request is not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise CommandError("bad_request", "request must be a JSON object {\"id\", \"cmd\", \"args\"}")
    try:
        return Request.model_validate(data, strict=True)
    except ValidationError as exc:
        raise CommandError("bad_request", describe_validation_error("request", exc)) from None


def parse_args(request: Request) -> BaseModel:
    model = COMMAND_ARGS.get(request.cmd)
    if model is None:
        raise CommandError("unknown_command", f"unknown command {request.cmd!r}; commands: {', '.join(COMMAND_ARGS)}")
    try:
        return model.model_validate_json(json.dumps(request.args), strict=True)
    except ValidationError as exc:
        raise CommandError("bad_args", describe_validation_error(f"{request.cmd} args", exc)) from None


def check_role(cmd: str, role: str) -> None:
    if role in (OPERATOR, LOCAL) or (role and cmd in READ_ONLY_COMMANDS):
        return
    raise CommandError("forbidden", f"{cmd} needs an operator key")
