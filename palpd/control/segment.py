"""Finding palpations in a continuous force/position stream.

The seed paper palpated by hand; in manual mode nothing is commanded and this
segmenter finds each palpation (contact onset, loading, unloading) in the
stream. Autonomous palpations go through the same segmenter, so both paths fit
the same data the same way.

Robust against the three things a hand-held session has: noise (hysteresis
between contact_on_n and contact_off_n on the force low-passed over filter_s,
and a palpation must press at least min_peak_n and min_depth_mm), drift (the
zero is tracked while out of contact and frozen during one) and double taps (a
release below contact_off_n ends a palpation, so the second tap is a palpation
of its own). Samples whose force is NaN or infinite are dropped and counted.

Each segment also keeps its raw samples (time, tip, pressed force), with up to
lookback_s of the approach before the threshold fired, so its contact point can
be found again from the whole trace (palpd.control.onset), outside the loop.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

Vec3 = tuple[float, float, float]
SETTLE_TIME_S = 0.05  # how fast the zero follows the force while the segmenter is disarmed
ZERO_SAMPLES = 50  # on arming, the zero is the mean of this many of the latest samples


@dataclass
class Segment:
    """One palpation: where it began, its loading and unloading traces, relative to the contact point."""

    t_onset_s: float
    contact_z_mm: float
    baseline_n: float
    xy_mm: tuple[float, float] = (0.0, 0.0)
    depth_mm: list[float] = field(default_factory=list)  # loading: onset to peak force
    force_n: list[float] = field(default_factory=list)
    unload_depth_mm: list[float] = field(default_factory=list)  # unloading: peak to release
    unload_force_n: list[float] = field(default_factory=list)
    peak_force_n: float = 0.0
    t_end_s: float = 0.0
    # raw (t_s, x_mm, y_mm, z_mm, pressed_n) from lookback_s before the threshold fired to the release
    samples: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    detected_at: int = 0  # index in samples where the threshold fired
    force_lead_s: float = 0.0  # how much newer each force sample is than the tip reading beside it
    onset_spread_mm: float = 0.0  # how far apart the contact points the trace fits as well lie (onset.refine)


class Segmenter:
    def __init__(self, contact_on_n: float, contact_off_n: float, min_peak_n: float = 0.15,
                 min_depth_mm: float = 0.5, baseline_time_s: float = 0.5, filter_s: float = 0.0,
                 lookback_s: float = 1.0, baseline_n: float | None = None) -> None:
        self.on_n, self.off_n = contact_on_n, contact_off_n
        self.min_peak_n, self.min_depth_mm = min_peak_n, min_depth_mm
        self.baseline_time_s, self.filter_s, self.lookback_s = baseline_time_s, filter_s, lookback_s
        self.baseline_n = baseline_n  # None: the first sample (an untared stream); a tared one starts at 0
        self._armed = True
        self.current: Segment | None = None
        self.rejected = 0  # contacts too slight to be palpations (brushes, noise)
        self.dropped = 0  # samples whose force was NaN or infinite
        self._last_t: float | None = None
        self._filtered: float | None = None
        self._lead = [0.0, 0]  # sum of force-sample leads, count
        self._xy_sum = [0.0, 0.0]
        self._trace: list[tuple[float, float]] = []  # (depth, force) since onset
        self._before: deque = deque()  # raw samples of the approach, for the onset refit
        self._raw: list = []

    @property
    def armed(self) -> bool:
        """False: the zero is tracked, but no contact is detected (a palpation's travel above the point)."""
        return self._armed

    @armed.setter
    def armed(self, value: bool) -> None:
        if value and not self._armed:
            recent = [f for *_, f in list(self._before)[-ZERO_SAMPLES:]]
            if recent:  # the zero as the force read just now, not as it was followed through travel and re-tares
                self.baseline_n = sum(recent) / len(recent)
        self._armed = value

    def forget(self) -> None:
        """Drop the samples kept so far (a palpation's travel, and its inertial forces, before the approach)."""
        self._before.clear()

    @property
    def filtered_n(self) -> float | None:
        """The low-passed force contact is judged on, less the tracked zero."""
        return None if self._filtered is None or self.baseline_n is None else self._filtered - self.baseline_n

    @property
    def approach_samples(self) -> list:
        """The raw (t, x, y, z, force less the zero) samples of the last lookback_s since the segmenter was armed
        (before this tick's: in contact, those of any brief contact that ended too)."""
        base = self.baseline_n or 0.0
        return [(t, x, y, z, f - base) for t, x, y, z, f in self._before]

    @property
    def in_contact(self) -> bool:
        return self.current is not None

    def push(self, t_s: float, tip_mm: Vec3, force_n: float, force_t_s: float | None = None) -> Segment | None:
        """Feed one sample; returns a palpation when one has just ended. force_t_s: when the force was
        sampled, if not at t_s (the tip reading may be a period older than the force)."""
        if not math.isfinite(force_n):
            self.dropped += 1
            return None
        dt = 0.0 if self._last_t is None else t_s - self._last_t
        self._last_t = t_s
        self._filter(force_n, dt)
        if force_t_s is not None:
            self._lead[0] += force_t_s - t_s
            self._lead[1] += 1
        if self.current is None:
            self._track_baseline(force_n, dt)
            if self.armed and self._filtered - self.baseline_n >= self.on_n:
                self._begin(t_s, tip_mm)
            else:
                self._remember(t_s, tip_mm, force_n)
                return None
        self._remember(t_s, tip_mm, force_n)  # a contact that ends early stays in the approach of the next
        return self._continue(t_s, tip_mm, force_n)

    def _filter(self, force_n: float, dt: float) -> None:
        if self.filter_s <= 0:
            self._filtered = force_n
        elif self._filtered is None:
            self._filtered = force_n if self.baseline_n is None else self.baseline_n
        else:
            self._filtered += (force_n - self._filtered) * (1.0 - math.exp(-dt / self.filter_s))

    def _remember(self, t_s: float, tip_mm: Vec3, force_n: float) -> None:
        before = self._before
        before.append((t_s, tip_mm[0], tip_mm[1], tip_mm[2], force_n))
        while before[0][0] < t_s - self.lookback_s:
            before.popleft()

    def _track_baseline(self, force_n: float, dt: float) -> None:
        if self.baseline_n is None or not math.isfinite(self.baseline_n):
            self.baseline_n = force_n
            return
        # Disarmed (travelling to the point), the zero follows faster: it starts from one noisy sample and
        # may be drifting; armed, it follows slowly (baseline_time_s; inf: held), so a slow press is not taken for drift.
        time_s = self.baseline_time_s if self._armed else min(self.baseline_time_s, SETTLE_TIME_S)
        self.baseline_n += (force_n - self.baseline_n) * (1.0 - math.exp(-dt / time_s))

    def _begin(self, t_s: float, tip_mm: Vec3) -> None:
        self.current = Segment(t_s, tip_mm[2], self.baseline_n)
        self._xy_sum = [0.0, 0.0]
        self._trace = []
        self._raw = self.approach_samples
        self.current.detected_at = len(self._raw)

    def _continue(self, t_s: float, tip_mm: Vec3, force_n: float) -> Segment | None:
        seg = self.current
        pressed = force_n - seg.baseline_n
        if self._filtered - seg.baseline_n < self.off_n:
            return self._end(t_s)
        self._trace.append((seg.contact_z_mm - tip_mm[2], pressed))
        self._raw.append((t_s, tip_mm[0], tip_mm[1], tip_mm[2], pressed))
        self._xy_sum[0] += tip_mm[0]
        self._xy_sum[1] += tip_mm[1]
        return None

    def _end(self, t_s: float) -> Segment | None:
        seg, trace, self.current = self.current, self._trace, None
        if not trace:
            return None
        peak = max(range(len(trace)), key=lambda i: trace[i][1])
        seg.peak_force_n = trace[peak][1]
        if seg.peak_force_n < self.min_peak_n or max(d for d, _ in trace) < self.min_depth_mm:
            self.rejected += 1
            return None
        seg.depth_mm, seg.force_n = [d for d, _ in trace[:peak + 1]], [f for _, f in trace[:peak + 1]]
        seg.unload_depth_mm, seg.unload_force_n = [d for d, _ in trace[peak + 1:]], [f for _, f in trace[peak + 1:]]
        seg.xy_mm = (self._xy_sum[0] / len(trace), self._xy_sum[1] / len(trace))
        seg.t_end_s = t_s
        seg.samples, self._raw = self._raw, []
        seg.force_lead_s = self.force_lead_s
        return seg

    @property
    def force_lead_s(self) -> float:
        return self._lead[0] / self._lead[1] if self._lead[1] else 0.0


class ManualSession:
    """A servo task that commands no motion (gravity compensation and damping only) while a person
    palpates, and collects the palpations the segmenter finds; done after duration_s."""

    follows_hand = True  # the safety monitors that judge a robot's palpation stand aside (control.safety)

    def __init__(self, segmenter: Segmenter, duration_s: float) -> None:
        self.segmenter, self.duration_s = segmenter, duration_s
        self.segments: list[Segment] = []
        self._t0: float | None = None
        self.done = False

    def step(self, tick) -> Vec3:
        if self._t0 is None:
            self._t0 = tick.t_s
        found = self.segmenter.push(tick.t_s, tick.tip_mm, tick.normal_force_n)
        if found is not None:
            self.segments.append(found)
        self.done = tick.t_s - self._t0 >= self.duration_s
        return tick.tip_mm  # the setpoint follows the hand: no spring pulls it anywhere
