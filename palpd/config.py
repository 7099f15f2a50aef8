"""Settings: pydantic models read from TOML, with PALPD_SECTION__KEY environment overrides.

Unknown keys are refused at every level, so a typo never silently falls back to a default. Safety and
timing limits have upper bounds with reasons (palpd.settings_bounds), checked with the rules between settings.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Annotated, Literal, Mapping

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_validator

from drivers.errors import describe_validation_error
from drivers.sim.scene import TissueSide
from drivers.tomlfile import read_toml
from palpd.errors import ConfigError
from palpd.settings_bounds import bound_problem, consistency_problem

ENV_PREFIX = "PALPD_"
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class RobotSettings(_Section):
    url: str = "sim://"
    current_limit_a: Annotated[float, Field(gt=0, le=5.5)] = 5.5  # the RE25's stall current
    # The bridge's watchdog (PROTOCOL.md): after hold_after_s without a host frame it ramps the currents over
    # hold_ramp_s to the gravity hold each command carries; after watchdog_s it cuts the amplifiers.
    hold_after_s: Annotated[float, Field(ge=0.0005, le=0.05)] = 0.0015
    hold_ramp_s: Annotated[float, Field(ge=0.0005, le=0.1)] = 0.001
    watchdog_s: Annotated[float, Field(ge=0.002, le=60)] = 10.0
    timeout_s: Annotated[float, Field(gt=0, le=10)] = 0.05  # no answer from the bridge in this time: a fault

    @model_validator(mode="after")
    def _hold_before_cut(self):
        if self.watchdog_s <= self.hold_after_s + self.hold_ramp_s:
            raise ValueError("watchdog_s must be longer than hold_after_s + hold_ramp_s (hold first, then cut)")
        return self


class SensorSettings(_Section):
    backend: str = "sim"  # sim | netft://HOST[:PORT] | nidaqmx://Dev1/ai0:5
    # "link2": fixed to the arm's last link, so its axes tilt with the arm (the seed paper's bench);
    # "level": held level by a gimbal. A simulated scan takes this from the scene's sensor.tilt.
    mount: Literal["link2", "level"] = "link2"
    calibration: str = ""  # the sensor's ATI .cal file (needed by nidaqmx; the simulator brings its own)
    timeout_s: Annotated[float, Field(gt=0, le=10)] = 0.05  # no new sample for this long: stalled or unplugged
    stale_after_s: Annotated[float, Field(gt=0, le=10)] = 0.02  # a sample older than this is flagged stale
    counts_per_force: Positive = 1_000_000.0  # Net F/T counts per N
    counts_per_torque: Positive = 1_000_000.0  # Net F/T counts per N*m


class TissueSettings(_Section):
    """Where the tissue is registered on the bench; a simulated scan takes it from the scene."""

    origin_mm: tuple[Finite, Finite, Finite] = (0.0, -60.0, 0.0)
    size_mm: tuple[TissueSide, TissueSide] = (60.0, 60.0)


class ServoSettings(_Section):
    rate_hz: Annotated[float, Field(ge=100, le=4000)] = 1000.0


class ControlSettings(_Section):
    stiffness_n_per_mm: Annotated[float, Field(gt=0, le=5.0)] = 1.5
    damping_n_s_per_mm: NonNegative = 0.02
    velocity_filter_hz: Positive = 100.0


class PalpationSettings(_Section):
    depth_mm: Annotated[float, Field(gt=0, le=30)] = 4.0
    speed_mm_s: Annotated[float, Field(gt=0, le=100)] = 10.0  # indentation speed
    # "varying": the speed swings around speed_mm_s, so tissue damping b can be told from stiffness k
    speed_profile: Literal["constant", "varying"] = "constant"
    approach_speed_mm_s: Annotated[float, Field(gt=0, le=100)] = 20.0
    travel_speed_mm_s: Annotated[float, Field(gt=0, le=300)] = 80.0
    accel_mm_s2: Annotated[float, Field(gt=0, le=10000)] = 2000.0
    clearance_mm: Annotated[float, Field(gt=0, le=50)] = 4.0
    max_force_n: Positive = 4.0
    hold_s: NonNegative = 0.0
    # A press that meets max_force_n early (`too_stiff`, or a fit less certain than 10 %, palpd.scan):
    # "repalpate" presses the same spot once more at gentle_speed_factor times speed_mm_s (more samples over
    # the same shallow depth, less of the controller's lag: scripts/stiff_spots.py, a 30 N/mm lump in 5 N/mm
    # tissue read 25.1 ± 6.9 in one press, 30.2 ± 4.3 gently) and keeps the gentle reading; "bound" keeps the first press and moves on.
    too_stiff: Literal["repalpate", "bound"] = "repalpate"
    gentle_speed_factor: Annotated[float, Field(gt=0, lt=1)] = 0.25
    # Contact: the low-passed force (time constant contact_filter_s) rises contact_on_sd noise sds above the
    # zero, and ends below contact_off_sd, the noise measured at the tare; never below these floors in N.
    contact_on_n: Positive = 0.03  # above safety.drift_retare_n: a drift left uncorrected never reads as contact
    contact_off_n: Positive = 0.015
    contact_on_sd: Annotated[float, Field(ge=2, le=50)] = 5.0
    contact_off_sd: Annotated[float, Field(ge=1, le=50)] = 2.5
    contact_filter_s: Annotated[float, Field(ge=0, le=0.1)] = 0.01
    force_axes: Literal["tissue", "sensor_z"] = "tissue"
    tare_samples: Annotated[int, Field(ge=1, le=10000)] = 200
    # "sliding": stay in contact at sliding_depth_mm and move along a path, the indentation modulated by
    # ± modulation_mm at modulation_hz; each cycle's force against depth gives one stiffness point.
    mode: Literal["discrete", "sliding"] = "discrete"
    sliding_depth_mm: Annotated[float, Field(gt=0, le=30)] = 2.5
    sliding_speed_mm_s: Annotated[float, Field(gt=0, le=50)] = 30.0
    sliding_length_mm: Annotated[float, Field(gt=0, le=500)] = 30.0  # one path of the active planner
    modulation_mm: Annotated[float, Field(gt=0, le=10)] = 1.0
    modulation_hz: Annotated[float, Field(gt=0, le=20)] = 10.0

    @model_validator(mode="after")
    def _hysteresis(self):
        if self.contact_off_n >= self.contact_on_n:
            raise ValueError("contact_off_n must be below contact_on_n (hysteresis)")
        if self.modulation_mm >= self.sliding_depth_mm:
            raise ValueError("modulation_mm must be below sliding_depth_mm (the probe keeps contact)")
        if self.contact_off_sd >= self.contact_on_sd:
            raise ValueError("contact_off_sd must be below contact_on_sd (hysteresis)")
        return self


RATE_MODELS = ("kelvin-voigt", "hunt-crossley")  # damping terms: identifiable only when the speed varies


class StiffnessSettings(_Section):
    # "select" lets the data choose by `criterion`; a model name fixes it ("linear" is the seed paper's §3.1).
    model: Literal["select", "linear", "linear-offset", "kelvin-voigt", "power", "exponential", "hunt-crossley"] = "select"
    criterion: Literal["aicc", "bic"] = "bic"  # BIC: a 1 kHz trace has hundreds of samples, and AICc then admits noise-fitting terms
    reference_depth_mm: Annotated[float, Field(gt=0, le=30)] = 2.0  # where the one comparable stiffness is read


class SafetySettings(_Section):
    force_cap_n: Positive = 6.0
    max_lateral_force_n: Positive = 2.0  # drag or shear along the surface (sliding palpation): above it, a stop
    workspace_margin_mm: NonNegative = 15.0
    max_tip_speed_mm_s: Positive = 400.0
    workspace_z_mm: tuple[Finite, Finite] = (-20.0, 80.0)  # tip height range above the tissue surface
    joint_limit_margin_rad: NonNegative = 0.02  # stop this short of the hard stops
    max_joint_speed_rad_s: Positive = 20.0  # an encoder step faster than this is a glitch, not motion
    max_sample_age_s: Positive = 0.005  # a force sample older than this is stale (a frozen sensor)
    # Loop stalls: an ordinary kernel deschedules the servo for a few ms now and then, and the controller
    # and the bridge's hold ride that out; one gap beyond max_tick_gap_s, or more than late_budget_s of
    # lateness within about a second, is a stalled loop.
    max_tick_gap_s: Annotated[float, Field(gt=0, le=1)] = 0.1
    late_budget_s: Annotated[float, Field(gt=0, le=1)] = 0.25
    rigid_window_s: Annotated[float, Field(gt=0, le=5)] = 0.05  # at the cap with the tip still this long: rigid
    max_tracking_error_mm: Positive = 10.0  # the tip this far from its setpoint...
    tracking_window_s: Annotated[float, Field(gt=0, le=5)] = 0.1  # ...for this long: the controller cannot follow
    retract_speed_mm_s: Annotated[float, Field(gt=0, le=200)] = 60.0  # controlled stop: back out, then park, this fast
    retract_timeout_s: Annotated[float, Field(gt=0, le=5)] = 0.5  # not backed out by then: cut the current
    # Sensor health (palpd.control.health): a reading repeated this long is a frozen sensor; at every approach
    # the force out of contact over drift_window_s is compared with the tare: re-tare beyond drift_retare_n,
    # fault beyond drift_fault_n.
    frozen_window_s: Positive = 0.003
    drift_window_s: Positive = 0.05
    drift_retare_n: Positive = 0.02
    drift_fault_n: Positive = 0.5
    # While the motors push (in contact or not), the force read against the force the motor currents put on the
    # tip (palpd.control.health): further apart than force_mismatch_n for force_mismatch_window_s, the sensor
    # is wrong (a drifting zero reads the tissue lighter or heavier than the arm feels it).
    force_mismatch_n: Positive = 0.5
    force_mismatch_window_s: Positive = 0.02
    # Never deeper than the palpation's depth plus this below the tissue surface, whatever the force reads
    # (palpd.control.surface).
    indentation_margin_mm: Positive = 0.75


class ScanSettings(_Section):
    strategy: Literal["raster", "random", "active"] = "active"
    max_palpations: Annotated[int, Field(ge=1, le=10000)] = 81
    seed: Annotated[int, Field(ge=0)] = 0
    min_contrast: Annotated[float, Field(gt=0)] = 0.3  # lump must be this much stiffer than tissue


class LearnerSettings(_Section):
    """The online learner (--strategy active and `palpd learner`)."""

    confidence: Annotated[float, Field(gt=0.5, lt=1.0)] = 0.9  # stop when the lump count has this posterior mass...
    tolerance_mm: Annotated[float, Field(gt=0, le=100)] = 0.5  # ...and the expected boundary error (mm) this
    # the prior's expected count of lumps on the tissue before any reading: what weighs the area that lumps no
    # reading has felt yet could take, part of the expected boundary error (tolerance_mm)
    expected_lumps: Annotated[float, Field(ge=0, le=100)] = 1.0
    max_palpations: Annotated[int, Field(ge=1, le=10000)] = 40
    initial_points: Annotated[int, Field(ge=0, le=1000)] = 8  # first design: points of the covering lattice
    grid_points: Annotated[int, Field(ge=11, le=401)] = 121  # candidate grid, per side
    min_spacing_mm: NonNegative = 1.5
    coverage_mm: Positive = 18.0  # done only once every spot is this close to a reading: no lump left unfelt
    # ...and a `none` verdict only once every spot is this close (at most coverage_mm; the covering lattice's reach):
    # a sharp-edged lump is felt only a little beyond its radius (a 10 mm lump of sharpness 40 at 2 % of its height
    # 11 mm from its centre), so `none` rules out lumps of 10 mm radius and wider. On a tissue larger than a 60 mm
    # square the reach widens, up to coverage_mm, until the covering takes no more points than there (16): `none`
    # in ~18 palpations on any tissue, ruling out a little less (80 x 80 mm: 14.25 mm); the verdict says how much
    none_coverage_mm: Positive = 11.0
    # ...and, beside two or more lumps found, a spot within three radii of one farther than this many of the
    # smallest one's radii from a palpation is a hole a lump nearly touching them could lie in unfelt; the count
    # stands once its mass times the chance that none does (expected_lumps beside each found one) is `confidence`; 0: off
    satellite_reach: NonNegative = 1.5
    length_scale_mm: tuple[Positive, Positive] = (1.5, 8.0)  # bounds of the free-form map's kernel length scale
    refit_growth: Annotated[float, Field(gt=1.0)] = 1.3  # relearn that kernel when the data grew this much
    reading_noise_floor: Annotated[float, Field(gt=0, le=1)] = 0.01  # readings repeat no better than this fraction
    training_set: str = ""  # labelled dataset CSV (tumor column): τ learned from it; empty: τ from the data

    @model_validator(mode="after")
    def _bounds_in_order(self):
        if self.length_scale_mm[0] > self.length_scale_mm[1]:
            raise ValueError("length_scale_mm must be [low, high] with low <= high")
        return self


def _zmq_endpoint(value: str) -> str:
    """A ZeroMQ endpoint palpd binds or connects: tcp://HOST:PORT (port 1-65535), ipc://PATH or inproc://NAME.
    Checked here, as ZeroMQ itself took tcp://127.0.0.1:99999 without a word and "garbage" was reported as
    "not a loopback endpoint; it needs CURVE keys"."""
    scheme, separator, rest = value.partition("://")
    if not separator or scheme not in ("tcp", "ipc", "inproc") or not rest:
        raise ValueError("not a ZeroMQ endpoint (tcp://HOST:PORT, ipc://PATH)")
    host, colon, port = rest.rpartition(":")
    if scheme == "tcp" and not (colon and host and port.isdigit() and 1 <= int(port) <= 65535):
        raise ValueError("a tcp endpoint is tcp://HOST:PORT, its port from 1 to 65535")
    return value


Endpoint = Annotated[str, AfterValidator(_zmq_endpoint)]


class BusSettings(_Section):
    events: Endpoint = "tcp://127.0.0.1:5555"
    commands: Endpoint = "tcp://127.0.0.1:5556"
    learner_events: Endpoint = "tcp://127.0.0.1:5557"  # `palpd learner` publishes estimates here
    high_water_mark: Annotated[int, Field(ge=1, le=1_000_000)] = 1000  # per subscriber; beyond it PUB drops
    # CURVE: the daemon's secret key file (from `palpd keygen`) and directories of clients' public keys.
    # Required when an endpoint is not loopback or ipc.
    curve_secret_key: str = ""
    operator_keys: str = ""  # all commands
    observer_keys: str = ""  # events, read-only commands and estop


class DaemonSettings(_Section):
    state_dir: str = ""  # sessions live here; "" = $STATE_DIRECTORY (systemd) or ~/.local/state/palpd
    scene: str = ""  # the simulated bench's scene (file or shipped name; "" = paper); on hardware: where the tissue is
    realtime: bool = True  # simulated bench on the wall clock (false: virtual time, as fast as the CPU allows)
    stop_timeout_s: Positive = 10.0  # SIGTERM/scan.stop: wait this long for the palpation to finish, then abort
    log_level: Literal["debug", "info", "warning", "error"] = "info"  # `palpd serve --log-level` overrides it
    status_interval_s: Annotated[float, Field(ge=0.05, le=1.0)] = 0.5  # status heartbeat: late subscribers catch up
    http: str = "127.0.0.1:8080"  # the live web view, HOST:PORT (port 0: any free port); "" = off
    http_token: str = ""  # required for a non-loopback `http`: clients send it as ?token= or Authorization: Bearer
    foxglove: str = ""  # HOST:PORT of a Foxglove WebSocket server (needs the foxglove extra); "" = off
    # Finished sessions beyond this many MiB in all are pruned, oldest first (never an unfinished one)
    max_sessions_mb: Annotated[float, Field(gt=0, le=10_000_000)] = 2048.0
    keep_days: Annotated[float, Field(ge=0, le=36500)] = 0.0  # finished sessions older are pruned; 0 = no age limit


class Settings(_Section):
    robot: RobotSettings = RobotSettings()
    sensor: SensorSettings = SensorSettings()
    tissue: TissueSettings = TissueSettings()
    servo: ServoSettings = ServoSettings()
    control: ControlSettings = ControlSettings()
    palpation: PalpationSettings = PalpationSettings()
    stiffness: StiffnessSettings = StiffnessSettings()
    safety: SafetySettings = SafetySettings()
    scan: ScanSettings = ScanSettings()
    learner: LearnerSettings = LearnerSettings()
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

    @model_validator(mode="after")
    def _identifiable_model(self):
        if self.stiffness.model in RATE_MODELS and self.palpation.speed_profile == "constant":
            raise ValueError(
                f"stiffness.model = {self.stiffness.model!r} is not identifiable at one constant indentation speed "
                "(k and the damping b rise alike): set palpation.speed_profile = \"varying\", or a model without "
                "damping (\"select\", \"power\", \"linear\")"
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
    def origin(dotted: str) -> str:
        env_name = (overrides or {}).get(dotted, (None, None))[0]
        return f"environment {env_name}" if env_name else source

    out_of_bounds = bound_problem(data)
    if out_of_bounds:
        dotted, problem = out_of_bounds
        raise ConfigError(f"{origin(dotted)}: {problem}")
    try:
        settings = Settings.model_validate(data)
    except ValidationError as exc:
        loc = ".".join(str(p) for p in exc.errors()[0]["loc"])
        raise ConfigError(describe_validation_error(origin(loc), exc)) from None
    inconsistent = consistency_problem(settings)
    if inconsistent:
        dotted, problem = inconsistent
        raise ConfigError(f"{origin(dotted)}: {problem}")
    return settings


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
