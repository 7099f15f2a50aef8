"""What each command does to the supervisor, and which lifecycle states allow it."""
from __future__ import annotations

import ctypes
import ctypes.util
import logging

from palpd.daemon.jobs import ProbeJob, RestartServoJob, ScanJob, region_problem, resolved_scan, session_plan
from palpd.daemon.learning import make_estimator, scan_settings
from palpd.daemon import storage
from palpd.daemon.session import PROBES, UNFINISHED, Session
from palpd.files import is_storage_error

log = logging.getLogger("palpd.daemon")
ALLOWED_STATES = {
    "status": None, "estimate.get": None, "sessions": None,  # None: any state
    "scan.start": ("ready",), "scan.stop": ("scanning",), "probe.at": ("ready",), "bias": ("ready",),
    "estop": ("configure", "ready", "scanning", "fault"), "reset": ("fault",),
}


def dispatch(sup, command) -> None:
    allowed = ALLOWED_STATES[command.cmd]
    if allowed is not None and sup.state not in allowed:
        sup.commands.fail(command, "invalid_state", f"{command.cmd} is not possible while {sup.state}"
                                                    f" (only while {' or '.join(allowed)})")
        return
    handler = HANDLERS[command.cmd]
    log.debug("command %s from %s", command.cmd, command.role or "unknown")
    try:
        handler(sup, command)
    except Exception as exc:  # a bug in one handler must not take the daemon down
        if is_storage_error(exc):  # e.g. scan.start on a full disk: a storage fault, said in the reply too
            sup.storage_failed(command.cmd, exc)
            sup.commands.fail(command, "storage", sup.storage_cause)
            return
        log.exception("command %s failed", command.cmd)
        sup.commands.fail(command, "internal", f"{command.cmd} failed: {exc!r}")


def status(sup, command) -> None:
    sup.commands.reply(command, **sup.status_event())


def estimate_get(sup, command) -> None:
    estimate = sup.last_estimate.model_dump(mode="json") if sup.last_estimate is not None else None
    session = sup.session
    sup.commands.reply(command, estimate=estimate, probes=probe_records(session.entries if session else []),
                       tissue_size_mm=list(sup.bench.tissue_size_mm), session=session.name if session else "",
                       map=sup.last_map)


def probe_records(entries: list[dict]) -> list[dict]:
    """A session's journaled palpations as reply.estimate.get's probes (failed ones where they were aimed)."""
    return [{"index": e["index"], "target_xy_mm": e.get("target_xy_mm") or e["xy_mm"], "xy_mm": e["xy_mm"],
             "stiffness_n_per_mm": e["stiffness_n_per_mm"], "rejected": e.get("rejected")} for e in entries]


def scan_start(sup, command) -> None:
    args = command.args
    if args.resume and args.discard:
        sup.commands.fail(command, "bad_args", "scan.start args: resume and discard exclude each other")
        return
    if args.resume:
        _resume(sup, command)
        return
    scan = args.model_dump(mode="json", exclude={"resume", "discard"})
    problem = region_problem(scan, sup.bench.tissue_size_mm)
    if problem:
        sup.commands.fail(command, "bad_args", f"scan.start args: {problem}")
        return
    refusal = _unfinished_refusal(sup.session, args.discard)
    if refusal:
        sup.commands.fail(command, "unfinished_session", refusal)
        return
    discarded = _discard(sup.session)
    scan = resolved_scan(scan, sup.bench.tissue_size_mm, sup.settings)
    sup.session = Session.create(sup.sessions_dir, scan)
    sup.show_map(None)
    sup.estimator = None  # the last session's learner goes before the next is built: one in memory, not two
    sup.estimator = make_estimator(scan_settings(sup.settings, scan), scan, sup.bench.tissue_size_mm)
    _start(sup, command, discarded)


def _unfinished_refusal(session, discard: bool) -> str | None:
    """No work is thrown away unasked: a new scan over an unfinished session needs resume or discard."""
    if session is None or session.meta["status"] != UNFINISHED or discard:
        return None
    return (f"session {session.name} is unfinished ({len(session.entries)} palpations journaled): scan.start "
            "with resume to continue it, or discard to abandon it and start anew")


def _discard(session) -> str:
    """Abandon the unfinished session (its files stay); its name, or "" when there was none."""
    if session is None or session.meta["status"] != UNFINISHED:
        return ""
    session.finish("abandoned")
    log.info("session %s abandoned (discarded by a new scan.start)", session.name)
    return session.name


def _resume(sup, command) -> None:
    session = sup.session
    if session is None or session.meta["status"] != "unfinished":
        sup.commands.fail(command, "invalid_state", "there is no unfinished session to resume")
        return
    _start(sup, command)  # the estimator was rebuilt from the journal when the session was recovered


def _start(sup, command, discarded: str = "") -> None:
    scan = sup.session.meta["scan"]
    settings = scan_settings(sup.settings, scan)
    planner = session_plan(scan, sup.estimator, sup.session.entries, settings)
    sup.job = ScanJob(sup.session, settings, planner, sup.estimator)
    sup.job.stop_reason = None
    sup.close_recording()  # the probes' recording, if single palpations came first
    sup.open_recording(sup.session)  # names itself in the job, whose journal entries point at it
    sup.worker.submit(sup.job)
    log.info("session %s: %s %s scan %s, up to %d %s (%d readings done), recording %s", sup.session.name,
             scan["strategy"], scan["palpation"], "resumed" if command.args.resume else "started",
             planner.expected_total, "paths" if scan["palpation"] == "sliding" else "palpations",
             len(sup.session.entries), sup.job.recording)
    sup.set_state("scanning", f"scan {scan['strategy']}")
    sup.commands.reply(command, session=sup.session.name, expected_total=planner.expected_total,
                       already_done=len(sup.session.entries), discarded=discarded)


def scan_stop(sup, command) -> None:
    sup.job.stop_reason = "stopped"
    sup.worker.request_stop()
    sup.commands.reply(command, stopping=True)


def estop(sup, command) -> None:
    sup.bench.servo.request_estop()  # the servo process trips on its next tick; any later motion trips at once
    if sup.job is None:
        sup.set_state("fault", "estop")
        sup.publish("fault", sup.now(), code="estop", message="emergency stop requested")
    sup.commands.reply(command, estop=True)


def reset(sup, command) -> None:
    if sup.storage_cause and not sup.recover_storage():  # still no room: the fault stays, saying why
        sup.set_state("fault", f"storage: {sup.storage_cause}")
        sup.commands.fail(command, "storage", sup.storage_cause)
        return
    if sup.bench.servo.lost:  # the servo process is gone: start a new one (in the worker: it takes seconds)
        sup.job = RestartServoJob(sup.reopen_bench)
        sup.worker.submit(sup.job)
        sup.set_state("configure", "restarting the servo process")
        sup.commands.reply(command, state=sup.state, restarting=True)
        return
    sup.bench.servo.reset()  # clears the e-stop input and the latched fault in the servo process
    sup.job = lambda worker: worker.home()  # from wherever the stop left the arm, supervised; ready when parked
    sup.worker.submit(sup.job)
    sup.set_state("configure", "fault cleared: bringing the arm home")
    sup.commands.reply(command, state=sup.state)


def probe_at(sup, command) -> None:
    problem = region_problem({"center_mm": command.args.xy_mm, "size_mm": (0.0, 0.0)}, sup.bench.tissue_size_mm)
    if problem:
        sup.commands.fail(command, "bad_args", f"probe.at args: point {problem.split(' at ')[1]}")
        return
    if sup.probe_session is None:
        sup.probe_session = Session.create(sup.sessions_dir, {"kind": "probe.at"}, status=PROBES)
    sup.job = ProbeJob(sup.settings, command.args.xy_mm, sup.probe_session)
    sup.open_recording(sup.probe_session)  # a file per probe, closed when it ends: an idle daemon records nothing
    sup.worker.submit(sup.job)
    sup.set_state("scanning", "probe")
    sup.commands.reply(command, accepted=True)


def bias(sup, command) -> None:
    sup.job = lambda worker: worker.tare()
    sup.worker.submit(sup.job)
    sup.set_state("scanning", "bias")
    sup.commands.reply(command, accepted=True)


def sessions(sup, command) -> None:
    daemon = sup.settings.daemon
    listed = storage.list_sessions(sup.sessions_dir)
    sup.commands.reply(command, sessions=listed, total_mb=round(sum(s["size_mb"] for s in listed), 3),
                       max_sessions_mb=daemon.max_sessions_mb, keep_days=daemon.keep_days,
                       filesystem=storage.filesystem(sup.sessions_dir), samples_dropped=sup.samples.dropped)


HANDLERS = {"status": status, "estimate.get": estimate_get, "scan.start": scan_start, "scan.stop": scan_stop,
            "estop": estop, "reset": reset, "probe.at": probe_at, "bias": bias, "sessions": sessions}


def job_ended(sup, fault: dict | None) -> None:
    job, sup.job = sup.job, None
    if isinstance(job, RestartServoJob) and job.bench is not None:
        sup.bench = job.bench
    if isinstance(job, ScanJob) and job.finished:
        sup.session.finish("finished")
    elif isinstance(job, ScanJob) and job.stop_reason == "stopped":
        sup.session.close()  # stays unfinished: scan.start {"resume": true} goes on where scan.stop left it
    if isinstance(job, ScanJob):
        log.info("session %s %s after %d palpations", sup.session.name, sup.session.meta["status"],
                 len(sup.session.entries))
    if fault is not None:
        sup.publish("fault", sup.now(), code=fault["code"], message=fault["message"])
        sup.set_state("fault", fault["code"])
    elif sup.storage_cause:  # the scan was stopped for it: the arm is parked now
        sup.storage_fault()
    else:
        sup.set_state("ready", "scan finished" if getattr(job, "finished", False) else
                      "servo process restarted" if isinstance(job, RestartServoJob) else "")
    if isinstance(job, (ScanJob, ProbeJob)):
        sup.end_recording(fault)  # after the last status and fault, so the recording has them
    if isinstance(job, ScanJob) and not sup.storage_cause:
        sup.prune_sessions()
    if isinstance(job, ScanJob):
        return_freed_memory()


def return_freed_memory() -> None:
    """Give the heap a scan freed back to the OS (glibc's malloc_trim). A scan's numpy, zstd and learner buffers
    are freed when it ends, but glibc keeps the pages: the second scan left the daemon 8 MB (5 %) bigger than
    the first, and there it stayed (`palpd bench soak`). Elsewhere than glibc, nothing to do."""
    name = ctypes.util.find_library("c")
    trim = getattr(ctypes.CDLL(name), "malloc_trim", None) if name else None
    if trim is not None:
        trim(0)
