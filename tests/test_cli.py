import subprocess
import sys

from conftest import ROOT


def test_a_reader_that_leaves_early_gets_no_traceback():
    """`palpd schema | head -1`: the pipe closes under palpd, which ends quietly."""
    process = subprocess.Popen([sys.executable, "-m", "palpd", "schema"], cwd=ROOT,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()  # before palpd writes a byte
    stderr = process.stderr.read().decode()
    assert process.wait(timeout=60) == 141
    assert stderr == ""


def test_help_lists_every_command():
    result = subprocess.run([sys.executable, "-m", "palpd", "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    for command in ("scan", "serve", "learner", "simulate", "dataset", "study", "calibration", "schema",
                    "replay", "keygen", "bench"):
        assert f"    {command}" in result.stdout
