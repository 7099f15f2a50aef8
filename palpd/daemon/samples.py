"""Raw 1 kHz samples into the recording: the supervisor drains the servo process's ring every loop turn.

The ring holds 16 s of ticks and the supervisor turns at least every 100 ms,
so nothing should be lost; if the reader ever falls a ring behind, the loss is
counted (status `samples_lost`) and logged, never hidden.
"""
from __future__ import annotations

import logging

log = logging.getLogger("palpd.recorder")


def raw_samples(ring_samples) -> list[dict]:
    """RawSample-shaped dicts of a ring slice (column-wise: one tolist per field, not per sample)."""
    columns = (ring_samples["t_s"].tolist(), ring_samples["tip_mm"].tolist(), ring_samples["force_n"].tolist(),
               ring_samples["normal_force_n"].tolist(), ring_samples["status"].tolist())
    return [{"t": t, "tip_mm": tip, "force_n": f, "normal_force_n": fn, "status": status}
            for t, tip, f, fn, status in zip(*columns)]


class SampleDrain:
    def __init__(self) -> None:
        self.next_index: int | None = None
        self.source = None  # whose ring next_index counts in
        self.lost = 0
        self.recorded = 0

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
            recording.record_samples(raw_samples(samples))
            self.recorded += len(samples)

    def stop(self) -> None:
        self.next_index = None
