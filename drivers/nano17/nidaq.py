"""NI-DAQmx gauge source: the Nano17's gauges read by a National Instruments DAQ card.

nidaqmx is an optional extra (not one of palpd's dependencies): it is imported
only when this backend is opened, so a machine without it still imports drivers.
"""
from __future__ import annotations

import time
from urllib.parse import urlsplit

from drivers.errors import DriverInitializationError, DriverOperationError
from drivers.nano17.calfile import load_calibration
from drivers.nano17.daq import DaqSensor, GaugeSource


class NidaqmxSource(GaugeSource):
    def __init__(self, channels: str, rail_v: float = 10.0) -> None:
        try:
            import nidaqmx
        except ImportError:
            raise DriverInitializationError(
                "nidaqmx://: the optional nidaqmx package is not installed (pip install nidaqmx)") from None
        self.rail_v, self._errors = rail_v, getattr(nidaqmx, "DaqError", OSError)
        try:
            self._task = nidaqmx.Task()
            self._task.ai_channels.add_ai_voltage_chan(channels, min_val=-rail_v, max_val=rail_v)
        except self._errors as exc:
            raise DriverInitializationError(f"nidaqmx://{channels}: cannot open the channels: {exc}") from exc
        self.channels = channels

    def read_voltages(self) -> tuple[float, tuple[float, ...]]:
        try:
            volts = self._task.read()
        except self._errors as exc:
            raise DriverOperationError(f"nidaqmx://{self.channels}: read failed: {exc}") from exc
        return time.monotonic(), tuple(float(v) for v in volts)  # on-demand read: each one is a new conversion

    def close(self) -> None:
        self._task.close()


def open_nidaqmx_sensor(url: str, calibration_file: str = "", clock=None, stale_after_s: float = 0.01,
                        **_ignored) -> DaqSensor:
    """``nidaqmx://Dev1/ai0:5`` (six gauges; ai0:6 adds the thermistor); needs sensor.calibration."""
    parts = urlsplit(url)
    channels = parts.netloc + parts.path
    if not channels:
        raise DriverInitializationError(f"{url}: expected nidaqmx://DEVICE/CHANNELS, e.g. nidaqmx://Dev1/ai0:5")
    if not calibration_file:
        raise DriverInitializationError(f"{url}: a real DAQ needs the sensor's calibration file (sensor.calibration)")
    calibration = load_calibration(calibration_file)
    return DaqSensor(NidaqmxSource(channels), calibration, clock, stale_after_s)
