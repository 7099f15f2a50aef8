"""Making a servo loop as real-time as this machine permits, and saying once what it did not permit."""
from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os

MCL_CURRENT, MCL_FUTURE = 1, 2
FIFO_PRIORITY = 80


def prepare_realtime() -> list[str]:
    """Try SCHED_FIFO, mlockall and gc.freeze(); returns one note per thing that could not be done."""
    notes = []
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(FIFO_PRIORITY))
    except (AttributeError, OSError) as exc:
        notes.append(f"SCHED_FIFO not permitted ({getattr(exc, 'strerror', None) or exc}): "
                     "running at normal priority; grant CAP_SYS_NICE or LimitRTPRIO for hard timing")
    if not _mlockall():
        notes.append("mlockall not permitted: memory may page out; grant CAP_IPC_LOCK or LimitMEMLOCK=infinity")
    gc.collect()
    gc.freeze()  # everything alive now is never scanned again, so collections stay short
    return notes


def _mlockall() -> bool:
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    libc = ctypes.CDLL(name, use_errno=True)
    return libc.mlockall(MCL_CURRENT | MCL_FUTURE) == 0
