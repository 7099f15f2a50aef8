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


def test_building_the_parser_imports_neither_numpy_nor_the_config():
    """Every command, failing ones included, builds the whole parser first: a subcommand's add_parser that
    pulled in the control stack cost each `palpd` start ~0.1-0.2 s (bench loop's did, through numpy)."""
    script = ("import sys\nfrom palpd.cli import build_parser\nbuild_parser()\n"
              "print([m for m in ('numpy', 'pydantic', 'palpd.config') if m in sys.modules])")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and result.stdout.strip() == "[]", result.stdout + result.stderr


def test_a_daemon_starts_without_scipy_s_optimiser_or_special_functions():
    """`palpd serve` imports its scan code at start-up; the stiffness fits import scipy.optimize and
    scipy.special at their first fit, so a daemon is ready in half the CPU (~1.0 s -> ~0.5 s), and one that
    never palpates never pays for them."""
    script = ("import sys\nimport palpd.daemon.supervisor\n"
              "print([m for m in ('scipy.optimize', 'scipy.special', 'sklearn') if m in sys.modules])")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and result.stdout.strip() == "[]", result.stdout + result.stderr


def test_a_scan_imports_the_fits_scipy_before_its_motors_are_on():
    """...and a scan loads them before servo.start(): on the wall clock the first fit happens while the loop
    holds the arm, and half a second of imports beside it is CPU the loop does not need to share."""
    script = ("import sys\nfrom drivers.sim.scene import Scene\nfrom palpd.bench import open_simulated_bench\n"
              "from palpd.config import Settings\nfrom palpd.scan import plan, run_scan\n"
              "settings = Settings()\nbench = open_simulated_bench(settings, Scene(name='flat'))\n"
              "start = bench.servo.start\n"
              "def started():\n    print('scipy.optimize' in sys.modules, 'scipy.special' in sys.modules)\n"
              "    start()\n"
              "bench.servo.start = started\n"
              "print('scipy.optimize' in sys.modules)\n"
              "run_scan(bench, settings, plan('raster', (20, 20), 1, 0))")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:2] == ["False", "True True"], result.stdout


def test_palpctl_names_an_endpoint_it_cannot_connect_to_in_one_line(run_cli):
    """A typo in --endpoint was `palpctl: ZMQError: Invalid argument (addr='tcp//...')`."""
    from conftest import assert_one_line_error

    result = run_cli("--endpoint", "tcp//127.0.0.1:5555", "status", module="palpd.palpctl")
    assert_one_line_error(result, "'tcp//127.0.0.1:5555' is not an endpoint", "tcp://HOST:PORT")
    assert result.returncode == 1
