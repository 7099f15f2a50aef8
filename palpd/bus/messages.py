"""Bus message models: every event payload carries v (schema version), seq and t.

These models are the contract of DESIGN.md's "Bus" section; `palpd schema`
prints their JSON Schemas. Add fields with defaults; bump SCHEMA_VERSION when a
field changes meaning or goes away.
"""
from __future__ import annotations

from typing import Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_VERSION = 1
TOPICS = ("status", "palpation", "stiffness", "estimate", "fault")
COMMANDS = ("status", "scan.start", "scan.stop", "estop", "reset", "estimate.get", "probe.at", "bias")


class Event(BaseModel):
    model_config = ConfigDict(extra="forbid")
    v: int = SCHEMA_VERSION
    seq: int = Field(ge=0)
    t: float  # seconds; robot (virtual or wall) time of the event


class Status(Event):
    state: Literal["configure", "ready", "scanning", "fault", "stopped"]
    palpations: int = 0
    message: str = ""


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
    radius_mm: float
    center_sd_mm: float
    radius_sd_mm: float
    boundary_mm: list[tuple[float, float]]


class Estimate(Event):
    points: int
    lumps: list[LumpMsg]
    next_probe_mm: Optional[tuple[float, float]] = None
    done: bool = False
    ambiguous_area_mm2: Optional[float] = None


class FaultMsg(Event):
    code: str
    message: str
    last_samples: list[dict[str, Any]] = []


EVENT_MODELS: dict[str, type[Event]] = {
    "status": Status, "palpation": Palpation, "stiffness": Stiffness, "estimate": Estimate, "fault": FaultMsg,
}


class Request(BaseModel):
    model_config = ConfigDict(extra="forbid")
    id: str | int
    cmd: str
    args: dict[str, Any] = {}


class ErrorBody(BaseModel):
    code: str
    message: str
