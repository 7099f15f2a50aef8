import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "config" / "scenes"


@pytest.fixture
def run_cli(tmp_path):
    """Run a console command as a real process; returns CompletedProcess with text output."""

    def run(*args: str, module: str = "palpd", env: dict | None = None) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", module, *map(str, args)],
            capture_output=True, text=True, timeout=120, cwd=tmp_path, env=env,
        )

    return run


def assert_one_line_error(result: subprocess.CompletedProcess, *fragments: str) -> None:
    """A failed command says what is wrong in one line, with no traceback."""
    assert result.returncode != 0, result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


# Tests whose servo loop runs on the wall clock (a real-time servo process, a separately started simulator, a
# timed bench). `make test` runs two xdist workers; these share one worker, one at a time, so two real-time
# loops never compete for the two cores while the other worker keeps the CPU-bound (virtual-time) tests going.
WALL_CLOCK_MODULES = {"test_simulate", "test_serve_remote", "test_servo_process", "test_bench_servo", "test_bridge",
                      "test_netft", "test_usb"}


def pytest_collection_modifyitems(items):
    """xdist groups (`--dist loadgroup`): the wall-clock modules in one group, every other module in its own,
    so a module's fixtures are set up once, on one worker."""
    for item in items:
        module = item.path.stem
        item.add_marker(pytest.mark.xdist_group("wall_clock" if module in WALL_CLOCK_MODULES else module))
