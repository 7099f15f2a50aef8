"""Raw 1 kHz samples into the recording: the supervisor drains the servo process's ring every loop turn.

The ring holds 16 s of ticks and the supervisor turns at least every 100 ms,
so nothing should be lost; if the reader ever falls a ring behind, the loss is
counted (status `samples_lost`) and logged, never hidden.
"""
from __future__ import annotations

import logging
import math
import time
from collections import deque

log = logging.getLogger("palpd.recorder")


def raw_samples(ring_samples) -> list[dict]:
    """RawSample-shaped dicts of a ring slice (column-wise: one tolist per field, not per sample)."""
    columns = (ring_samples["t_s"].tolist(), ring_samples["tip_mm"].tolist(), ring_samples["force_n"].tolist(),
               ring_samples["normal_force_n"].tolist(), ring_samples["status"].tolist())
    return [{"t": t, "tip_mm": tip, "force_n": f, "normal_force_n": fn, "status": status}
            for t, tip, f, fn, status in zip(*columns)]


REST_SAMPLES = 200  # the arm is at rest when its newest this many ticks (0.2 s at 1 kHz)...
REST_MM = 0.05  # ...stay within this of each other
NOTHING_TICKS_S = 0.5  # no tick for this long in virtual time (it stands still between tasks): nothing moves either
SETTLE_LIMIT_S = 10.0  # the recording waits at most this long for the arm to come to rest


class SampleDrain:
    def __init__(self) -> None:
        self.next_index: int | None = None
        self.source = None  # whose ring next_index counts in
        self.lost = 0
        self.recorded = 0
        self.dropped = 0  # not recorded on purpose: the disk was full (storage.DroppedRecording)
        self.recent: deque = deque(maxlen=REST_SAMPLES)  # (t_s, tip_mm) of the newest samples drained
        self.drained_at = time.monotonic()  # when a sample last came

    def start(self, servo) -> None:
        """Record from the newest tick on (what came before belongs to no recording)."""
        _, self.next_index, _ = servo.read_samples(None)
        self.source = servo

    def drain(self, servo, recording) -> None:
        if self.next_index is None or recording is None:
            return
        if servo is not self.source:  # a new servo process (reset after a lost one): its ring counts from 0
            log.info("recording the new servo process's samples from its newest tick")
            self.start(servo)
        samples, self.next_index, lost = servo.read_samples(self.next_index)
        if lost:
            self.lost += lost
            log.warning("%d raw samples lost (the servo ring was overwritten before it was read)", lost)
        if len(samples):
            rows = raw_samples(samples)
            recording.record_samples(rows)
            self.recorded += len(samples)
            self.recent.extend((row["t"], row["tip_mm"]) for row in rows[-REST_SAMPLES:])
            self.drained_at = time.monotonic()

    def stop(self) -> None:
        self.next_index = None

    def at_rest(self, since_s: float, virtual_time: bool = True) -> tuple[float, float, float] | None:
        """Where the tip came to rest (the newest sample's position) once it has, else None. Also, in virtual
        time, once no tick came for NOTHING_TICKS_S (its clock stands still between tasks, and nothing moves),
        and in any case SETTLE_LIMIT_S after since_s (monotonic): the recording must end. On the wall clock the
        ticks never stop while the servo process lives; a gap is that process kept off a busy host's cores, and
        the arm moves on after it: the recording was closed in such a gap with the arm still falling."""
        now = time.monotonic()
        newest = self.recent[-1][1] if self.recent else None
        quiet = virtual_time and now - self.drained_at > NOTHING_TICKS_S and now - since_s > NOTHING_TICKS_S
        if quiet or now - since_s > SETTLE_LIMIT_S:
            return tuple(newest) if newest is not None else (math.nan, math.nan, math.nan)
        if len(self.recent) < REST_SAMPLES:
            return None
        tips = [tip for _, tip in self.recent]
        spread = max(max(tip[i] for tip in tips) - min(tip[i] for tip in tips) for i in range(3))
        return tuple(newest) if spread <= REST_MM else None
