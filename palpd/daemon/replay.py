"""Replay a session: refit every recorded palpation and re-learn, then compare with the recorded estimate.

The palpation traces come from the journal (fsynced, complete even after a
crash) or, without one, from the MCAP recordings; the estimate to reproduce is
the last one recorded in the MCAP files.
"""
from __future__ import annotations

import math
from pathlib import Path

from palpd.daemon.learning import make_estimator
from palpd.daemon.mcap import read_messages
from palpd.daemon.session import JOURNAL, read_journal
from palpd.errors import PalpdError
from palpd.stiffness import FitRejected, fit_linear

TOLERANCE = 1e-6


def recorded(session_dir: Path) -> tuple[list[dict], dict | None]:
    """(palpations in order, last recorded estimate) of a session directory."""
    recordings = sorted(session_dir.glob("recording-*.mcap"), key=lambda p: int(p.stem.split("-")[1]))
    if not recordings and not (session_dir / JOURNAL).exists():
        raise PalpdError(f"{session_dir}: not a session directory (no journal, no recording)")
    palpations, estimate = {}, None
    for path in recordings:
        try:
            messages = read_messages(path)
        except (OSError, ValueError) as exc:
            raise PalpdError(f"{path}: cannot read: {exc}") from None
        for topic, payload in messages:
            if topic == "palpation":
                palpations[payload["index"]] = payload
            elif topic == "estimate":
                estimate = payload
    journal = read_journal(session_dir / JOURNAL)
    traces = journal if len(journal) >= len(palpations) else [palpations[i] for i in sorted(palpations)]
    return traces, estimate


def replay(session_dir: Path, settings) -> dict:
    traces, recorded_estimate = recorded(session_dir)
    estimator = make_estimator(settings)
    worst_k = 0.0
    for trace in traces:
        try:
            k = fit_linear(trace["depth_mm"], trace["force_n"]).stiffness_n_per_mm
        except FitRejected:
            k = None
        if trace.get("stiffness_n_per_mm") is not None and k is not None:
            worst_k = max(worst_k, abs(k - trace["stiffness_n_per_mm"]))
        estimator.observe(trace["xy_mm"], k)
    estimate = estimator.estimate()
    return {"palpations": len(traces), "max_stiffness_difference_n_per_mm": worst_k, "estimate": estimate,
            "recorded": recorded_estimate, "reproduced": same_lumps(estimate, recorded_estimate)}


def same_lumps(ours: dict, theirs: dict | None) -> bool:
    if theirs is None or ours["points"] != theirs["points"] or len(ours["lumps"]) != len(theirs["lumps"]):
        return False
    for a, b in zip(ours["lumps"], theirs["lumps"]):
        if math.dist(a["center_mm"], b["center_mm"]) > TOLERANCE or abs(a["radius_mm"] - b["radius_mm"]) > TOLERANCE:
            return False
    return True
