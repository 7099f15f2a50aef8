"""palpd bench stall: host stalls injected in simulated time, and what the tissue and the arm went through.

Each pattern stalls the host (the servo loop stops running, as when the kernel
deschedules it: simulated time jumps) for gap_ms every `every` ticks while the
servo palpates the stiff lump of the paper scene and a soft spot, then parks.
Per pattern it prints: completed or the fault (and its stop), the true peak
contact force (the simulator's, every physics step) next to the host's, how far
the true tip strayed outside the workspace box, and how far the arm moved (and
how hard it pressed the tissue) in the second after the stop, with the
amplifiers off.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass

# (gap_ms, every_ticks): isolated gaps about once a second, repeated ones, and one beyond max_tick_gap_s.
DEFAULT_PATTERNS = ((0, 0), (1, 1000), (5, 1000), (20, 1000), (50, 1000), (2, 10), (5, 50), (20, 200),
                    (10, 20), (150, 100000))
POINTS_MM = ((7.5, -4.0), (-20.0, 20.0))  # the paper lump's centre (0.8 N/mm), then plain tissue
AFTER_STOP_S = 1.0
FIRST_STALL_TICK = 1500  # a "once" pattern (every > run length) stalls here: the first press is under way


@dataclass(frozen=True)
class Pattern:
    gap_ms: float
    every: int  # ticks between stalls

    @property
    def name(self) -> str:
        if self.gap_ms == 0:
            return "no stall"
        if self.every >= 100000:
            return f"{self.gap_ms:g} ms once"
        return f"{self.gap_ms:g} ms every {self.every} ticks"


def add_parser(subparsers):
    stall = subparsers.add_parser("stall", help="host stalls in simulated time: faults, true force, arm after stop")
    stall.add_argument("--pattern", action="append", metavar="GAP_MS/EVERY",
                       help="a stall of GAP_MS every EVERY ticks (repeatable; default: a standard set)")
    stall.add_argument("--json", action="store_true", help="print JSON")
    stall.add_argument("--config", metavar="FILE", help="settings (TOML)")
    return stall


def run(args) -> int:
    from palpd.config import load_settings

    patterns = [parse_pattern(text) for text in args.pattern] if args.pattern else \
        [Pattern(g, e) for g, e in DEFAULT_PATTERNS]
    settings = load_settings(args.config)
    results = [run_pattern(settings, pattern) for pattern in patterns]
    if args.json:
        print(json.dumps({"cap_n": settings.safety.force_cap_n, "patterns": results}, indent=2))
        return 0
    print(f"{'pattern':24s} {'outcome':34s} {'true peak':>9s} {'host peak':>9s} {'outside':>7s} "
          f"{'moved after stop':>16s} {'pressing after':>14s}")
    for r in results:
        print(f"{r['pattern']:24s} {r['outcome'][:34]:34s} {r['true_peak_n']:7.2f} N {r['host_peak_n']:7.2f} N "
              f"{r['outside_workspace_mm']:4.1f} mm {r['moved_after_stop_mm']:13.1f} mm {r['pressing_after_stop_n']:12.2f} N")
    print(f"force cap {settings.safety.force_cap_n} N; simulated time, paper scene, palpations at "
          f"{', '.join(str(p) for p in POINTS_MM)} mm")
    return 0


def parse_pattern(text: str) -> Pattern:
    from palpd.errors import UsageError

    gap, _, every = text.partition("/")
    try:
        pattern = Pattern(float(gap), int(every or 100000))
    except ValueError:
        raise UsageError(f"--pattern {text!r}: expected GAP_MS/EVERY_TICKS, e.g. 5/100") from None
    if not (0 <= pattern.gap_ms <= 10000 and pattern.every >= 1):
        raise UsageError(f"--pattern {text!r}: the gap must be 0-10000 ms and EVERY at least 1 tick")
    return pattern


def run_pattern(settings, pattern: Pattern, points_mm=None) -> dict:
    """One run of the pattern on a fresh simulated bench; the figures the table prints."""
    from palpd.bench import open_simulated_bench
    from palpd.scan import FixedPlan, run_scan

    bench = open_simulated_bench(settings, paper_scene())
    watch = _Watch(bench, pattern)
    report = run_scan(bench, settings, FixedPlan(list(points_mm or POINTS_MM)))
    fault = report["faults"][0] if report["faults"] else None
    moved_mm, pressing_n = watch.after_stop(AFTER_STOP_S)
    return {"pattern": pattern.name, "gap_ms": pattern.gap_ms, "every_ticks": pattern.every,
            "outcome": "completed" if fault is None else f"{fault['code']}, {_how_it_stopped(fault)}",
            "fault": fault and {k: fault[k] for k in ("code", "message", "stop_category", "stop")},
            "palpations": report["palpations"], "true_peak_n": round(watch.true_peak_n, 3),
            "host_peak_n": report["max_contact_force_n"], "outside_workspace_mm": round(watch.outside_mm, 2),
            "moved_after_stop_mm": round(moved_mm, 2), "pressing_after_stop_n": round(pressing_n, 3),
            "robot_time_s": report["robot_time_s"]}


def _how_it_stopped(fault: dict) -> str:
    if "parked" in fault["stop"]:
        return "backed out and parked"
    return "current cut" if "cut" in fault["stop"] else fault["stop"]


def paper_scene():
    """The seed paper's bench (config/scenes/paper.toml), built here so the benchmark runs from anywhere."""
    from drivers.sim.scene import Scene

    return Scene(name="paper", seed=1, tissue={"size_mm": (60.0, 60.0), "stiffness_n_per_mm": 0.12},
                 lump=[{"center_mm": (7.5, -4.0), "radius_mm": 10.0, "depth_mm": 3.0, "stiffness_n_per_mm": 0.8}],
                 sensor={"noise_n": 0.01, "tilt": True})


class _Watch:
    """Stalls the host on the pattern (from the servo's tick hook) and watches the truth at every physics step."""

    def __init__(self, bench, pattern: Pattern) -> None:
        from drivers.sim.faults import stall

        self.bench, self.world = bench, bench.world
        self.box = bench.servo.supervisor.box_mm
        self.true_peak_n, self.outside_mm, self._ticks = 0.0, 0.0, 0
        gap_s, every = pattern.gap_ms / 1000.0, pattern.every

        def on_tick(_tick) -> None:
            self._ticks += 1
            if gap_s and (self._ticks % every == 0 if every < 100000 else self._ticks == FIRST_STALL_TICK):
                stall(bench.clock, gap_s)

        bench.servo.tick_hook = on_tick
        self.world.step_hook = self._on_step

    def _on_step(self, world) -> None:
        self.true_peak_n = max(self.true_peak_n, world.contact_force_n)
        tip = world.tip_mm()
        out = max(max(low - v, v - high) for v, (low, high) in zip(tip, self.box))
        self.outside_mm = max(self.outside_mm, out)

    def after_stop(self, seconds: float) -> tuple[float, float]:
        """(how far the tip moved, the largest contact force) over `seconds` with the motors off."""
        world, clock = self.world, self.bench.clock
        world.step_hook = None
        start, pressing = world.tip_mm(), 0.0
        end_s = clock.now() + seconds
        while clock.now() < end_s - 1e-9:
            clock.sleep_until(min(clock.now() + 0.01, end_s))
            world.advance_to(clock.now())
            pressing = max(pressing, world.contact_force_n)
        return math.dist(start, world.tip_mm()), pressing
