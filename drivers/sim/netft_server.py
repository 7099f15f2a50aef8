"""A simulated ATI Net F/T box serving RDT over UDP, with ATI's packet layouts.

It streams the simulated Nano17's load in counts (per N and per N*m) at
rate_hz, answers stop / stream / buffered stream / software bias, and sets
the status word when the load is beyond the calibrated range. Off-the-shelf
RDT clients can read it.
"""
from __future__ import annotations

import socket

from drivers.nano17 import rdt
from drivers.sim.nano17 import FORCE_RANGE_N, TORQUE_RANGE_N_MM

# The simulator's status word: bit 31 "error", bit 17 "a gauge or axis beyond its range" (0 = healthy).
STATUS_SATURATED = 0x80020000
BUFFERED_RECORDS = 4  # records per datagram in buffered mode


class NetFtEndpoint:
    def __init__(self, world, host: str = "127.0.0.1", port: int = rdt.PORT, rate_hz: float = 1000.0,
                 counts_per_force: float = rdt.DEFAULT_COUNTS_PER_UNIT,
                 counts_per_torque: float = rdt.DEFAULT_COUNTS_PER_UNIT) -> None:
        self.world, self.period_s = world, 1.0 / rate_hz
        self._force_counts, self._torque_counts = counts_per_force, counts_per_torque / 1000.0  # per N*mm
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._socket.bind((host, port))
        self.address = self._socket.getsockname()[:2]
        self.url = f"netft://{self.address[0]}:{self.address[1]}"
        self.stalled = False  # a hung box: stops streaming, ignores requests
        self._client = None
        self._remaining = 0  # records left to send; -1 = endless
        self._per_datagram = 1
        self._bias = [0.0] * 6
        self._rdt_seq = self._ft_seq = 0
        self._next_send_s = 0.0

    def fds(self) -> list:
        return [self._socket]

    def on_readable(self, fd) -> None:
        data, sender = self._socket.recvfrom(64)
        request = rdt.decode_request(data)
        if request is None or self.stalled:
            return
        command, samples = request
        if command == rdt.STOP:
            self._client, self._remaining = None, 0
        elif command in (rdt.STREAM, rdt.BUFFERED_STREAM):
            self._client, self._remaining = sender, samples or -1
            self._per_datagram = BUFFERED_RECORDS if command == rdt.BUFFERED_STREAM else 1
        elif command == rdt.SET_SOFTWARE_BIAS:
            self._bias = list(self.world.sensor_wrench())

    def on_tick(self, now_s: float) -> None:
        if self._client is None or self.stalled or now_s < self._next_send_s:
            return
        self._next_send_s = max(self._next_send_s + self.period_s * self._per_datagram, now_s)
        records = [self._record() for _ in range(self._per_datagram if self._remaining < 0
                                                 else min(self._per_datagram, self._remaining))]
        try:
            self._socket.sendto(b"".join(records), self._client)
        except OSError:
            self._client = None
            return
        if self._remaining > 0:
            self._remaining -= len(records)
            if self._remaining == 0:
                self._client = None

    def _record(self) -> bytes:
        load = self.world.sensor_wrench()
        beyond = any(abs(load[i]) > FORCE_RANGE_N[i] for i in range(3)) or any(
            abs(v) > TORQUE_RANGE_N_MM for v in load[3:])
        counts = [round((v - b) * (self._force_counts if i < 3 else self._torque_counts))
                  for i, (v, b) in enumerate(zip(load, self._bias))]
        self._rdt_seq = (self._rdt_seq + 1) & 0xFFFFFFFF
        self._ft_seq = (self._ft_seq + 7) & 0xFFFFFFFF  # the box's internal rate is higher than RDT's
        counts = [max(-2**31, min(2**31 - 1, c)) for c in counts]
        return rdt.RECORD.pack(self._rdt_seq, self._ft_seq, STATUS_SATURATED if beyond else 0, *counts)

    def skip(self, records: int) -> None:
        """Lose records on the wire (for tests of gap counting)."""
        self._rdt_seq = (self._rdt_seq + records) & 0xFFFFFFFF

    def close(self) -> None:
        self._socket.close()
