"""Who watches the daemon besides bus subscribers: the live web view (`daemon.http`) and, with the optional
Foxglove SDK, a Foxglove WebSocket server (`daemon.foxglove`). Each sees every event the supervisor publishes
(`event`), the learner's posterior map (`map`) and, after a restart, the session's palpations so far (`probes`).
"""
from __future__ import annotations

import time

from palpd.bus.security import is_local_endpoint
from palpd.errors import ConfigError, PalpdError

MAX_FAULTS_SHOWN = 20
MIN_TOKEN_CHARS = 16  # a shorter token could be guessed


def open_viewers(daemon_settings, tissue_size_mm) -> list:
    viewers = []
    try:
        if daemon_settings.http:
            viewers.append(LiveView(daemon_settings.http, daemon_settings.http_token, tissue_size_mm))
        if daemon_settings.foxglove:
            viewers.append(FoxgloveStream(daemon_settings.foxglove))
    except PalpdError:
        for viewer in viewers:
            viewer.close()
        raise
    return viewers


def parse_address(text: str, setting: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or int(port) > 65535:
        raise ConfigError(f"{setting} {text!r}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    return host.strip("[]"), int(port)


def check_live_view(address: str, token: str) -> tuple[str, int]:
    """(host, port) of daemon.http; ConfigError unless it is loopback or protected by a token hard to guess."""
    host, port = parse_address(address, "daemon.http")
    if is_local_endpoint(f"tcp://{host}:{port}"):
        return host, port
    if not token:
        raise ConfigError(f"daemon.http {address!r} is not a loopback address; the live view there needs "
                          f"daemon.http_token (or bind it to 127.0.0.1)")
    if len(token) < MIN_TOKEN_CHARS:
        raise ConfigError(f"daemon.http_token has {len(token)} characters; a token on the network needs at least "
                          f"{MIN_TOKEN_CHARS} (e.g. python3 -c 'import secrets; print(secrets.token_urlsafe())')")
    return host, port


class LiveView:
    """Feeds the web page's state (palpd.web.server) from the daemon's events."""

    def __init__(self, address: str, token: str, tissue_size_mm) -> None:
        from palpd.web.server import LiveServer, LiveState

        host, port = check_live_view(address, token)
        self.state = LiveState(tissue_size_mm)
        try:
            self.server = LiveServer(host, port, self.state, token)
        except OSError as exc:
            raise PalpdError(f"daemon.http {address}: cannot listen: {exc.strerror or exc}") from None
        self._session, self._probes, self._faults, self._state = None, [], [], None
        self.what, self.url = "live view", self.server.url

    def event(self, topic: str, payload: dict) -> None:
        if topic == "status":
            if payload["session"] != self._session:
                self.probes([], payload["session"])
            if self._state == "fault" and payload["state"] != "fault" and self._faults:
                self._faults = []  # cleared by reset: the panel shows the faults that stand, not old ones
                self.state.update("faults", self._faults)
            self._state = payload["state"]
            self.state.update("status", payload)
        elif topic == "estimate":
            self.state.update("estimate", payload)
        elif topic in ("palpation", "stiffness"):
            self._on_probe(topic, payload)
        elif topic == "fault":
            self._faults = [*self._faults, {k: payload[k] for k in ("t", "code", "message")}][-MAX_FAULTS_SHOWN:]
            self.state.update("faults", self._faults)

    def _on_probe(self, topic: str, payload: dict) -> None:
        if topic == "palpation":
            self._probes.append({"index": payload["index"], "xy_mm": payload["xy_mm"],
                                 "target_xy_mm": payload.get("target_xy_mm") or payload["xy_mm"],
                                 "stiffness_n_per_mm": None, "rejected": payload.get("rejected")})
        else:
            for probe in self._probes:
                if probe["index"] == payload["index"]:
                    probe["stiffness_n_per_mm"] = payload["stiffness_n_per_mm"]
        self.state.update("probes", [dict(p) for p in self._probes])

    def map(self, posterior: dict | None) -> None:
        self.state.update("map", posterior)

    def probes(self, records: list[dict], session: str) -> None:
        self._session, self._probes = session, [dict(r) for r in records]
        self.state.update("probes", [dict(p) for p in self._probes])

    def close(self) -> None:
        self.server.close()


class FoxgloveStream:
    """Every bus topic as a JSON channel of the same name on a Foxglove WebSocket server (the SDK's). The SDK
    (0.30) accepts the WebSocket subprotocol `foxglove.sdk.v1` only (the Foxglove app asks for it); a client
    asking for `foxglove.websocket.v1` alone is refused with HTTP 400 (docs/how-to/foxglove.md)."""

    def __init__(self, address: str) -> None:
        try:
            import foxglove
        except ImportError:
            raise ConfigError("daemon.foxglove is set but the Foxglove SDK is missing: "
                              "pip install 'palpd[foxglove]'") from None
        from palpd.bus.messages import EVENT_MODELS, recording_schemas

        host, port = parse_address(address, "daemon.foxglove")
        if not is_local_endpoint(f"tcp://{host}:{port}"):  # the SDK's server has no authentication
            raise ConfigError(f"daemon.foxglove {address!r}: only a loopback address (the Foxglove server has "
                              f"no authentication; reach it through an SSH tunnel)")
        self.context = foxglove.Context()
        try:
            self.server = foxglove.start_server(name="palpd", host=host, port=port, context=self.context)
        except Exception as exc:  # the SDK raises its own error types for a port in use
            raise PalpdError(f"daemon.foxglove {address}: cannot listen: {exc}") from None
        # the bus topics only: the 1 kHz raw samples are the recording's, never streamed, so never advertised
        self.channels = {topic: foxglove.Channel(topic, schema=schema, context=self.context)
                         for topic, schema in recording_schemas().items() if topic in EVENT_MODELS}
        self.what, self.url = "Foxglove WebSocket", f"ws://{host}:{self.server.port}"

    def event(self, topic: str, payload: dict) -> None:
        self.channels[topic].log(payload, log_time=time.time_ns())

    def map(self, posterior) -> None:
        """Foxglove shows the events; the posterior map is the web view's."""

    def probes(self, records, session) -> None:
        """Foxglove shows palpations as they are published."""

    def close(self) -> None:
        self.server.stop()
