"""Who may talk to palpd: loopback/ipc endpoints by default, CURVE with two key lists otherwise.

Operators may send every command; observers may subscribe and send read-only
commands. The ZAP handler (pyzmq's ThreadAuthenticator) refuses unknown keys
at the handshake, so a stranger gets nothing at all, not even an error reply.
"""
from __future__ import annotations

import ipaddress
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from palpd.errors import ConfigError

OPERATOR, OBSERVER, LOCAL = "operator", "observer", "local"


def is_local_endpoint(endpoint: str) -> bool:
    """ipc://, inproc:// and TCP on a loopback address are reachable from this machine only."""
    scheme = endpoint.split("://", 1)[0]
    if scheme in ("ipc", "inproc"):
        return True
    if scheme != "tcp":
        return False
    host = urlsplit(endpoint).hostname or ""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:  # "*", an interface name or a host name: may be reachable from outside
        return False


def _public_keys(directory: str, setting: str) -> set[str]:
    if not directory:
        return set()
    path = Path(directory)
    if not path.is_dir():
        raise ConfigError(f"bus.{setting}: {directory} is not a directory of public keys")
    try:
        return {key.decode("ascii") for key in zmq.auth.load_certificates(path)}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"bus.{setting}: cannot read keys in {directory}: {exc}") from None


@dataclass
class Security:
    """The server's CURVE keys (or None) and the role of each known client key (z85)."""

    secret_key: bytes | None = None
    public_key: bytes | None = None
    roles: dict[str, str] = field(default_factory=dict)
    _auth: ThreadAuthenticator | None = None

    @classmethod
    def from_settings(cls, bus) -> "Security":
        remote = [e for e in (bus.events, bus.commands) if not is_local_endpoint(e)]
        if not bus.curve_secret_key:
            if remote:
                raise ConfigError(f"bus: {remote[0]} is not a loopback or ipc endpoint; it needs CURVE keys "
                                  f"(set bus.curve_secret_key and bus.operator_keys, see `palpd keygen`)")
            return cls()
        try:
            public, secret = zmq.auth.load_certificate(bus.curve_secret_key)
        except (OSError, ValueError) as exc:
            raise ConfigError(f"bus.curve_secret_key: cannot read {bus.curve_secret_key}: {exc}") from None
        if secret is None:
            raise ConfigError(f"bus.curve_secret_key: {bus.curve_secret_key} holds no secret key")
        roles = {key: OBSERVER for key in _public_keys(bus.observer_keys, "observer_keys")}
        roles.update({key: OPERATOR for key in _public_keys(bus.operator_keys, "operator_keys")})
        if not roles:
            raise ConfigError("bus: CURVE is on but bus.operator_keys and bus.observer_keys list no client key")
        return cls(secret, public, roles)

    def start(self, context: zmq.Context) -> None:
        if self.secret_key is None:
            return
        self._auth = ThreadAuthenticator(context)
        self._auth.start()
        self._auth.configure_curve_callback("*", credentials_provider=self)

    def callback(self, domain: str, client_key: bytes) -> bool:
        """ZAP: admit a client only if its public key is on a list."""
        return client_key.decode("ascii") in self.roles

    def secure(self, socket: zmq.Socket) -> None:
        """Make a socket a CURVE server (before bind)."""
        if self.secret_key is not None:
            socket.curve_secretkey = self.secret_key
            socket.curve_publickey = self.public_key
            socket.curve_server = True

    def role_of(self, user_id: str | None) -> str:
        if self.secret_key is None:
            return LOCAL  # only this machine can reach a loopback/ipc endpoint
        return self.roles.get(user_id or "", "")

    def stop(self) -> None:
        if self._auth is not None:
            self._auth.stop()
            self._auth = None
