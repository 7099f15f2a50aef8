"""Making a servo loop as real-time as this machine permits, and saying once what it did not permit.

SCHED_FIFO, mlockall and gc.freeze() keep the loop from being preempted, paged out or paused by a
long collection. The PM QoS request (/dev/cpu_dma_latency at 0 us, held for the process's life)
keeps idle CPUs from sleeping deeply, so waking the loop, or the bridge process it talks to, costs
microseconds rather than the milliseconds a halted (virtual) CPU can take.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import struct

MCL_CURRENT, MCL_FUTURE = 1, 2
FIFO_PRIORITY = 80
CPU_LATENCY_QOS = "/dev/cpu_dma_latency"
_held: list[int] = []  # the QoS request lasts while its file stays open


def prepare_realtime() -> list[str]:
    """Try SCHED_FIFO, mlockall, low CPU wake-up latency and gc.freeze(); one note per thing not done."""
    notes = []
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(FIFO_PRIORITY))
    except (AttributeError, OSError) as exc:
        notes.append(f"SCHED_FIFO not permitted ({getattr(exc, 'strerror', None) or exc}): "
                     "running at normal priority; grant CAP_SYS_NICE or LimitRTPRIO for hard timing")
    if not _mlockall():
        notes.append("mlockall not permitted: memory may page out; grant CAP_IPC_LOCK or LimitMEMLOCK=infinity")
    if not _hold_low_cpu_latency():
        notes.append(f"{CPU_LATENCY_QOS} not writable: idle CPUs may be slow to wake the loop")
    gc.collect()
    gc.freeze()  # everything alive now is never scanned again, so collections stay short
    return notes


def scheduling() -> str:
    """The scheduling this process got, as the start-up log says it: "SCHED_FIFO 80", "SCHED_OTHER"."""
    try:
        policy, priority = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    except (AttributeError, OSError):
        return "unknown (no sched_getscheduler here)"
    names = {getattr(os, name): name for name in ("SCHED_OTHER", "SCHED_FIFO", "SCHED_RR", "SCHED_BATCH",
                                                  "SCHED_IDLE") if hasattr(os, name)}
    name = names.get(policy, f"policy {policy}")
    return f"{name} {priority}" if priority else name


def _mlockall() -> bool:
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    libc = ctypes.CDLL(name, use_errno=True)
    return libc.mlockall(MCL_CURRENT | MCL_FUTURE) == 0


def _hold_low_cpu_latency() -> bool:
    if _held:
        return True
    try:
        fd = os.open(CPU_LATENCY_QOS, os.O_WRONLY)
    except OSError:
        return False
    os.write(fd, struct.pack("i", 0))
    _held.append(fd)
    return True
