"""Who may talk to palpd: loopback/ipc endpoints by default, CURVE with two key lists otherwise.

Operators may send every command; observers may subscribe, send read-only
commands, and `estop` (anyone allowed to watch the arm may stop it; only an
operator restarts it). The ZAP handler (pyzmq's ThreadAuthenticator) refuses unknown keys
at the handshake, so a stranger gets nothing at all, not even an error reply.
Every process that binds a bus endpoint (the daemon, `palpd learner`) builds
its Security here, so each refuses a non-loopback endpoint without CURVE, and
key files anyone else could read or change (palpd.bus.keyfiles).
"""
from __future__ import annotations

import ipaddress
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from palpd.bus.keyfiles import key_list_problem, secret_key_problem
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
    problem = key_list_problem(path)
    if problem:
        raise ConfigError(f"bus.{setting}: {problem}")
    try:
        return {key.decode("ascii") for key in zmq.auth.load_certificates(path)}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"bus.{setting}: cannot read keys in {directory}: {exc}") from None


def load_secret_key(path: str, setting: str) -> tuple[bytes, bytes]:
    """(public, secret) of a key pair file (NAME.key_secret), refused if it is not private to this user."""
    problem = secret_key_problem(path)
    if problem:
        raise ConfigError(f"{setting}: {problem}")
    try:
        public, secret = zmq.auth.load_certificate(path)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{setting}: cannot read {path}: {exc}") from None
    if secret is None:
        raise ConfigError(f"{setting}: {path} holds no secret key (use NAME.key_secret from `palpd keygen`)")
    return public, secret


@dataclass
class Security:
    """The server's CURVE keys (or None) and the role of each known client key (z85)."""

    secret_key: bytes | None = None
    public_key: bytes | None = None
    roles: dict[str, str] = field(default_factory=dict)
    _auth: ThreadAuthenticator | None = None

    @classmethod
    def from_settings(cls, bus, endpoints: tuple[str, ...] = ("events", "commands")) -> "Security":
        """The Security of a process that binds these bus endpoints (setting names); ConfigError (one line) for a
        non-loopback endpoint without CURVE, or key files anyone else could read or change."""
        remote = [name for name in endpoints if not is_local_endpoint(getattr(bus, name))]
        if not bus.curve_secret_key:
            if remote:
                raise ConfigError(f"bus.{remote[0]} {getattr(bus, remote[0])} is not a loopback or ipc endpoint; it "
                                  f"needs CURVE keys (set bus.curve_secret_key and bus.operator_keys, see `palpd keygen`)")
            return cls()
        public, secret = load_secret_key(bus.curve_secret_key, "bus.curve_secret_key")
        roles = {key: OBSERVER for key in _public_keys(bus.observer_keys, "observer_keys")}
        roles.update({key: OPERATOR for key in _public_keys(bus.operator_keys, "operator_keys")})
        if not roles:
            raise ConfigError("bus: CURVE is on but bus.operator_keys and bus.observer_keys list no client key")
        # Who holds the daemon's own key pair runs on its host as its user: `palpd learner` subscribes with it.
        roles.setdefault(public.decode("ascii"), OBSERVER)
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

    def secure_client(self, socket: zmq.Socket) -> None:
        """Make a socket a CURVE client of the daemon with its own key pair (before connect): `palpd learner`."""
        if self.secret_key is not None:
            socket.curve_serverkey = self.public_key
            socket.curve_publickey = self.public_key
            socket.curve_secretkey = self.secret_key

    def role_of(self, user_id: str | None) -> str:
        if self.secret_key is None:
            return LOCAL  # only this machine can reach a loopback/ipc endpoint
        return self.roles.get(user_id or "", "")

    def stop(self) -> None:
        if self._auth is not None:
            self._auth.stop()
            self._auth = None
