"""A separately started `palpd simulate` (bridge over TCP or a pty, Net F/T over UDP), and a config naming it."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from conftest import SCENES

# Real time on a shared CI machine without real-time scheduling: the separately running simulator and palpd's
# servo process are descheduled for tens of ms now and then (on a bench a loop stall; here, the machine), so the
# transport timeouts and the two timing limits below sit at their upper bounds (palpd.settings_bounds), and the
# tip-speed limit allows the overshoot of an arm that kept its last current meanwhile (500+ mm/s seen at load 5
# on 2 cores). What is under test here is the wire path, not the timing (`palpd bench loop` measures that).
LOADED_HOST_SETTINGS = ('[safety]\nmax_tick_gap_s = 0.1\nmax_tip_speed_mm_s = 1000.0\n')


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
    """A config naming only the simulator's bridge and Net F/T URLs (plus the loaded-host timing)."""
    path.write_text(f'[robot]\nurl = "{endpoints["bridge"]}"\ntimeout_s = 0.1\n'
                    f'[sensor]\nbackend = "{endpoints["netft"]}"\ntimeout_s = 0.5\nstale_after_s = 0.1\n'
                    f'{LOADED_HOST_SETTINGS}{extra}')
    return path
