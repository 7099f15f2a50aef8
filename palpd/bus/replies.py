"""The successful reply of every command: `{"id", "ok": true, ...}` with the fields below.

`palpd schema reply.CMD` prints each one's JSON Schema; the command server
validates every reply against its model before sending it, so the published
schemas cannot drift from what the daemon says.
"""
from __future__ import annotations

from typing import Literal, Optional

from pydantic import BaseModel

from palpd.bus.messages import SENT, Estimate, State, Status


class Reply(BaseModel):
    """Fields every successful reply carries."""

    model_config = SENT
    id: str | int | None
    """The request's id."""
    ok: Literal[True] = True


class StatusReply(Status, Reply):
    """The current status, exactly as a `status` event carries it (seq: the latest status event's), plus id and ok."""


class ScanStartReply(Reply):
    """The scan started (or resumed)."""

    session: str
    """The session directory's name."""
    expected_total: int
    """Palpations the scan plans."""
    already_done: int
    """Palpations journaled before this start (resume), else 0."""
    discarded: str = ""
    """The unfinished session this start abandoned (discard), else empty."""


class AcceptedReply(Reply):
    """The job was accepted; its progress and end arrive as events (status, palpation, fault)."""

    accepted: Literal[True] = True


class ScanStopReply(Reply):
    """The palpation under way finishes, then the scan stops (status goes back to ready)."""

    stopping: Literal[True] = True


class EstopReply(Reply):
    """The servo process trips on its next tick; the fault is latched until reset."""

    estop: Literal[True] = True


class ResetReply(Reply):
    """The latched fault is cleared (or, after servo_lost, a new servo process is starting)."""

    state: State
    """The state after the reset (configure while a new servo process starts)."""
    restarting: bool = False
    """A new servo process is being started (servo_lost)."""


class ProbeRecord(BaseModel):
    """One palpation of the current session, in order; failed ones are reported where they were aimed."""

    model_config = SENT
    index: int
    """0-based index in the session."""
    target_xy_mm: tuple[float, float]
    """Where the probe was aimed, tissue frame."""
    xy_mm: tuple[float, float]
    """Where it touched."""
    stiffness_n_per_mm: Optional[float]
    """The fitted stiffness; null when the fit was rejected."""
    rejected: Optional[str] = None
    """Why the fit was rejected (e.g. "no contact found")."""


class PosteriorMap(BaseModel):
    """The learner's posterior on a grid (rows: ys_mm, columns: xs_mm), tissue frame."""

    model_config = SENT
    xs_mm: list[float]
    """Column coordinates."""
    ys_mm: list[float]
    """Row coordinates."""
    p_lump: list[list[float]]
    """P(lump) per cell."""
    stiffness_n_per_mm: list[list[float]]
    """Posterior mean stiffness per cell."""
    stiffness_sd_n_per_mm: list[list[float]]
    """Posterior standard deviation per cell."""
    confidence: float
    """learner.confidence c: P between 1 - c and c is the uncertainty band."""


class EstimateGetReply(Reply):
    """The latest estimate, the session's palpations and the posterior map."""

    estimate: Optional[Estimate]
    """The latest `estimate` event (null before the first)."""
    probes: list[ProbeRecord]
    """Every palpation of the current scan session, in order."""
    tissue_size_mm: tuple[float, float]
    """The palpable rectangle, centred on the tissue origin."""
    session: str = ""
    """The session the estimate belongs to."""
    map: Optional[PosteriorMap] = None
    """The learner's posterior (null before the first stiffness point)."""


class SessionRecord(BaseModel):
    """One session directory under the state directory."""

    model_config = SENT
    name: str
    """The directory's name (its start time)."""
    status: str
    """unfinished, finished, abandoned, probes (single palpations), or unreadable."""
    size_mb: float
    """Its files together, MiB."""
    created: float
    """Unix time."""


class FilesystemUsage(BaseModel):
    """The filesystem the sessions live on."""

    model_config = SENT
    total_mb: float
    """Its size, MiB."""
    free_mb: float
    """Free, MiB."""
    used_percent: float
    """Used, % of its size."""


class SessionsReply(Reply):
    """The sessions on disk, oldest first, with their sizes and the storage limits (`palpctl sessions`)."""

    sessions: list[SessionRecord]
    """Every session, oldest first."""
    total_mb: float
    """All sessions together, MiB."""
    max_sessions_mb: float
    """daemon.max_sessions_mb: finished sessions beyond it are pruned, oldest first."""
    keep_days: float
    """daemon.keep_days: finished sessions older than this are pruned (0: no age limit)."""
    filesystem: FilesystemUsage
    """How full the sessions' filesystem is."""
    samples_dropped: int = 0
    """Raw samples not recorded because the disk was full (as in status)."""


REPLY_MODELS: dict[str, type[Reply]] = {
    "status": StatusReply, "scan.start": ScanStartReply, "scan.stop": ScanStopReply, "estop": EstopReply,
    "reset": ResetReply, "estimate.get": EstimateGetReply, "probe.at": AcceptedReply, "bias": AcceptedReply,
    "sessions": SessionsReply,
}
