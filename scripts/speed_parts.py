"""Where a virtual-time scan's wall time goes, in parts that can be timed apart (docs/mechanics.md, "Virtual-time speed").

    python scripts/speed_parts.py ticks [SCENE]        # servo CPU per tick: 9 palpations on a 3 x 3 grid, in-process
    python scripts/speed_parts.py capture [SCENE] FILE # a whole scan in-process; every learner fit's inputs to FILE
    python scripts/speed_parts.py replay FILE [REPS]   # those fits again: best CPU of REPS, and a digest of the results
    python scripts/speed_parts.py overlap [SCENE]      # a scan through the servo process, the lift overlapped and not

The overlap figures are the parent's, wall and CPU seconds: `begin` is the wait for each palpation's record
(`run` when not overlapped), `judge` and `observe` the stiffness fit and the learner's update, `settle` the wait
for the lift's end; the judge's wall over its CPU is the time the parent was off a core while the lift ran.
The tick figure leaves out the learner and the stiffness fits (the servo loop's share only); the replay's digest
is over every fit's θ, covariance, noise, evidence and work, so two versions of the learner that give the same
digest gave the same fits to the last bit. CPU time (process_time), not wall: this machine is shared.
"""
from __future__ import annotations

import hashlib
import pickle
import sys
import time

from palpd.threads import pin_blas_to_one_thread

pin_blas_to_one_thread()

DEFAULT_SCENE = "config/scenes/paper-3d.toml"


def _settings():
    from palpd.embedded import scan_settings

    return scan_settings(None, None, None, None, None, None, None, None, None, None, None)


def ticks(scene_name: str) -> None:
    import palpd.scan as scan
    from palpd.bench import open_simulated_bench
    from palpd.control.tasks import HoldAndCollect, MoveTo
    from palpd.shipped import load_scene_named

    settings = _settings()
    bench = open_simulated_bench(settings, load_scene_named(scene_name), seed=0)
    servo, p = bench.servo, settings.palpation
    spent = [0.0]
    run = servo.run

    def timed(task, timeout_s=120.0):
        started = time.process_time()
        try:
            run(task, timeout_s)
        finally:
            spent[0] += time.process_time() - started

    servo.run = timed
    scan.judge = lambda record, settings: None  # the servo's share only: no stiffness fits
    servo.start()
    first = (0.0, 0.0, p.clearance_mm)
    servo.run(MoveTo(first, p.travel_speed_mm_s, p.accel_mm_s2))
    tare = HoldAndCollect(p.tare_samples, where=first)
    servo.run(tare)
    servo.forces.tare(tare.samples)
    for x in (-15.0, 0.0, 15.0):
        for y in (-15.0, 0.0, 15.0):
            scan._press(bench, settings, p, (x, y))
    n = servo.timing.ticks
    print(f"{n} ticks, robot {bench.clock.now():.2f} s, servo CPU {spent[0]:.3f} s, {spent[0] / n * 1e6:.1f} us/tick")


def capture(scene_name: str, path: str) -> None:
    import palpd.learner.evidence as evidence
    from palpd.embedded import run_simulated_scan
    from palpd.shipped import load_scene_named

    calls, fit = [], evidence.fit

    def recorded(*args, **kwargs):
        calls.append(pickle.dumps((args, kwargs)))
        return fit(*args, **kwargs)

    evidence.fit = recorded  # hypotheses.py calls it as evidence.fit
    report, _ = run_simulated_scan(_settings(), load_scene_named(scene_name), in_process=True)
    with open(path, "wb") as out:
        pickle.dump(calls, out)
    print(f"{len(calls)} fits over {report['palpations']} palpations written to {path}")


def replay(path: str, reps: int = 3) -> None:
    import numpy as np

    import palpd.learner.evidence as evidence

    with open(path, "rb") as source:
        calls = [pickle.loads(c) for c in pickle.load(source)]
    best, fits = float("inf"), []
    for _ in range(reps):
        started = time.process_time()
        fits = [evidence.fit(*args, **kwargs) for args, kwargs in calls]
        best = min(best, time.process_time() - started)
    digest = hashlib.sha256()
    for fit in fits:
        if fit is None:
            digest.update(b"none")
            continue
        for value in (fit.theta, fit.cov, np.array([fit.noise_sd, fit.log_evidence, fit.log_posterior, fit.work]),
                      *fit.alternatives):
            digest.update(np.ascontiguousarray(value).tobytes())
    print(f"{len(calls)} fits, best CPU {best:.3f} s of {reps}, digest {digest.hexdigest()[:16]}")


def overlap(scene_name: str) -> None:
    import os

    import palpd.scan as scan
    from palpd.control.remote import RemoteServo
    from palpd.embedded import run_simulated_scan
    from palpd.learner.planner import ActivePlanner
    from palpd.shipped import load_scene_named

    begin = RemoteServo.begin
    for overlapped in (False, True):
        spent: dict = {}
        originals = [(RemoteServo, "begin", "begin"), (RemoteServo, "settle", "settle"), (scan, "judge", "judge"),
                     (ActivePlanner, "observe", "observe")]
        RemoteServo.begin = begin if overlapped else (lambda self, task, timeout_s=120.0: self.run(task, timeout_s))
        saved = [(owner, name, getattr(owner, name)) for owner, name, _ in originals]
        for owner, name, key in originals:
            setattr(owner, name, _timed(getattr(owner, name), key, spent))
        try:
            report, _ = run_simulated_scan(_settings(), load_scene_named(scene_name))
        finally:
            for owner, name, original in saved:
                setattr(owner, name, original)
            RemoteServo.begin = begin
        parts = "  ".join(f"{k} {w:.2f}/{c:.2f}" for k, (w, c) in spent.items())
        print(f"{'overlapped' if overlapped else 'in turn':10}  wall {report['wall_time_s']:.2f} s "
              f"({report['robot_time_s'] / report['wall_time_s']:.2f}x)  {parts}  load {os.getloadavg()[0]:.2f}")


def _timed(function, key: str, spent: dict):
    def timed(*args, **kwargs):
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            w, c = spent.get(key, (0.0, 0.0))
            spent[key] = (w + time.perf_counter() - wall, c + time.process_time() - cpu)
    return timed


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in ("ticks", "capture", "replay", "overlap"):
        print(__doc__, file=sys.stderr)
        return 2
    if argv[0] == "ticks":
        ticks(argv[1] if len(argv) > 1 else DEFAULT_SCENE)
    elif argv[0] == "overlap":
        overlap(argv[1] if len(argv) > 1 else DEFAULT_SCENE)
    elif argv[0] == "capture":
        capture(*(argv[1:3] if len(argv) > 2 else (DEFAULT_SCENE, argv[1])))
    else:
        replay(argv[1], int(argv[2]) if len(argv) > 2 else 3)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
