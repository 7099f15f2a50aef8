"""Shared memory between the servo process and its parent: a header and a ring of samples.

Single producer (the servo loop writes one sample per tick), single consumer
(the parent reads what is new). The producer writes the slot, then bumps the
write index, so a reader never sees a slot before it is complete; a reader that
falls more than a ring behind loses the oldest samples and is told how many.
The header also carries the loop's heartbeat, its clock and tick counters, and
the parent's e-stop input, which the loop reads every tick, and its wind-down request (end the task under
way gently: a slide lifts off at once), which a task that can wind down reads every tick.

Every header field is one aligned 8-byte word, written and read through numpy (a single
store or load), never through `struct`: struct writes a field byte by byte, and a reader in
the other process then saw the write index as 0 about once in 150 reads while it changed,
went back to reading from index 0 and recorded a ring of samples twice.
"""
from __future__ import annotations

import struct
from multiprocessing import shared_memory

import numpy as np

CAPACITY = 1 << 14  # samples: 16 s at 1 kHz
# write_index, heartbeat, ticks, overruns, now_s (the producer's), estop, wind_down (the parent's)
_WORDS = ("written", "heartbeat", "ticks", "overruns", "now_s", "estop", "wind_down")
_INDEX, _BEAT, _TICKS, _OVERRUNS, _NOW, _ESTOP, _WIND_DOWN = range(len(_WORDS))
_SAMPLE = struct.Struct("<d3d3d3ddII")
SAMPLE_DTYPE = np.dtype([("t_s", "<f8"), ("q_rad", "<f8", 3), ("tip_mm", "<f8", 3), ("force_n", "<f8", 3),
                         ("normal_force_n", "<f8"), ("status", "<u4"), ("flags", "<u4")])
assert SAMPLE_DTYPE.itemsize == _SAMPLE.size
HEADER_BYTES = 64
FLAG_MOTORS_ON, FLAG_FAULT, FLAG_TASK = 1, 2, 4


class SampleRing:
    def __init__(self, memory: shared_memory.SharedMemory, owner: bool) -> None:
        self.memory, self.owner = memory, owner
        self._buffer = memory.buf
        self.capacity = (memory.size - HEADER_BYTES) // _SAMPLE.size
        self._slots = np.ndarray((self.capacity,), SAMPLE_DTYPE, self._buffer, HEADER_BYTES)
        self._words = np.ndarray((len(_WORDS),), "<u8", self._buffer, 0)  # the header, one aligned word each
        self._now = np.ndarray((1,), "<f8", self._buffer, 8 * _NOW)
        self._index = 0
        self._beats = 0

    @classmethod
    def create(cls, capacity: int = CAPACITY) -> "SampleRing":
        memory = shared_memory.SharedMemory(create=True, size=HEADER_BYTES + capacity * _SAMPLE.size)
        memory.buf[:HEADER_BYTES] = bytes(HEADER_BYTES)
        return cls(memory, owner=True)

    @classmethod
    def attach(cls, name: str) -> "SampleRing":
        return cls(shared_memory.SharedMemory(name=name), owner=False)

    @property
    def name(self) -> str:
        return self.memory.name

    # Producer (the servo process) ----------------------------------------------------------------

    def write(self, tick, flags: int) -> None:
        """One tick's sample; no allocation beyond the packing itself."""
        i = self._index
        q, tip, f = tick.q, tick.tip_mm, tick.force_tissue_n
        _SAMPLE.pack_into(self._buffer, HEADER_BYTES + (i % self.capacity) * _SAMPLE.size, tick.t_s,
                          q[0], q[1], q[2], tip[0], tip[1], tip[2], f[0], f[1], f[2],
                          tick.normal_force_n, tick.status, flags)
        self._index = i + 1
        self._words[_INDEX] = i + 1  # after the slot: a reader never sees a slot before it is complete

    def beat(self, now_s: float | None, ticks: int, overruns: int) -> None:
        """A heartbeat; now_s None keeps the time the last tick wrote."""
        self._beats += 1
        words = self._words
        words[_BEAT], words[_TICKS], words[_OVERRUNS] = self._beats, ticks, overruns
        if now_s is not None:
            self._now[0] = now_s

    def is_set(self) -> bool:
        """The e-stop input (the loop polls it like a threading.Event)."""
        return self._words[_ESTOP] != 0

    def wind_down_wanted(self) -> bool:
        return self._words[_WIND_DOWN] != 0

    # Consumer (the parent) -------------------------------------------------------------------------

    def set_estop(self, on: bool = True) -> None:
        self._words[_ESTOP] = 1 if on else 0

    def set_wind_down(self, on: bool = True) -> None:
        self._words[_WIND_DOWN] = 1 if on else 0

    def written(self) -> int:
        """How many samples the producer has written (the index of the next)."""
        return int(self._words[_INDEX])

    def header(self) -> dict:
        written, beat, ticks, overruns, _, estop, wind_down = self._words.tolist()
        return {"written": written, "heartbeat": beat, "ticks": ticks, "overruns": overruns,
                "estop": bool(estop), "wind_down": bool(wind_down), "now_s": float(self._now[0])}

    def last_flags(self) -> int:
        """The flags of the newest sample (FLAG_FAULT: the loop has latched a fault); 0 before the first."""
        end = self.written()
        return 0 if end == 0 else int(self._slots[(end - 1) % self.capacity]["flags"])

    def read_new(self, since: int) -> tuple[np.ndarray, int, int]:
        """Samples written since index `since`: (samples, next index to ask for, samples lost)."""
        end = self.written()
        start = max(since, end - self.capacity)
        slots = np.arange(start, end) % self.capacity
        samples = self._slots[slots]  # fancy indexing copies
        # Lapped while we copied: those slots may hold newer or torn samples. The slot of the index the
        # producer is writing now (`written`) is the one of index written - capacity: that one too.
        overwritten = self.written() - self.capacity + 1
        if overwritten > start:
            samples = samples[overwritten - start:]  # none at all if it lapped us past `end`
            start = overwritten
        return samples, max(end, start), start - since  # lost once: the next read starts past them

    def close(self) -> None:
        del self._slots, self._words, self._now
        self._buffer = None
        self.memory.close()
        if self.owner:
            self.memory.unlink()
