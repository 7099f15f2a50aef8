"""systemd/: the unit verifies, and reaches exactly the device nodes the (filled-in) udev rule names."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

SYSTEMD = Path(__file__).resolve().parent.parent / "systemd"
UNIT = SYSTEMD / "palpd.service"


def unit_settings() -> list[tuple[str, str]]:
    lines = [line.strip() for line in UNIT.read_text().splitlines()]
    return [tuple(line.split("=", 1)) for line in lines if "=" in line and not line.startswith("#")]


def filled_rule(vid: str, pid: str) -> str:
    return (SYSTEMD / "99-phantom-bridge.rules.in").read_text().replace("@BRIDGE_VID@", vid) \
        .replace("@BRIDGE_PID@", pid)


def test_the_installer_fills_in_every_id_of_the_udev_rule():
    rules = [line for line in filled_rule("abcd", "0123").splitlines() if line and not line.startswith("#")]
    assert len(rules) == 2 and "@" not in "".join(rules)
    for rule in rules:
        assert re.search(r'ATTRS?\{idVendor\}=="abcd"', rule) and re.search(r'ATTRS?\{idProduct\}=="0123"', rule)
        assert 'GROUP="palpd-bridge"' in rule and 'MODE="0660"' in rule


def test_the_unit_allows_exactly_the_nodes_the_rule_names():
    named = {f"/dev/{name}" for name in re.findall(r'SYMLINK\+="([^"]+)"', filled_rule("abcd", "0123"))}
    allowed = {value.split()[0] for key, value in unit_settings() if key == "DeviceAllow"}
    assert named == allowed == {"/dev/phantom-bridge", "/dev/phantom-bridge-usb"}
    assert ("DevicePolicy", "closed") in unit_settings()


def test_the_unit_is_a_notify_service_that_keeps_real_time():
    settings = dict(unit_settings())
    assert settings["Type"] == "notify" and settings["Restart"] == "on-failure"
    assert settings["RestartPreventExitStatus"] == "78" and float(settings["WatchdogSec"]) > 0
    assert settings["LimitMEMLOCK"] == "infinity" and int(settings["LimitRTPRIO"]) > 0
    assert "RestrictRealtime" not in settings and settings["StateDirectory"] == "palpd"


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze is not installed here")
def test_systemd_analyze_verify_passes(tmp_path):
    palpd = Path(sys.executable).parent / "palpd"  # ExecStart must exist: point it at this venv's palpd
    unit = tmp_path / "palpd.service"
    unit.write_text(UNIT.read_text().replace("/opt/palpd/.venv/bin/palpd", str(palpd)))
    result = subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and result.stderr.strip() == "", result.stderr
