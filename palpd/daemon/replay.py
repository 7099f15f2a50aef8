"""Replay a session: re-segment, refit every recorded palpation and re-learn, then compare estimates.

The palpations come from the journal (fsynced, complete even after a crash)
or, without one, from the MCAP recordings; each is cut again out of the raw
1 kHz samples when the recording has all its ticks (segmentation, then the
scan's own fit, then the same learner), else its journaled trace is refitted.
The estimate to reproduce is the last one recorded in the MCAP files.
"""
from __future__ import annotations

import bisect
import json
import math
from pathlib import Path
from types import SimpleNamespace

from palpd.bus.messages import SAMPLES_CHANNEL
from palpd.control.onset import refine
from palpd.control.palpation import palpation_segmenter
from palpd.daemon.jobs import OLDER_SESSIONS, resolved_scan
from palpd.daemon.learning import make_estimator, scan_settings
from palpd.daemon.mcap import read_messages
from palpd.daemon.session import JOURNAL, META, read_journal
from palpd.errors import PalpdError
from palpd.learner.observations import CENSORED
from palpd.stiffness import FitRejected
from palpd.stiffness.palpation import fit_palpation

TOLERANCE = 1e-6


def recorded(session_dir: Path, settings) -> tuple[list[dict], dict | None]:
    """(palpations in order, last recorded estimate) of a session directory; each palpation re-segmented
    from the raw samples when the recording has them."""
    recordings = sorted(session_dir.glob("recording-*.mcap"), key=lambda p: int(p.stem.split("-")[1]))
    if not recordings and not (session_dir / JOURNAL).exists():
        raise PalpdError(f"{session_dir}: not a session directory (no journal, no recording)")
    palpations, estimate, samples = {}, None, {}
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
            elif topic == SAMPLES_CHANNEL:
                samples.setdefault(path.name, []).append((payload["t"], payload["tip_mm"], payload["normal_force_n"]))
    journal = read_journal(session_dir / JOURNAL)
    traces = journal if len(journal) >= len(palpations) else [palpations[i] for i in sorted(palpations)]
    return [resegmented(trace, samples.get(trace.get("recording"), []), settings) for trace in traces], estimate


def resegmented(trace: dict, samples: list, settings) -> dict:
    """The palpation cut again out of the raw samples by a fresh segmenter, as its task cut it live; the
    journaled trace as it is when the recording has no samples for it (older sessions, a crash's lost second)."""
    t0, t1 = trace.get("t_first_tick_s"), trace.get("t_end_s")
    if t0 is None or not t1 or not samples:
        return trace
    times = [t for t, _, _ in samples]
    start, stop = bisect.bisect_left(times, t0), bisect.bisect_right(times, t1)
    if start == len(times) or times[start] != t0 or times[stop - 1] != t1:
        return trace  # not every tick of it was recorded
    p = settings.palpation
    segmenter = palpation_segmenter(trace.get("contact_on_n", p.contact_on_n), trace.get("contact_off_n", p.contact_off_n),
                                    trace.get("contact_filter_s", 0.0))
    t_approach, t_armed = trace.get("t_start_s") or t0, trace.get("t_armed_s") or t0
    best, forgotten = None, False
    for t, tip, force in samples[start:stop]:
        if t > t_approach and not forgotten:  # live, the task acts after its segmenter has taken that tick
            segmenter.forget()
            forgotten = True
        if t > t_armed and not segmenter.armed:
            segmenter.armed = True
            segmenter.forget()
        segment = segmenter.push(t, tip, force)
        if segment is not None and (best is None or segment.peak_force_n > best.peak_force_n):
            best = segment
    if best is None:
        return trace | {"depth_mm": [], "force_n": [], "unload_depth_mm": [], "unload_force_n": [], "segmented": True}
    best.force_lead_s = trace.get("force_lead_s", 0.0)
    refine(best)
    return trace | {"xy_mm": list(best.xy_mm), "depth_mm": best.depth_mm, "force_n": best.force_n,
                    "unload_depth_mm": best.unload_depth_mm, "unload_force_n": best.unload_force_n,
                    "segmented": True}


def replay(session_dir: Path, settings) -> dict:
    scan = session_scan(session_dir, settings)
    settings = scan_settings(settings, scan)
    traces, recorded_estimate = recorded(session_dir, settings)
    estimator = make_estimator(settings, scan, scan["size_mm"])
    worst_k = 0.0
    for trace in traces:
        k, sd = reading(trace, settings)
        if trace.get("stiffness_n_per_mm") is not None and k is not None:
            worst_k = max(worst_k, abs(k - trace["stiffness_n_per_mm"]))
        outcome = "fit" if k is not None else trace.get("outcome")  # a censored reading stays a bound
        estimator.observe(trace["xy_mm"], k, sd, trace.get("target_xy_mm"), outcome, trace.get("stiffness_bound_n_per_mm"))
    estimate = estimator.estimate()
    return {"palpations": len(traces), "segmented": sum(bool(t.get("segmented")) for t in traces), "max_stiffness_difference_n_per_mm": worst_k, "estimate": estimate,
            "recorded": recorded_estimate, "reproduced": same_lumps(estimate, recorded_estimate)}


def session_scan(session_dir: Path, settings) -> dict:
    """The scan's args as the daemon kept them (its region above all); the defaults without session.json."""
    try:
        scan = json.loads((session_dir / META).read_text())["scan"]
    except (OSError, ValueError, KeyError):
        scan = {}
    defaults = {"strategy": "raster", "max_palpations": None, "seed": 0, "center_mm": (0.0, 0.0), "size_mm": None,
                "depth_mm": None, "speed_mm_s": None} | OLDER_SESSIONS
    return resolved_scan(defaults | scan, settings.tissue.size_mm, settings)


def reading(trace: dict, settings) -> tuple[float | None, float]:
    """(k, sd) as the scan read it: a sliding cycle as journaled, a press fitted again, and a bound left a
    bound (judged from the whole press, e.g. one that bounced off: palpd.probe.judge; no slope in its trace)."""
    if trace.get("palpation") == "sliding":
        return journaled(trace)
    if trace.get("outcome") in CENSORED:
        return None, 0.0
    return refit(trace, settings)


def journaled(trace: dict) -> tuple[float | None, float]:
    """A sliding reading as the scan read it: one modulation cycle of a path, not a palpation to cut again."""
    return trace["stiffness_n_per_mm"], trace.get("stiffness_sd_n_per_mm") or 0.0


def refit(trace: dict, settings) -> tuple[float | None, float]:
    """The palpation's stiffness and its standard error, fitted as the scan fitted it."""
    record = SimpleNamespace(depth_mm=trace["depth_mm"], force_n=trace["force_n"],
                             stop_reason=trace.get("stop_reason", "force"),
                             unload_depth_mm=trace.get("unload_depth_mm", []),
                             unload_force_n=trace.get("unload_force_n", []))
    try:
        fit = fit_palpation(record, settings.stiffness, settings.servo.rate_hz,
                            settings.palpation.speed_profile == "varying")
    except FitRejected:
        return None, 0.0
    return fit.stiffness_n_per_mm, fit.stiffness_se_n_per_mm


def same_lumps(ours: dict, theirs: dict | None) -> bool:
    if theirs is None or ours["points"] != theirs["points"] or len(ours["lumps"]) != len(theirs["lumps"]):
        return False
    for a, b in zip(ours["lumps"], theirs["lumps"]):
        if math.dist(a["center_mm"], b["center_mm"]) > TOLERANCE or abs(a["radius_mm"] - b["radius_mm"]) > TOLERANCE:
            return False
    return True
