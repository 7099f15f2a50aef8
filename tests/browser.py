"""Debian's chromium, headless, driven over the DevTools protocol (websockets): load a page, read it, screenshot it."""
from __future__ import annotations

import base64
import contextlib
import itertools
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

from websockets.sync.client import connect

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


class HeadlessChromium:
    def __init__(self, url: str, profile: Path, width: int = 1100, height: int = 820) -> None:
        # Its scratch directory (a socket in it: the path must stay short) removed on close, not left in /tmp.
        self._scratch = tempfile.mkdtemp(prefix="palpd-chromium-")
        self.process = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--hide-scrollbars",
             f"--user-data-dir={profile}", "--remote-debugging-port=0", f"--window-size={width},{height}", url],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            env={**os.environ, "TMPDIR": self._scratch})
        port = self._devtools_port(profile / "DevToolsActivePort")
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as answer:
            page = next(t for t in json.load(answer) if t["type"] == "page")
        self._open = contextlib.ExitStack()
        self.socket = self._open.enter_context(connect(page["webSocketDebuggerUrl"], max_size=2**26, open_timeout=10))
        self._ids = itertools.count(1)

    def _devtools_port(self, active_port: Path, timeout_s: float = 30.0) -> int:
        give_up = time.monotonic() + timeout_s
        while time.monotonic() < give_up:
            if active_port.exists() and active_port.read_text().strip():
                return int(active_port.read_text().split()[0])
            assert self.process.poll() is None, "chromium exited at start"
            time.sleep(0.05)
        raise AssertionError("chromium did not open its DevTools port")

    def send(self, method: str, **params) -> dict:
        request_id = next(self._ids)
        self.socket.send(json.dumps({"id": request_id, "method": method, "params": params}))
        while True:
            answer = json.loads(self.socket.recv(timeout=30))
            if answer.get("id") == request_id:
                assert "error" not in answer, answer
                return answer["result"]

    def evaluate(self, expression: str):
        return self.send("Runtime.evaluate", expression=expression, returnByValue=True)["result"].get("value")

    def wait_for(self, expression: str, timeout_s: float = 30.0):
        """The value of a JavaScript expression once it is truthy."""
        give_up = time.monotonic() + timeout_s
        while time.monotonic() < give_up:
            value = self.evaluate(expression)
            if value:
                return value
            time.sleep(0.1)
        raise AssertionError(f"the page never satisfied {expression}")

    def screenshot(self, path: Path) -> Path:
        path.write_bytes(base64.b64decode(self.send("Page.captureScreenshot", format="png")["data"]))
        return path

    def close(self) -> None:
        self._open.close()
        self.process.kill()
        self.process.wait(10)
        shutil.rmtree(self._scratch, ignore_errors=True)
