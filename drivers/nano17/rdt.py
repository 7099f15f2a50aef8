"""ATI Net F/T Raw Data Transfer (RDT) packet layouts, shared by the client and the simulator.

Request, 8 bytes big-endian: header 0x1234, command, sample count (0 = endless).
Record, 36 bytes big-endian: rdt_sequence, ft_sequence, status, then Fx Fy Fz Tx Ty Tz in counts.
A buffered stream packs several records into one datagram.
"""
from __future__ import annotations

import struct

PORT = 49152
HEADER = 0x1234
STOP, STREAM, BUFFERED_STREAM, SET_SOFTWARE_BIAS = 0x0000, 0x0002, 0x0003, 0x0042
REQUEST = struct.Struct(">HHI")
RECORD = struct.Struct(">III6i")
DEFAULT_COUNTS_PER_UNIT = 1_000_000  # counts per force (N) and per torque (N*m) unless configured


def encode_request(command: int, samples: int = 0) -> bytes:
    return REQUEST.pack(HEADER, command, samples)


def decode_request(data: bytes) -> tuple[int, int] | None:
    """(command, samples), or None when it is not an RDT request."""
    if len(data) != REQUEST.size:
        return None
    header, command, samples = REQUEST.unpack(data)
    return (command, samples) if header == HEADER else None


def decode_records(data: bytes) -> list[tuple]:
    """Each record as (rdt_sequence, ft_sequence, status, counts[6]); a datagram of the wrong size gives []."""
    if not data or len(data) % RECORD.size:
        return []
    out = []
    for offset in range(0, len(data), RECORD.size):
        rdt_seq, ft_seq, status, *counts = RECORD.unpack_from(data, offset)
        out.append((rdt_seq, ft_seq, status, counts))
    return out
