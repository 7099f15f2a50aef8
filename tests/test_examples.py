"""Examples as a user pastes them: palpd.simulate_scan from a plain script and from stdin, and every Python
block of the README and the tutorials saved to a file and run with `python FILE` in an empty directory."""
import subprocess
import sys

PLAIN_SCRIPT = """\
import palpd
report = palpd.simulate_scan("paper", max_palpations=2)
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
        assert "palpations 2" in result.stdout, result.stdout
