"""Bus message models: every event payload carries v (schema version), seq and t.

These models are the contract of DESIGN.md's "Bus" section; `palpd schema`
prints their JSON Schemas. Add fields with defaults; bump SCHEMA_VERSION when a
field changes meaning or goes away.
"""
from __future__ import annotations

from typing import Annotated, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_VERSION = 1
TOPICS = ("status", "palpation", "stiffness", "estimate", "fault")
COMMANDS = ("status", "scan.start", "scan.stop", "estop", "reset", "estimate.get", "probe.at", "bias")


class Event(BaseModel):
    model_config = ConfigDict(extra="forbid")
    v: int = SCHEMA_VERSION
    seq: int = Field(ge=0)
    t: float  # seconds; robot (virtual or wall) time of the event


State = Literal["configure", "ready", "scanning", "fault", "stopped"]


class Status(Event):
    state: State
    palpations: int = 0
    message: str = ""
    session: str = ""  # the session directory's name
    expected_total: int = 0  # palpations the scan plans (0 when no scan)
    resumable: bool = False  # an unfinished session waits for scan.start {"resume": true}
    samples_lost: int = 0  # raw samples the recorder missed (the servo ring lapped it); should stay 0


class Palpation(Event):
    index: int
    xy_mm: tuple[float, float]
    depth_mm: list[float]
    force_n: list[float]


class Stiffness(Event):
    index: int
    xy_mm: tuple[float, float]
    stiffness_n_per_mm: float
    stiffness_sd_n_per_mm: float = 0.0  # fit uncertainty, the learner's observation noise
    model: str = "linear"


class LumpMsg(BaseModel):
    model_config = ConfigDict(extra="forbid")
    center_mm: tuple[float, float]
    radius_mm: float  # an ellipse's equal-area radius
    center_sd_mm: float
    radius_sd_mm: float
    boundary_mm: list[tuple[float, float]]
    axes_mm: Optional[tuple[float, float]] = None  # ellipse: (major, minor) semi-axes
    axes_sd_mm: Optional[tuple[float, float]] = None
    angle_deg: Optional[float] = None  # ellipse: major axis from +x
    angle_sd_deg: Optional[float] = None
    edge_mm: Optional[float] = None  # where modelled: 75 % to 25 % of the lump's height
    edge_sd_mm: Optional[float] = None


class ModelChoice(BaseModel):
    """The lump hypothesis the evidence chose: `none`, `circles:K`, `ellipse:K` or `free-form`."""
    model_config = ConfigDict(extra="forbid")
    chosen: str
    weight: float  # its posterior weight among the hypotheses compared
    runner_up: Optional[str] = None


class Estimate(Event):
    points: int
    lumps: list[LumpMsg]
    next_probe_mm: Optional[tuple[float, float]] = None
    done: bool = False
    ambiguous_area_mm2: Optional[float] = None
    model: Optional[ModelChoice] = None  # None before the first reading


class FaultMsg(Event):
    code: str
    message: str
    last_samples: list[dict[str, Any]] = []


EVENT_MODELS: dict[str, type[Event]] = {
    "status": Status, "palpation": Palpation, "stiffness": Stiffness, "estimate": Estimate, "fault": FaultMsg,
}


class RawSample(BaseModel):
    """One servo tick as recorded: MCAP channel `samples` only, never on the bus (1 kHz stays off the network)."""

    model_config = ConfigDict(extra="forbid")
    t: float  # robot time of the tick, s
    tip_mm: tuple[float, float, float]
    force_n: tuple[float, float, float]  # tissue frame, bias-compensated
    normal_force_n: float
    status: int = 0  # the robot's status bits


SAMPLES_CHANNEL = "samples"


class _Args(BaseModel):
    """Command arguments, validated from JSON in strict mode: "5" is not a number, 5 is."""

    model_config = ConfigDict(extra="forbid", strict=True)


class NoArgs(_Args):
    pass


FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class ScanStartArgs(_Args):
    strategy: Literal["raster", "random", "active"] = "raster"
    # None: 81 for raster/random; for active, learner.max_palpations (its own rule usually stops it sooner)
    max_palpations: Optional[Annotated[int, Field(ge=1, le=10000)]] = None
    seed: Annotated[int, Field(ge=0)] = 0
    # The region to palpate (tissue frame); default: the whole palpable rectangle.
    center_mm: tuple[FiniteFloat, FiniteFloat] = (0.0, 0.0)
    size_mm: Optional[tuple[PositiveFloat, PositiveFloat]] = None
    depth_mm: Optional[Annotated[float, Field(gt=0, le=30)]] = None
    speed_mm_s: Optional[Annotated[float, Field(gt=0, le=100)]] = None
    resume: bool = False  # continue the unfinished session instead of starting a new one


class ProbeAtArgs(_Args):
    xy_mm: tuple[FiniteFloat, FiniteFloat]


COMMAND_ARGS: dict[str, type[BaseModel]] = {
    "status": NoArgs, "scan.start": ScanStartArgs, "scan.stop": NoArgs, "estop": NoArgs, "reset": NoArgs,
    "estimate.get": NoArgs, "probe.at": ProbeAtArgs, "bias": NoArgs,
}
READ_ONLY_COMMANDS = ("status", "estimate.get")  # what observers may send


class Request(BaseModel):
    model_config = ConfigDict(extra="forbid")
    id: str | int
    cmd: str
    args: dict[str, Any] = {}


class ErrorBody(BaseModel):
    code: Literal["bad_json", "bad_request", "unknown_command", "bad_args", "invalid_state", "forbidden",
                  "unavailable", "internal"]
    message: str


class ErrorReply(BaseModel):
    id: str | int | None
    ok: Literal[False] = False
    error: ErrorBody


def json_schemas() -> dict[str, dict]:
    """JSON Schema of every event topic and command (`palpd schema`, MCAP channels)."""
    schemas = {topic: model.model_json_schema() for topic, model in EVENT_MODELS.items()}
    schemas["request"] = Request.model_json_schema()
    schemas["error"] = ErrorReply.model_json_schema()
    for name, model in COMMAND_ARGS.items():
        schemas[f"{name}.args"] = model.model_json_schema()
    return schemas


def recording_schemas() -> dict[str, dict]:
    """The JSON Schema of every MCAP channel: the event topics and the raw samples."""
    schemas = {topic: model.model_json_schema() for topic, model in EVENT_MODELS.items()}
    return schemas | {SAMPLES_CHANNEL: RawSample.model_json_schema()}
