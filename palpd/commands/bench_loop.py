"""palpd bench loop: the servo loop in real time against the simulator, next to a bare loop.

The bare loop only sleeps to the same absolute deadlines, so the difference
between the two is what the servo work costs the timing on this machine.
"""
from __future__ import annotations

import json
import sys
import time


def add_parser(subparsers):
    loop = subparsers.add_parser("loop", help="servo loop timing vs a bare sleep-to-deadline loop")
    loop.add_argument("--seconds", type=float, default=5.0, metavar="S", help="length of each loop (default 5)")
    loop.add_argument("--json", action="store_true", help="print the Bench JSON")
    loop.add_argument("--config", metavar="FILE", help="settings (TOML)")
    loop.add_argument("--scene", metavar="PATH|NAME",
                      help="the tissue palpated (default: the 2-D default tissue); a 3-D scene reads its force "
                           "table every physics step (a cold table is built first: minutes, then cached)")
    return loop


def run(args) -> int:
    from palpd.config import load_settings
    from palpd.control.realtime import prepare_realtime
    from palpd.errors import UsageError

    if not 0 < args.seconds <= 3600:
        raise UsageError("--seconds must be in (0, 3600]")
    settings = load_settings(args.config)
    for note in prepare_realtime():
        print(f"palpd: {note}", file=sys.stderr)
    scene = _scene(args.scene)
    bare = bare_loop(settings.servo.rate_hz, args.seconds)
    servo, faults = servo_loop(settings, args.seconds, scene)
    result = {"scene": scene.name, "loop": servo, "bare_loop": bare, "faults": faults}
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for name in ("loop", "bare_loop"):
            r = result[name]
            print(f"{name:9s}: {r['ticks']} ticks, lateness p50/p99/p99.9/max {r['lateness_us']['p50']}/"
                  f"{r['lateness_us']['p99']}/{r['lateness_us']['p999']}/{r['lateness_us']['max']} us, "
                  f"overruns {r['overruns']}, compute p50/p99 {r['compute_us']['p50']}/{r['compute_us']['p99']} us")
        r = result["loop"]
        print(f"  of the loop's compute, p50/p99: host {r['host_us']['p50']}/{r['host_us']['p99']} us, "
              f"simulator (bridge + DAQ + physics) {r['sim_us']['p50']}/{r['sim_us']['p99']} us")
    return 0


def _scene(spec: str | None):
    from drivers.sim.scene import Scene, load_scene
    from palpd.shipped import resolve_scene

    return Scene(name="bench") if spec is None else load_scene(resolve_scene(spec))


def bare_loop(rate_hz: float, seconds: float) -> dict:
    from drivers.clock import RealClock
    from palpd.control.timing import TimingStats

    clock, stats, period = RealClock(), TimingStats(rate_hz), 1.0 / rate_hz
    deadline = clock.now()
    end = deadline + seconds
    while deadline < end:
        started = time.perf_counter()
        compute = time.perf_counter() - started
        deadline += period
        now = clock.now()
        if now > deadline + period:
            missed = int((now - deadline) / period)
            stats.overruns += missed
            deadline += missed * period
        clock.sleep_until(deadline)
        stats.record(max(0.0, clock.now() - deadline), compute)
    return stats.summary()


def servo_loop(settings, seconds: float, scene=None) -> tuple[dict, list[dict]]:
    """Palpate one point over and over on the simulated bench (the scene's tissue centre), on the wall clock, in
    the servo process."""
    from palpd.control.remote import open_servo_bench
    from palpd.errors import ScanFault

    bench = open_servo_bench(settings, scene if scene is not None else _scene(None), realtime=True)
    servo, faults = bench.servo, []
    try:
        servo.start()
        servo.timing.reset()  # from here on: the process's start-up is not the loop's timing
        end = bench.clock.now() + seconds
        while bench.clock.now() < end:
            try:
                servo.run(_PalpateUntil(end, settings.palpation))
            except ScanFault:
                faults.append({k: v for k, v in servo.fault.as_dict().items() if k != "last_samples"})
                servo.reset()
                servo.start()
        summary = servo.timing.summary()  # before the park at the end, which is not the loop under test
        servo.stop()
        return summary, faults
    finally:
        servo.close()


class _PalpateUntil:
    """Palpations at the tissue centre, one after another, until the wall clock says stop; then up off the
    tissue to above it (a task that ended mid-press would leave the arm pressing, and between tasks the
    bridge's gravity hold lets the tissue throw the light arm off: 461 mm/s at the park's first tick, a
    speed fault)."""

    def __init__(self, end_s: float, palpation_settings) -> None:
        # imported here, not at the top: `palpd --help` and every other command build this module's parser,
        # and the control stack brings numpy (~0.1 s per command start)
        from palpd.control.palpation import Palpation
        from palpd.control.tasks import MoveTo

        self._palpation, self._move_to = Palpation, MoveTo
        self.end_s, self.settings = end_s, palpation_settings
        self._task = None
        self._target = None
        self._leaving = False
        self.done = False

    def step(self, tick):
        p = self.settings
        if tick.t_s >= self.end_s and not self._leaving:
            self._leaving = True
            target = self._target
            if target is None or target[2] >= p.clearance_mm:  # not down near the tissue: stop where it is
                self.done = True
                return target if target is not None else tick.tip_mm
            self._task = self._move_to((target[0], target[1], p.clearance_mm), p.approach_speed_mm_s, p.accel_mm_s2,
                                start=target)  # straight up, as a palpation's own retract
        if self._task is None or self._task.done:
            if self._leaving:
                self.done = True
                return self._target
            self._task = self._palpation((0.0, 0.0), p)
        self._target = self._task.step(tick)
        return self._target
