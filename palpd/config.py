"""Settings: pydantic models read from TOML, with PALPD_SECTION__KEY environment overrides.

Unknown keys are refused at every level, so a typo never silently falls back to a default.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Annotated, Literal, Mapping

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from drivers.errors import describe_validation_error
from drivers.tomlfile import read_toml
from palpd.errors import ConfigError

ENV_PREFIX = "PALPD_"
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class RobotSettings(_Section):
    url: str = "sim://"
    current_limit_a: Annotated[float, Field(gt=0, le=5.5)] = 5.5  # the RE25's stall current


class SensorSettings(_Section):
    backend: str = "sim"
    # "link2": fixed to the arm's last link, so its axes tilt with the arm (the seed paper's bench);
    # "level": held level by a gimbal. A simulated scan takes this from the scene's sensor.tilt.
    mount: Literal["link2", "level"] = "link2"


class TissueSettings(_Section):
    """Where the tissue is registered on the bench; a simulated scan takes it from the scene."""

    origin_mm: tuple[Finite, Finite, Finite] = (0.0, -60.0, 0.0)
    size_mm: tuple[Positive, Positive] = (60.0, 60.0)


class ServoSettings(_Section):
    rate_hz: Annotated[float, Field(ge=100, le=4000)] = 1000.0


class ControlSettings(_Section):
    stiffness_n_per_mm: Annotated[float, Field(gt=0, le=5.0)] = 1.5
    damping_n_s_per_mm: NonNegative = 0.02
    velocity_filter_hz: Positive = 100.0


class PalpationSettings(_Section):
    depth_mm: Annotated[float, Field(gt=0, le=30)] = 4.0
    speed_mm_s: Annotated[float, Field(gt=0, le=100)] = 10.0  # indentation speed
    approach_speed_mm_s: Annotated[float, Field(gt=0, le=100)] = 20.0
    travel_speed_mm_s: Annotated[float, Field(gt=0, le=300)] = 80.0
    accel_mm_s2: Annotated[float, Field(gt=0, le=10000)] = 2000.0
    clearance_mm: Annotated[float, Field(gt=0, le=50)] = 4.0
    max_force_n: Positive = 4.0
    hold_s: NonNegative = 0.0
    contact_on_n: Positive = 0.06
    contact_off_n: Positive = 0.03
    force_axes: Literal["tissue", "sensor_z"] = "tissue"
    tare_samples: Annotated[int, Field(ge=1, le=10000)] = 200

    @model_validator(mode="after")
    def _hysteresis(self):
        if self.contact_off_n >= self.contact_on_n:
            raise ValueError("contact_off_n must be below contact_on_n (hysteresis)")
        return self


class SafetySettings(_Section):
    force_cap_n: Positive = 6.0
    workspace_margin_mm: NonNegative = 15.0
    max_tip_speed_mm_s: Positive = 400.0
    workspace_z_mm: tuple[Finite, Finite] = (-20.0, 80.0)  # tip height range above the tissue surface


class ScanSettings(_Section):
    strategy: Literal["raster", "random", "active"] = "raster"
    max_palpations: Annotated[int, Field(ge=1, le=10000)] = 81
    seed: Annotated[int, Field(ge=0)] = 0
    min_contrast: Annotated[float, Field(gt=0)] = 0.3  # lump must be this much stiffer than tissue


class BusSettings(_Section):
    events: str = "tcp://127.0.0.1:5555"
    commands: str = "tcp://127.0.0.1:5556"
    high_water_mark: Annotated[int, Field(ge=1, le=1_000_000)] = 1000  # per subscriber; beyond it PUB drops
    # CURVE: the daemon's secret key file (from `palpd keygen`) and directories of clients' public keys.
    # Required when an endpoint is not loopback or ipc.
    curve_secret_key: str = ""
    operator_keys: str = ""  # all commands
    observer_keys: str = ""  # events and read-only commands


class DaemonSettings(_Section):
    state_dir: str = ""  # sessions live here; "" = $STATE_DIRECTORY (systemd) or ~/.local/state/palpd
    scene: str = ""  # the simulated bench's scene, needed while robot.url is sim://
    realtime: bool = True  # simulated bench on the wall clock (false: virtual time, as fast as the CPU allows)
    stop_timeout_s: Positive = 10.0  # SIGTERM/scan.stop: wait this long for the palpation to finish, then abort


class Settings(_Section):
    robot: RobotSettings = RobotSettings()
    sensor: SensorSettings = SensorSettings()
    tissue: TissueSettings = TissueSettings()
    servo: ServoSettings = ServoSettings()
    control: ControlSettings = ControlSettings()
    palpation: PalpationSettings = PalpationSettings()
    safety: SafetySettings = SafetySettings()
    scan: ScanSettings = ScanSettings()
    bus: BusSettings = BusSettings()
    daemon: DaemonSettings = DaemonSettings()

    @model_validator(mode="after")
    def _palpation_below_cap(self):
        if self.palpation.max_force_n >= self.safety.force_cap_n:
            raise ValueError(
                f"palpation.max_force_n ({self.palpation.max_force_n} N) must be below "
                f"safety.force_cap_n ({self.safety.force_cap_n} N)"
            )
        return self

    def updated(self, **sections: dict) -> "Settings":
        """A copy with some keys replaced, validated like a file (e.g. from command-line flags)."""
        data = self.model_dump()
        for section, values in sections.items():
            data[section].update({k: v for k, v in values.items() if v is not None})
        return _validate(data, "command line")


def load_settings(path: str | Path | None = None, environ: Mapping[str, str] | None = None) -> Settings:
    """Defaults, then the TOML file if given, then PALPD_ environment overrides."""
    data = read_toml(Path(path), "config file", ConfigError) if path is not None else {}
    source = str(path) if path is not None else "built-in defaults"
    overrides = _environment_overrides(os.environ if environ is None else environ)
    for dotted, (name, value) in overrides.items():
        _set_dotted(data, dotted, value, name)
    return _validate(data, source, overrides)


def _validate(data: dict, source: str, overrides: dict | None = None) -> Settings:
    try:
        return Settings.model_validate(data)
    except ValidationError as exc:
        loc = ".".join(str(p) for p in exc.errors()[0]["loc"])
        env_name = (overrides or {}).get(loc, (None, None))[0]
        raise ConfigError(describe_validation_error(f"environment {env_name}" if env_name else source, exc)) from None


def _environment_overrides(environ: Mapping[str, str]) -> dict[str, tuple[str, object]]:
    """{dotted.path: (VARIABLE, value)} for each PALPD_SECTION__KEY variable."""
    found = {}
    for name, raw in environ.items():
        if not name.startswith(ENV_PREFIX) or "__" not in name:
            continue
        dotted = ".".join(part.lower() for part in name[len(ENV_PREFIX):].split("__"))
        try:
            value = json.loads(raw)  # numbers, booleans and lists as JSON; anything else stays text
        except json.JSONDecodeError:
            value = raw
        found[dotted] = (name, value)
    return found


def _set_dotted(data: dict, dotted: str, value: object, name: str) -> None:
    *parents, leaf = dotted.split(".")
    node = data
    for part in parents:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ConfigError(f"environment {name}: {part} is a value, not a section")
        node = child
    node[leaf] = value
