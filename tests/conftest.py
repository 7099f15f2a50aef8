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
