"""A separately started `palpd simulate` (bridge over TCP or a pty, Net F/T over UDP), and a config naming it."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from conftest import SCENES


def serve_simulator(cwd, *options, scene: Path = SCENES / "paper.toml"):
    """Start `palpd simulate`, yield {kind: url} once it says ready, terminate it afterwards."""
    process = subprocess.Popen([sys.executable, "-m", "palpd", "simulate", "--scene", str(scene), *options],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd)
    endpoints = {}
    try:
        for line in process.stdout:
            if line.strip() == "ready":
                break
            kind, url = line.split()
            endpoints[kind] = url
        yield endpoints
    finally:
        process.terminate()
        process.wait(5)
        process.stdout.close()
        process.stderr.close()


def bench_config(path: Path, endpoints: dict, extra: str = "") -> Path:
    """The settings a user writes for a bench: only where the bridge and the sensor are. Safety and timing stay
    default (the loop rides out a loaded host by design)."""
    path.write_text(f'[robot]\nurl = "{endpoints["bridge"]}"\n[sensor]\nbackend = "{endpoints["netft"]}"\n{extra}')
    return path
