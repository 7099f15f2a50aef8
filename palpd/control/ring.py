"""Shared memory between the servo process and its parent: a header and a ring of samples.

Single producer (the servo loop writes one sample per tick), single consumer
(the parent reads what is new). The producer writes the slot, then bumps the
write index, so a reader never sees a slot before it is complete; a reader that
falls more than a ring behind loses the oldest samples and is told how many.
The header also carries the loop's heartbeat, its clock and tick counters, and
the parent's e-stop input, which the loop reads every tick, and its wind-down request (end the task under
way gently: a slide lifts off at once), which a task that can wind down reads every tick.
"""
from __future__ import annotations

import struct
from multiprocessing import shared_memory

import numpy as np

CAPACITY = 1 << 14  # samples: 16 s at 1 kHz
# write_index, heartbeat, ticks, overruns, now_s (the producer's, written in one call), estop, wind_down
# (the parent's)
_HEADER = struct.Struct("<QQQQdQQ")
_BEAT_FIELDS = struct.Struct("<QQQd")
_SAMPLE = struct.Struct("<d3d3d3ddII")
SAMPLE_DTYPE = np.dtype([("t_s", "<f8"), ("q_rad", "<f8", 3), ("tip_mm", "<f8", 3), ("force_n", "<f8", 3),
                         ("normal_force_n", "<f8"), ("status", "<u4"), ("flags", "<u4")])
assert SAMPLE_DTYPE.itemsize == _SAMPLE.size
HEADER_BYTES = 64
FLAG_MOTORS_ON, FLAG_FAULT, FLAG_TASK = 1, 2, 4
_INDEX, _BEAT, _TICKS, _OVERRUNS, _NOW, _ESTOP, _WIND_DOWN = (8 * i for i in range(7))


class SampleRing:
    def __init__(self, memory: shared_memory.SharedMemory, owner: bool) -> None:
        self.memory, self.owner = memory, owner
        self._buffer = memory.buf
        self.capacity = (memory.size - HEADER_BYTES) // _SAMPLE.size
        self._slots = np.ndarray((self.capacity,), SAMPLE_DTYPE, self._buffer, HEADER_BYTES)
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
        struct.pack_into("<Q", self._buffer, _INDEX, i + 1)

    def beat(self, now_s: float, ticks: int, overruns: int) -> None:
        self._beats += 1
        _BEAT_FIELDS.pack_into(self._buffer, _BEAT, self._beats, ticks, overruns, now_s)

    def is_set(self) -> bool:
        """The e-stop input (the loop polls it like a threading.Event)."""
        return struct.unpack_from("<Q", self._buffer, _ESTOP)[0] != 0

    def wind_down_wanted(self) -> bool:
        return struct.unpack_from("<Q", self._buffer, _WIND_DOWN)[0] != 0

    # Consumer (the parent) -------------------------------------------------------------------------

    def set_estop(self, on: bool = True) -> None:
        struct.pack_into("<Q", self._buffer, _ESTOP, 1 if on else 0)

    def set_wind_down(self, on: bool = True) -> None:
        struct.pack_into("<Q", self._buffer, _WIND_DOWN, 1 if on else 0)

    def header(self) -> dict:
        index, beat, ticks, overruns, now_s, estop, wind_down = _HEADER.unpack_from(self._buffer, 0)
        return {"written": index, "heartbeat": beat, "ticks": ticks, "overruns": overruns,
                "estop": bool(estop), "wind_down": bool(wind_down), "now_s": now_s}

    def last_flags(self) -> int:
        """The flags of the newest sample (FLAG_FAULT: the loop has latched a fault); 0 before the first."""
        end = struct.unpack_from("<Q", self._buffer, _INDEX)[0]
        return 0 if end == 0 else int(self._slots[(end - 1) % self.capacity]["flags"])

    def read_new(self, since: int) -> tuple[np.ndarray, int, int]:
        """Samples written since index `since`: (samples, next index to ask for, samples lost)."""
        end = struct.unpack_from("<Q", self._buffer, _INDEX)[0]
        start = max(since, end - self.capacity)
        slots = np.arange(start, end) % self.capacity
        samples = self._slots[slots].copy()
        overwritten = struct.unpack_from("<Q", self._buffer, _INDEX)[0] - self.capacity
        if overwritten > start:  # the producer lapped us while we copied: those slots may be torn
            samples = samples[overwritten - start:]
            start = overwritten
        return samples, end, start - since

    def close(self) -> None:
        del self._slots
        self._buffer = None
        self.memory.close()
        if self.owner:
            self.memory.unlink()
