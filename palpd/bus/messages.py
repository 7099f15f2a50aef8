"""Bus message models: every event payload carries v (schema version), seq and t.

These models are the contract of DESIGN.md's "Bus" section and docs/protocol.md;
`palpd schema` prints their JSON Schemas (field docstrings become descriptions).
Add fields with defaults; bump SCHEMA_VERSION when a field changes meaning or goes away.
"""
from __future__ import annotations

from typing import Annotated, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_VERSION = 1
# Positions and stiffnesses a listener acts on: a NaN position (JSON allows the literal) left the learner
# process unable to update again; refused in the message, the listener says so in one line and goes on.
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
TOPICS = ("status", "palpation", "stiffness", "estimate", "fault")
COMMANDS = ("status", "scan.start", "scan.stop", "estop", "reset", "estimate.get", "probe.at", "bias")
# What palpd sends: unknown fields refused, field docstrings as schema descriptions, and every field
# required in the published schema (a sent message always has them all, defaults included).
SENT = ConfigDict(extra="forbid", use_attribute_docstrings=True, json_schema_serialization_defaults_required=True)


class Event(BaseModel):
    """Fields every event carries."""

    model_config = SENT
    v: int = SCHEMA_VERSION
    """Schema version of the payload."""
    seq: int = Field(ge=0)
    """Per-topic sequence number, from 0 at daemon start; a gap means events were dropped."""
    t: float
    """Robot time of the event in seconds (virtual in simulated time, else the wall clock)."""


State = Literal["configure", "ready", "scanning", "fault", "stopped"]
Outcome = Literal["fit", "no_contact", "too_stiff", "too_soft", "rejected"]  # DESIGN.md probes[].outcome


class Status(Event):
    """The daemon's lifecycle state and progress. Published on every transition and as a heartbeat
    (`daemon.status_interval_s`), so a subscriber joining at any time has it within a second."""

    state: State
    """Lifecycle: configure -> ready -> scanning -> (ready | fault) ... -> stopped."""
    palpations: int = 0
    """Palpations journaled in the current session."""
    message: str = ""
    """Why the daemon is in this state (e.g. "scan active", a fault code)."""
    session: str = ""
    """The current session directory's name ("" before the first scan)."""
    expected_total: int = 0
    """Palpations the running scan plans (0 when no scan runs)."""
    resumable: bool = False
    """An unfinished session waits for scan.start {"resume": true}."""
    samples_lost: int = 0
    """Raw samples the recorder missed (the servo ring lapped it); should stay 0."""
    samples_dropped: int = 0
    """Raw samples not recorded on purpose since the daemon started: the disk was full, and the journal of
    palpations comes first."""


class Palpation(Event):
    """One palpation's loading trace, journaled (fsynced) before it is published."""

    index: int
    """0-based index of the palpation in its session."""
    xy_mm: tuple[FiniteFloat, FiniteFloat]
    """Where the probe touched, tissue frame."""
    depth_mm: list[float]
    """Indentation below the contact point of each loading sample."""
    force_n: list[float]
    """Normal force of each loading sample."""
    target_xy_mm: Optional[tuple[FiniteFloat, FiniteFloat]] = None
    """Where the probe was aimed (a failed palpation is reported there)."""
    rejected: Optional[str] = None
    """Why no stiffness was fitted (null: a `stiffness` event follows)."""
    outcome: Optional[Outcome] = None
    """What the palpation gave: `fit` (a `stiffness` event follows), `no_contact`, `too_stiff`, `too_soft` or
    `rejected` (null from a daemon older than the field)."""
    stiffness_bound_n_per_mm: Optional[PositiveFloat] = None
    """A censored reading's bound: `too_stiff`, k is at least this; `too_soft`, at most (null otherwise)."""
    presses: Optional[int] = None
    """2 when the force limit came early and the spot was pressed again gently (palpation.too_stiff =
    "repalpate"; the trace is the gentle press's), else 1 (null from a daemon older than the field)."""


class Stiffness(Event):
    """The stiffness fitted to one palpation (absent when the fit was rejected)."""

    index: int
    """The palpation's index."""
    xy_mm: tuple[FiniteFloat, FiniteFloat]
    """Where the probe touched, tissue frame."""
    stiffness_n_per_mm: PositiveFloat
    """Fitted stiffness at the reference depth."""
    stiffness_sd_n_per_mm: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 0.0
    """Fit uncertainty (standard error), the learner's observation noise."""
    model: str = "linear"
    """The force-displacement model the fit chose."""


class LumpMsg(BaseModel):
    """One estimated lump with its uncertainty: what the hypothesis the evidence chose says of it."""

    model_config = SENT
    center_mm: tuple[float, float]
    """Centre, tissue frame."""
    radius_mm: float
    """Radius (an ellipse's: its equal-area radius, √(major·minor)); a lump's radius is where its felt
    stiffness is halfway between tissue and lump."""
    center_sd_mm: float
    """Standard deviation of the centre."""
    radius_sd_mm: float
    """Standard deviation of the radius."""
    boundary_mm: list[tuple[float, float]]
    """The lump's 50 % boundary, a closed polygon [[x, y], ...]."""
    axes_mm: Optional[tuple[float, float]] = None
    """Ellipse only: (major, minor) semi-axes."""
    axes_sd_mm: Optional[tuple[float, float]] = None
    """Ellipse only: their standard deviations."""
    angle_deg: Optional[float] = None
    """Ellipse only: the major axis's angle from +x, in [0, 180)."""
    angle_sd_deg: Optional[float] = None
    """Ellipse only: its standard deviation."""
    edge_mm: Optional[float] = None
    """Where modelled: the edge width, 75 % to 25 % of the lump's height along a radius."""
    edge_sd_mm: Optional[float] = None
    """Where modelled: its standard deviation."""
    depth_mm: Optional[float] = None
    """Where modelled: the depth of its top below the surface, from its contrast, size and edge (a surrogate of
    the finite-element tissue: docs/learner.md, "Depth")."""
    depth_sd_mm: Optional[float] = None
    """Where modelled: its standard deviation."""
    boundary_sd_mm: Optional[float] = None
    """Free-form regions and lumps cut by the tissue's edge: the sd of the boundary's position across itself,
    RMS along it (on the tissue)."""
    cut_by_edge: Optional[bool] = None
    """True for a lump with most of its boundary off the tissue (a stiff region running past its edge): its
    centre and radius are then the centroid and equal-area radius of its part on the tissue, and an ellipse's
    axes and angle are the whole shape's, as fitted, and held to no tolerance (mostly off the tissue, no
    reading pins them)."""


class SoftRegionMsg(BaseModel):
    """Tissue softer than around it (a cyst, fat): no lump, but part of what the chosen model draws."""

    model_config = SENT
    center_mm: tuple[float, float]
    """Centre, tissue frame."""
    radius_mm: float
    """Where the tissue is halfway (in log stiffness) between around it and the region's softest."""
    softer: float
    """How many times softer its core is than the tissue around it."""
    boundary_mm: list[tuple[float, float]]
    """That halfway boundary, a closed polygon [[x, y], ...]."""


class ModelChoice(BaseModel):
    """The lump hypothesis the evidence chose."""

    model_config = SENT
    chosen: str
    """`none`, `circles:K`, `ellipse:K` or `free-form`; `none+soft:1` is no lump on tissue with a soft region."""
    weight: float
    """Its posterior weight among the hypotheses compared."""
    runner_up: Optional[str] = None
    """The next most likely hypothesis (null when there was no other)."""
    drawn_by: Optional[str] = None
    """The hypothesis whose lumps `lumps` holds: `chosen`, or `free-form` when the chosen one misses the
    readings (`undecided` says so) and the free-form map foresees them better (leave-one-out)."""
    count_weight: Optional[float] = None
    """The posterior mass of the chosen hypothesis's lump count: every hypothesis that claims as many lumps
    (the verdict stands on it, whichever outline those hypotheses draw)."""
    expected_boundary_error_mm: Optional[float] = None
    """The reported boundary's expected error: the expected misclassified area ∫ min(P, 1 − P) dA with P(lump)
    averaged over the hypotheses, plus `unfelt_area_mm2`, divided by the boundary's length (null without a
    lump): what `tolerance_mm` speaks of."""
    unfelt_area_mm2: Optional[float] = None
    """The expected area of lumps no reading has felt yet (their prior, `learner.expected_lumps`, wherever a
    lump's disc holds no reading): part of the expected boundary error, what a tighter tolerance reads on for."""
    unfelt_radius_mm: Optional[float] = None
    """The farthest any spot of the tissue lies from a reading: a lump of smaller radius could sit between the
    readings unfelt, so the count means "no other lump this large or larger"."""
    undecided: Optional[str] = None
    """Why the choice does not stand yet (null once it does): too few readings, a weight under the confidence
    asked for, no hypothesis that explains the readings to their precision, or a choice one reading old. A scan
    that ends with it set is `undetermined`."""
    boundary_doubt: Optional[str] = None
    """Why the boundary is not known to the tolerance asked (null once it is, or with no lump): its expected
    error over `tolerance_mm`, or a lump whose centre, edge or top no reading has read. A scan whose count is
    decided ends `lumps` with it set when the budget runs out first."""
    soft_regions: Optional[list[SoftRegionMsg]] = None
    """Only when the chosen model has one (`none+soft:1`): the soft region it draws."""


class Estimate(Event):
    """The online learner's estimate, after each palpation and at the end of a scan."""

    points: int
    """Stiffness points the estimate is made of."""
    lumps: list[LumpMsg]
    """The lumps found (empty: none)."""
    next_probe_mm: Optional[tuple[float, float]] = None
    """Where the learner would palpate next (null once it is sure enough, and in a scan whose strategy is not
    the learner's: a raster's or random scan's next point is its plan's, not the learner's)."""
    done: bool = False
    """The scan that made this estimate has ended."""
    ambiguous_area_mm2: Optional[float] = None
    """Area whose P(lump) lies between 1 - c and c (c: learner.confidence)."""
    model: Optional[ModelChoice] = None
    """The hypothesis the evidence chose, its weight and the runner-up (null before the first reading)."""


class FaultMsg(Event):
    """A latched safety fault: the robot stopped and needs `reset`."""

    code: str
    """What tripped (e.g. force_cap, estop, servo_lost)."""
    message: str
    """One line saying what happened."""
    last_samples: list[dict[str, Any]] = []
    """The servo samples before the fault, when the servo process sent them."""


EVENT_MODELS: dict[str, type[Event]] = {
    "status": Status, "palpation": Palpation, "stiffness": Stiffness, "estimate": Estimate, "fault": FaultMsg,
}


class RawSample(BaseModel):
    """One servo tick as recorded: MCAP channel `samples` only, never on the bus (1 kHz stays off the network)."""

    model_config = SENT
    t: float
    """Robot time of the tick, s."""
    tip_mm: tuple[float, float, float]
    """Probe tip, tissue frame."""
    force_n: tuple[float, float, float]
    """Force on the tissue, tissue frame, bias-compensated."""
    normal_force_n: float
    """Force along the tissue normal."""
    status: int = 0
    """The robot's status bits."""


SAMPLES_CHANNEL = "samples"


class _Args(BaseModel):
    """Command arguments, validated from JSON in strict mode: "5" is not a number, 5 is."""

    model_config = ConfigDict(extra="forbid", strict=True, use_attribute_docstrings=True)


class NoArgs(_Args):
    """The command takes no arguments."""


class ScanStartArgs(_Args):
    """Start a scan (a new session), or resume the unfinished one."""

    strategy: Literal["raster", "random", "active"] = "active"
    """Where to palpate: where the online learner is least sure (the default), a raster, or uniform random points."""
    max_palpations: Optional[Annotated[int, Field(ge=1, le=10000)]] = None
    """Budget; null: 81 for raster/random, learner.max_palpations for active (its own rule usually stops it sooner)."""
    seed: Annotated[int, Field(ge=0)] = 0
    """Seed of random points and of the learner's first design."""
    center_mm: tuple[FiniteFloat, FiniteFloat] = (0.0, 0.0)
    """Centre of the region to palpate, tissue frame."""
    size_mm: Optional[tuple[PositiveFloat, PositiveFloat]] = None
    """Size of the region; null: the whole palpable rectangle."""
    depth_mm: Optional[Annotated[float, Field(gt=0, le=30)]] = None
    """Indentation depth; null: palpation.depth_mm."""
    speed_mm_s: Optional[Annotated[float, Field(gt=0, le=100)]] = None
    """Indentation speed; null: palpation.speed_mm_s."""
    palpation: Optional[Literal["discrete", "sliding"]] = None
    """Press point by point, or slide along paths in contact (max_palpations then counts paths); null: palpation.mode."""
    resume: bool = False
    """Continue the unfinished session instead of starting a new one (other arguments are ignored)."""
    discard: bool = False
    """Abandon the unfinished session and start a new one; without resume or discard, a scan.start over an
    unfinished session (stopped, faulted or cut by a crash) is refused with `unfinished_session`."""


class ProbeAtArgs(_Args):
    """One palpation at a point, journaled in the daemon's probes session."""

    xy_mm: tuple[FiniteFloat, FiniteFloat]
    """The point, tissue frame."""


COMMAND_ARGS: dict[str, type[BaseModel]] = {
    "status": NoArgs, "scan.start": ScanStartArgs, "scan.stop": NoArgs, "estop": NoArgs, "reset": NoArgs,
    "estimate.get": NoArgs, "probe.at": ProbeAtArgs, "bias": NoArgs, "sessions": NoArgs,
}
# What observers may send: reading, and stopping the arm (an emergency stop is open to every authenticated
# client, as a hardware e-stop button is to everyone in the room); restarting it (reset) needs an operator.
OBSERVER_COMMANDS = ("status", "estimate.get", "sessions", "estop")


class Request(BaseModel):
    """A command request (DEALER -> ROUTER, one JSON frame)."""

    model_config = SENT
    id: str | int
    """Chosen by the client; the reply carries it back."""
    cmd: str
    """The command's name."""
    args: dict[str, Any] = {}
    """The command's arguments (schema: CMD.args)."""


class ErrorBody(BaseModel):
    """What went wrong."""

    model_config = SENT
    code: Literal["bad_json", "bad_request", "unknown_command", "bad_args", "invalid_state", "unfinished_session",
                  "forbidden", "unavailable", "internal"]
    """Machine-readable reason."""
    message: str
    """One line for a person."""


class ErrorReply(BaseModel):
    """The reply to any request that failed."""

    model_config = SENT
    id: str | int | None
    """The request's id (null when the request was unreadable)."""
    ok: Literal[False] = False
    error: ErrorBody


def recording_schemas() -> dict[str, dict]:
    """The JSON Schema of every MCAP channel: the event topics and the raw samples (as `palpd schema` prints them)."""
    from palpd.bus.schemas import published_schema

    schemas = {topic: published_schema(topic, model) for topic, model in EVENT_MODELS.items()}
    return schemas | {SAMPLES_CHANNEL: published_schema(SAMPLES_CHANNEL, RawSample)}
