"""The live view's HTTP server: the page, a JSON snapshot, and server-sent events (stdlib http.server).

GET /         the page (index.html, live.js: no build step, no CDN); /?snapshot=1 draws /state once and
              keeps no stream open (for a headless browser's screenshot: docs/how-to/screenshot-live-view.md)
GET /state    the current snapshot as JSON: status, estimate, probes, map, faults (current only), tissue size
GET /events   text/event-stream: a `snapshot` event at once, then `status`, `estimate`, `probes`, `map`, `fault`

Each /events client has a bounded queue: a client that stops reading is dropped, never waited for.
A non-loopback address needs `daemon.http_token` (sent as ?token= or `Authorization: Bearer`); the page
loaded with it sets a session cookie that lets its script and event stream in.
"""
from __future__ import annotations

import hmac
import json
import logging
import queue
import threading
from http.cookies import SimpleCookie
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from urllib.parse import parse_qs, urlsplit

log = logging.getLogger("palpd.http")
CLIENT_QUEUE = 256  # updates a slow page may fall behind before it is dropped
KEEPALIVE_S = 10.0
COOKIE = "palpd_token"  # set on the page's load with the token: its live.js and /events come without one
ASSETS = {"/": ("index.html", "text/html; charset=utf-8"), "/live.js": ("live.js", "text/javascript; charset=utf-8")}


class LiveState:
    """What the page shows, updated from the supervisor's thread and read by the server's threads."""

    def __init__(self, tissue_size_mm) -> None:
        self._lock = threading.Lock()
        self._snapshot = {"status": None, "estimate": None, "probes": [], "map": None, "faults": [],
                          "tissue_size_mm": list(tissue_size_mm)}
        self._clients: set[queue.Queue] = set()

    def snapshot(self) -> dict:
        with self._lock:
            return json.loads(json.dumps(self._snapshot))

    def update(self, key: str, value, event: str | None = None, data=None) -> None:
        """Set one part of the snapshot and tell every page (event name and data default to key and value)."""
        message = _sse(event or key, value if data is None else data)
        with self._lock:
            self._snapshot[key] = value
            for client in list(self._clients):
                try:
                    client.put_nowait(message)
                except queue.Full:  # that page stopped reading: drop it rather than hold anything up
                    self._clients.discard(client)
                    _end(client)

    def subscribe(self) -> tuple[queue.Queue, bytes]:
        client: queue.Queue = queue.Queue(CLIENT_QUEUE)
        with self._lock:
            self._clients.add(client)
            return client, _sse("snapshot", self._snapshot)

    def unsubscribe(self, client: queue.Queue) -> None:
        with self._lock:
            self._clients.discard(client)

    def end_streams(self) -> None:
        with self._lock:
            for client in self._clients:
                _end(client)
            self._clients.clear()


def _end(client: queue.Queue) -> None:
    """Empty a client's queue and leave the end-of-stream mark, without ever blocking."""
    while not client.empty():
        try:
            client.get_nowait()
        except queue.Empty:
            break
    client.put_nowait(None)


def _sse(event: str, data) -> bytes:
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n".encode()


class LiveServer:
    def __init__(self, host: str, port: int, state: LiveState, token: str = "") -> None:
        self.state, self.token = state, token
        self.httpd = ThreadingHTTPServer((host, port), _handler_for(self))
        self.httpd.daemon_threads = True
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="palpd-http", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        host, port = self.httpd.server_address[:2]
        return f"http://{host}:{port}/"

    def authorised(self, handler: BaseHTTPRequestHandler) -> bool:
        """The token as ?token=, `Authorization: Bearer`, or the cookie the page's own load set (so the
        page's script and event stream, which the browser asks for without the token, are let in too)."""
        if not self.token:
            return True
        offered = parse_qs(urlsplit(handler.path).query).get("token", [""])[0]
        header = handler.headers.get("Authorization", "")
        if header.startswith("Bearer "):
            offered = header[len("Bearer "):]
        if not offered:
            cookie = SimpleCookie(handler.headers.get("Cookie", ""))
            offered = cookie[COOKIE].value if COOKIE in cookie else ""
        return hmac.compare_digest(offered.encode(), self.token.encode())

    def session_cookie(self) -> str | None:
        """Set-Cookie for an authorised page load: the browser's session only, never sent to another site
        or read by a script."""
        return f"{COOKIE}={self.token}; Path=/; HttpOnly; SameSite=Strict" if self.token else None

    def close(self) -> None:
        self.state.end_streams()
        self.httpd.shutdown()
        self.httpd.server_close()


def _handler_for(server: LiveServer):
    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
            path = urlsplit(self.path).path
            if not server.authorised(self):
                self._send(401, b"a token is needed (?token=... or Authorization: Bearer ...)\n", "text/plain")
            elif path in ASSETS:
                name, kind = ASSETS[path]
                cookie = server.session_cookie() if path == "/" else None
                self._send(200, resources.files("palpd.web").joinpath(name).read_bytes(), kind, cookie)
            elif path == "/state":
                self._send(200, json.dumps(server.state.snapshot()).encode(), "application/json")
            elif path == "/events":
                self._stream()
            else:
                self._send(404, b"not found\n", "text/plain")

        def _send(self, code: int, body: bytes, kind: str, cookie: str | None = None) -> None:
            self.send_response(code)
            if cookie:
                self.send_header("Set-Cookie", cookie)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

        def _stream(self) -> None:
            client, first = server.state.subscribe()
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            try:
                self.wfile.write(first)
                self.wfile.flush()
                while (message := _next(client)) is not None:
                    self.wfile.write(message)
                    self.wfile.flush()
            except OSError:  # the page went away
                pass
            finally:
                server.state.unsubscribe(client)
                self.close_connection = True

        def log_message(self, format: str, *args) -> None:  # noqa: A002 (http.server's signature)
            log.debug("%s %s", self.address_string(), format % args)

    return Handler


def _next(client: queue.Queue) -> bytes | None:
    try:
        return client.get(timeout=KEEPALIVE_S)
    except queue.Empty:
        return b": keep-alive\n\n"
