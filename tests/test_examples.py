"""Examples as a user pastes them: palpd.simulate_scan from a plain script and from stdin, and every Python
block of the README and the tutorials saved to a file and run with `python FILE` in an empty directory."""
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

from conftest import ROOT

TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.md"))

PLAIN_SCRIPT = """\
import palpd
report = palpd.simulate_scan("paper", max_palpations=1)
print("palpations", report["palpations"])
"""


def assert_ran_cleanly(result: subprocess.CompletedProcess) -> None:
    """Exit 0, no traceback, and no shared memory left for the resource tracker to find."""
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr and "leaked shared_memory" not in result.stderr, result.stderr


def test_simulate_scan_runs_from_a_script_without_a_main_guard_and_from_stdin(tmp_path):
    """The servo process is spawned without re-running the caller's script: a script with no
    `if __name__ == "__main__":` guard would otherwise start a second scan in the child (multiprocessing's
    "bootstrapping phase" error), and a script read from stdin has no file the child could run."""
    script = tmp_path / "scan.py"
    script.write_text(PLAIN_SCRIPT)
    as_file = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    from_stdin = subprocess.run([sys.executable, "-"], input=PLAIN_SCRIPT, cwd=tmp_path, text=True,
                                capture_output=True, timeout=120)
    stdout, stderr = as_file.communicate(timeout=120)
    for result in (subprocess.CompletedProcess(as_file.args, as_file.returncode, stdout, stderr), from_stdin):
        assert_ran_cleanly(result)
        assert "palpations 1" in result.stdout, result.stdout


def fenced_blocks(path: Path, language: str) -> list[str]:
    """The code of every ```LANGUAGE block of a Markdown file (the fence may be indented, as in a list)."""
    pattern = rf"^( *)```{language}\n(.*?)^\1```"
    return [textwrap.dedent(code) for _, code in re.findall(pattern, path.read_text(), re.S | re.M)]


def examples() -> list[tuple[str, list[str], str]]:
    """(where, command, code): every Python block of the README and the tutorials (`python FILE`), and every
    `sh` block of the tutorials (`sh -e FILE`; tutorials mark what needs hardware or a daemon as `bash`)."""
    found = {}  # by code: the README's script is the scripting tutorial's first, run once
    for path in [ROOT / "README.md", *TUTORIALS]:
        for i, code in enumerate(fenced_blocks(path, "python")):
            found.setdefault(code, (f"{path.name} python block {i + 1}", [sys.executable, "example.py"], code))
    for path in TUTORIALS:
        for i, code in enumerate(fenced_blocks(path, "sh")):
            found.setdefault(code, (f"{path.name} sh block {i + 1}", ["sh", "-e", "example.sh"], code))
    return list(found.values())


def test_every_example_of_the_readme_and_the_tutorials_runs_as_pasted(tmp_path):
    """Each block saved to a file in an empty directory of its own and run as a user would, side by side,
    with the venv's palpd and palpctl first on PATH (as after `pip install .` in an activated venv)."""
    blocks = examples()
    assert any(b[1][0] == sys.executable for b in blocks) and any(b[1][0] == "sh" for b in blocks)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    running = []
    for i, (where, command, code) in enumerate(blocks):
        directory = tmp_path / f"example-{i}"
        directory.mkdir()
        (directory / command[-1]).write_text(code)
        running.append((where, subprocess.Popen(command, cwd=directory, env=env, text=True,
                                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)))
    for where, process in running:
        stdout, stderr = process.communicate(timeout=180)
        result = subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)
        assert result.returncode == 0 and "Traceback" not in stderr, (where, stderr[-2000:])
