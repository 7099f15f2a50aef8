"""The servo ring read by the parent while another process writes it as fast as it can."""
import multiprocessing
import time
from types import SimpleNamespace

import numpy as np
import pytest

from palpd.control.ring import SampleRing
from palpd.daemon.samples import SampleDrain

# The producer: one sample per "tick", t_s = index / 1000, with nothing between writes (a servo loop is
# far slower, so the reader sees far more index changes here than in a scan, and may be lapped even when
# it never pauses).
# Run by exec in a spawned process, as the servo process is started (it shares our resource tracker).
PRODUCER = """
import types
from palpd.control.ring import SampleRing
ring = SampleRing.attach(name)
for i in range(total):
    ring.write(types.SimpleNamespace(t_s=i / 1000, q=(0, 0, 0), tip_mm=(0, 0, 0), force_tissue_n=(0, 0, 0),
                                     normal_force_n=0.0, status=0), 0)
ring.close()
"""


class RingServo:
    """What SampleDrain asks of a servo, straight from a ring."""

    def __init__(self, ring: SampleRing) -> None:
        self.ring = ring

    def read_samples(self, since):
        return ([], self.ring.written(), 0) if since is None else self.ring.read_new(since)


class Indices:
    """A recording that keeps only which sample indices it was given."""

    def __init__(self) -> None:
        self.indices: list[int] = []

    def record_samples(self, batch) -> None:
        self.indices.extend(round(sample["t"] * 1000) for sample in batch)


@pytest.mark.parametrize("capacity, pause_every", [(1 << 14, 0), (256, 50)], ids=["keeping-up", "lapped"])
def test_a_drain_records_each_sample_once_in_order_and_counts_what_it_lost(capacity, pause_every):
    """A reader once saw the write index as 0 while it changed (struct wrote it byte by byte), read a whole
    ring again from index 0 and recorded it twice. Lapped: the reader pauses, the producer overwrites."""
    total = 200_000
    ring = SampleRing.create(capacity)
    producer = multiprocessing.get_context("spawn").Process(
        target=exec, args=(PRODUCER, {"name": ring.name, "total": total}), daemon=True)
    drain, recording, servo, turns = SampleDrain(), Indices(), RingServo(ring), 0
    drain.start(servo)  # from index 0: nothing is written yet
    producer.start()
    try:
        while producer.is_alive() or drain.next_index < ring.written():
            drain.drain(servo, recording)
            turns += 1
            if pause_every and turns % pause_every == 0:
                time.sleep(0.002)
        assert producer.exitcode == 0
    finally:
        producer.kill()
        producer.join()
        ring.close()
    indices = np.array(recording.indices)
    bad = np.flatnonzero(np.diff(indices) <= 0)
    assert len(indices) > 0 and not len(bad), [indices[max(b - 2, 0):b + 3].tolist() for b in bad[:5]]
    assert indices[-1] == total - 1 and len(indices) + drain.lost == total
    assert drain.lost > 0 or not pause_every  # lapped: it lost samples, and said how many


def _write(ring: SampleRing, count: int) -> None:
    start = ring.written()
    for i in range(start, start + count):
        ring.write(SimpleNamespace(t_s=i / 1000, q=(0, 0, 0), tip_mm=(0, 0, 0), force_tissue_n=(0, 0, 0),
                                   normal_force_n=0.0, status=0), 0)


def test_a_drain_follows_a_new_servo_process_from_its_newest_tick():
    """After a reset restarts a lost servo process, its ring counts from 0 again: the drain neither waits for
    it to pass the old index nor counts the old process's index as samples lost."""
    old, new = SampleRing.create(1024), SampleRing.create(1024)
    try:
        drain, recording, old_servo, new_servo = SampleDrain(), Indices(), RingServo(old), RingServo(new)
        _write(old, 500)
        drain.start(old_servo)
        _write(old, 300)
        drain.drain(old_servo, recording)
        _write(new, 40)
        drain.drain(new_servo, recording)  # the first turn after the restart: from the newest tick on
        _write(new, 60)
        drain.drain(new_servo, recording)
    finally:
        old.close()
        new.close()
    assert recording.indices == list(range(500, 800)) + list(range(40, 100)) and drain.lost == 0
