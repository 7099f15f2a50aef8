"""Command server: ROUTER socket, JSON requests {"id", "cmd", "args"} with replies that never block.

Every way a request can be wrong becomes an error reply with a code and a
message (palpd.bus.requests reads it, bounded before it is parsed); anything
else that goes wrong while receiving one is an `internal` error reply. Nothing
a client sends can raise out of here.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from typing import Any

import zmq
from pydantic import BaseModel, ValidationError

from drivers.errors import describe_validation_error
from palpd.bus.publisher import bind_or_close
from palpd.bus.replies import REPLY_MODELS
from palpd.bus.requests import CommandError, check_role, parse_args, read_header

log = logging.getLogger("palpd.commands")

# Frames up to MAX_FRAME_BYTES are read and, beyond requests.MAX_REQUEST_BYTES, answered with an error; a bigger
# frame is cut by the transport (its sender is disconnected, unread) so no client can make the daemon hold more.
MAX_FRAME_BYTES = 1 << 20
RECEIVE_HWM = 100  # messages queued per client: a flood waits in the client's own queue, not in the daemon
MAX_ERROR_CHARS = 300


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
        self.socket.setsockopt(zmq.MAXMSGSIZE, MAX_FRAME_BYTES)
        self.socket.setsockopt(zmq.RCVHWM, RECEIVE_HWM)
        security.secure(self.socket)
        bind_or_close(self.socket, endpoint)

    def receive(self) -> Command | None:
        """One request parsed and checked; a bad one is answered here and None returned. Never raises."""
        try:
            frames = self.socket.recv_multipart(copy=False, flags=zmq.NOBLOCK)
        except zmq.ZMQError:
            return None  # nothing after all (or interrupted): the next poll tells
        command = Command([frames[0].bytes], None, "", None, "")
        try:
            body = self._unwrap(frames, command)
            command.role = self.security.role_of(_user_id(frames[-1]))
            return self._parse(body, command)
        except CommandError as exc:
            self.fail(command, exc.code, exc.message)
        except Exception as exc:  # a bug here must cost one request, never the daemon
            log.exception("reading a request failed")
            self.fail(command, "internal", f"the daemon could not read this request ({type(exc).__name__})")
        return None

    @staticmethod
    def _unwrap(frames, command: Command) -> bytes:
        """The body; a REQ client's empty delimiter frame goes back with the reply. More frames are refused."""
        if len(frames) == 3 and not frames[1].bytes:
            command.envelope.append(b"")
        elif len(frames) != 2:
            raise CommandError("bad_request", f"a request is one frame, not {len(frames) - 1}")
        return frames[-1].bytes

    @staticmethod
    def _parse(body: bytes, command: Command) -> Command:
        """Bounds, JSON, header (the error reply carries the id from here on), role, then the arguments."""
        header = read_header(body)
        command.id, command.cmd = header.id, header.cmd
        check_role(header.cmd, command.role)
        command.args = parse_args(header.cmd, header.body)
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
        log.debug("%s refused (%s): %s", command.cmd[:40] or "request", code, message)
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
