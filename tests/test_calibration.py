"""Nano17 calibration files, the DAQ layer, and the nidaqmx backend against a fake module."""
import json
import sys
import types

import numpy as np
import pytest
from hypothesis import given, strategies as st

import drivers
from conftest import ROOT, assert_one_line_error
from drivers.errors import DriverInitializationError
from drivers.interfaces import SAMPLE_INVALID, SAMPLE_REPEAT, SAMPLE_SATURATED, SAMPLE_STALE
from drivers.nano17.calfile import load_calibration
from drivers.nano17.calibration import tool_transform
from drivers.nano17.daq import DaqSensor, GaugeSource

CAL = ROOT / "config" / "calibration" / "FT8577.cal"
USER_AXIS_FZ = [3.74583, 0.11288, 3.84196, 0.02560, 3.70096, -0.10953]


def test_the_real_nano17_file():
    cal = load_calibration(CAL)
    assert (cal.serial, cal.body_style, cal.part_number) == ("FT8577", "Nano17", "SI-25-0.25")
    assert (cal.force_units, cal.torque_units, cal.gauges) == ("N", "N-mm", 6)
    assert cal.ranges == (25, 25, 35, 250, 250, 250)
    assert list(cal.matrix[2]) == pytest.approx(USER_AXIS_FZ)
    assert cal.check_agreement() < 1e-4  # UserAxis = BasicTransform(Axis / scale)


def test_a_disagreeing_file_is_reported(tmp_path):
    text = CAL.read_text().replace('Dz="6.096"', 'Dz="9.0"')
    (tmp_path / "bad.cal").write_text(text)
    assert load_calibration(tmp_path / "bad.cal").check_agreement() > 1.0


def test_units_convert_forces_and_torques():
    cal = load_calibration(CAL)
    volts = np.array([0.1, -0.2, 0.3, 0.05, -0.1, 0.2])
    in_n = cal.matrix @ volts
    other = cal.in_units("lbf", "N-m")
    assert other.matrix @ volts == pytest.approx(np.r_[in_n[:3] / 4.4482216152605, in_n[3:] / 1000.0])
    with pytest.raises(DriverInitializationError, match="unknown force unit 'stone'"):
        cal.in_units("stone")


def test_tool_transform_moves_the_torque_reference_point():
    force, torque = np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 0.0])
    moved = tool_transform((0.0, 0.0, 10.0), (0.0, 0.0, 0.0)) @ np.r_[force, torque]
    assert moved[3:] == pytest.approx(-np.cross([0.0, 0.0, 10.0], force))
    turned = tool_transform((0, 0, 0), (0, 0, 90)) @ np.r_[1.0, 0, 0, 0, 0, 0]
    assert turned[:3] == pytest.approx([0.0, -1.0, 0.0])  # axes turned +90 deg about z: old x is new -y


@given(st.lists(st.floats(-20, 20), min_size=6, max_size=6))
def test_voltages_and_loads_round_trip(load):
    cal = load_calibration(CAL)
    volts = np.linalg.solve(cal.matrix, load)
    assert cal.matrix @ volts == pytest.approx(load, abs=1e-9)


class ScriptedSource(GaugeSource):
    def __init__(self, readings):
        self.readings = list(readings)

    def read_voltages(self):
        return self.readings.pop(0)


def test_daq_sensor_flags_rails_range_nan_and_stale():
    cal = load_calibration(CAL)
    quiet = (0.0,) * 6
    beyond_range = tuple(np.linalg.solve(cal.matrix, [0, 0, 40.0, 0, 0, 0]))  # 40 N > 35 N Fz range
    source = ScriptedSource([(1.0, quiet), (2.0, (9.99, 0, 0, 0, 0, 0)), (3.0, beyond_range),
                             (4.0, (float("nan"),) * 6), (4.0, quiet), (5.0, quiet + (1.7,))])

    class Clock:
        t = 0.0

        def now(self):
            self.t += 0.02
            return self.t

    sensor = DaqSensor(source, cal, Clock(), stale_after_s=0.01)
    flags = [sensor.read().flags for _ in range(6)]
    assert flags == [0, SAMPLE_SATURATED, SAMPLE_SATURATED, SAMPLE_INVALID, SAMPLE_REPEAT | SAMPLE_STALE, 0]
    assert sensor.thermistor_v == 1.7


def test_nidaqmx_backend_reads_through_the_fake_module(monkeypatch):
    cal = load_calibration(CAL)
    volts = list(np.linalg.solve(cal.matrix, [0.0, 0.0, 2.0, 0.0, 0.0, 0.0]))
    opened = {}

    class FakeTask:
        def __init__(self):
            self.ai_channels = self

        def add_ai_voltage_chan(self, channels, min_val, max_val):
            opened.update(channels=channels, range=(min_val, max_val))

        def read(self):
            return volts

        def close(self):
            opened["closed"] = True

    monkeypatch.setitem(sys.modules, "nidaqmx", types.SimpleNamespace(Task=FakeTask, DaqError=RuntimeError))
    sensor = drivers.open_sensor("nidaqmx://Dev1/ai0:5", calibration_file=str(CAL))
    assert sensor.read().force_n == pytest.approx((0.0, 0.0, 2.0), abs=1e-9)
    sensor.close()
    assert opened == {"channels": "Dev1/ai0:5", "range": (-10.0, 10.0), "closed": True}


def test_nidaqmx_missing_is_one_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "nidaqmx", None)  # import fails as if not installed
    with pytest.raises(DriverInitializationError, match="nidaqmx package is not installed"):
        drivers.open_sensor("nidaqmx://Dev1/ai0:5", calibration_file=str(CAL))


def test_cli_calibration_show_json_matches_user_axis(run_cli):
    result = run_cli("calibration", "show", CAL, "--json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["serial"] == "FT8577" and info["part_number"] == "SI-25-0.25"
    assert np.allclose(info["user_matrix"][2], USER_AXIS_FZ, atol=1e-4)
    assert np.allclose(info["user_matrix"], load_calibration(CAL).matrix, atol=1e-4)
    text = run_cli("calibration", "show", CAL)
    assert "agree" in text.stdout and "FT8577" in text.stdout


@pytest.mark.parametrize("content, fragment", [
    (None, "calibration file not found"), ("<nope", "bad XML"), ("<Other/>", "expected <FTSensor>"),
])
def test_cli_calibration_show_bad_files(tmp_path, run_cli, content, fragment):
    path = tmp_path / "x.cal"
    if content is not None:
        path.write_text(content)
    assert_one_line_error(run_cli("calibration", "show", path), "x.cal", fragment)
