"""What an installed palpd ships and how its command lines start: shipped scenes by name, files for installers,
--version, one-line errors, and validation before anything heavy is imported."""
import json
import logging
import os
import subprocess
import sys

from conftest import ROOT, SCENES, assert_one_line_error
from palpd.daemon.logs import JournalFormatter, setup_logging
from palpd.shipped import resolve_scene, scene_names, shipped_file

HEAVY = ("scipy.stats", "sklearn", "matplotlib")


def test_every_scene_in_config_ships_and_resolves_by_name_while_files_still_work():
    assert scene_names() == sorted(p.stem for p in SCENES.glob("*.toml"))
    for name in scene_names():
        assert resolve_scene(name).read_text() == (SCENES / f"{name}.toml").read_text()
    assert resolve_scene(SCENES / "paper.toml") == SCENES / "paper.toml"


def test_installer_files_ship_unchanged():
    assert shipped_file("systemd/palpd.service").read_text() == (ROOT / "systemd/palpd.service").read_text()
    assert shipped_file("palpd.toml").read_text() == (ROOT / "config/palpd.toml").read_text()
    assert shipped_file("calibration/FT8577.cal").read_bytes() == (ROOT / "config/calibration/FT8577.cal").read_bytes()


def test_scenes_version_and_an_unknown_scene_from_an_empty_directory(run_cli):
    listed = run_cli("scenes", "--json")
    assert listed.returncode == 0 and [s["name"] for s in json.loads(listed.stdout)] == scene_names()
    version = run_cli("--version")
    assert version.returncode == 0 and version.stdout.startswith("palpd ")
    unknown = run_cli("scan", "--scene", "nosuch")
    assert_one_line_error(unknown, "nosuch", "paper", "palpd scenes")
    assert unknown.returncode == 78  # a scene, like a config file, is configuration


def test_commands_check_arguments_and_config_before_importing_scipy_stats_sklearn_or_matplotlib(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[palpation]\ndepth_mm = 'deep'\n")
    calls = [["scan", "--scene", "paper", "--config", str(bad)], ["scan", "--scene", "nosuch"],
             ["serve", "--config", str(bad)], ["dataset", "--scene", "paper", "--palpations", "3", "--config", str(bad)],
             ["replay", str(tmp_path), "--config", str(bad)], ["bench", "loop", "--config", str(bad)],
             ["bench", "drivers", "--scene", "nosuch"], ["simulate", "--scene", "nosuch"], ["learner", "--config", str(bad)]]
    script = ("import contextlib, io, json, sys\nfrom palpd.cli import main\nout = []\n"
              f"for argv in {calls!r}:\n"
              "    with contextlib.redirect_stderr(io.StringIO()):\n        code = main(argv)\n"
              f"    out.append([argv[0], code, [m for m in {HEAVY!r} if m in sys.modules]])\n"
              "print(json.dumps(out))\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    for command, code, heavy in json.loads(result.stdout):
        assert code != 0 and heavy == [], (command, code, heavy)


def test_daemon_log_lines_carry_journald_priorities_under_systemd_and_times_elsewhere(tmp_path):
    with open(tmp_path / "log", "w+") as stream:
        info = os.fstat(stream.fileno())
        os.environ["JOURNAL_STREAM"] = f"{info.st_dev}:{info.st_ino}"
        try:
            logger = setup_logging("debug", stream)
        finally:
            del os.environ["JOURNAL_STREAM"]
        assert isinstance(logger.handlers[0].formatter, JournalFormatter)
        logging.getLogger("palpd.daemon").warning("servo %s", "late")
        logging.getLogger("palpd.daemon").debug("detail")
        stream.seek(0)
        assert stream.read().splitlines() == ["<4>palpd.daemon: servo late", "<7>palpd.daemon: detail"]
    with open(tmp_path / "plain", "w+") as stream:
        setup_logging("info", stream)
        logging.getLogger("palpd.daemon").info("ready")
        logging.getLogger("palpd.daemon").debug("hidden")
        stream.seek(0)
        (line,) = stream.read().splitlines()
        assert line.endswith("INFO    palpd.daemon: ready") and line[:4].isdigit()
    logging.getLogger("palpd").handlers.clear()
