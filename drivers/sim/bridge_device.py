"""The device side of the Phantom bridge protocol, played by the simulator.

BridgeDevice turns host frames into STATE replies against a SimWorld, exactly
as the bridge board's firmware would; its watchdog zeroes the currents and
drops the amplifiers when host frames stop for one watchdog period.
SimBridgeTransport puts it behind ``sim://`` in the same process; the servers
in drivers/sim/servers.py put it behind TCP and a pty.
"""
from __future__ import annotations

import time

from drivers.errors import DriverInitializationError, DriverOperationError
from drivers.interfaces import STATUS_WATCHDOG_TRIPPED
from drivers.phantom import codec
from drivers.sim.world import NO_FORCE
from drivers.transport import Transport

DEFAULT_WATCHDOG_S = 0.25


class BridgeDevice:
    def __init__(self, world, watchdog_s: float = DEFAULT_WATCHDOG_S) -> None:
        self.world = world
        self.watchdog_s = watchdog_s
        self.decoder = codec.FrameDecoder()
        self.tripped = False
        self.stalled = False  # a hung bridge: swallows frames, answers nothing
        self._last_host_frame_s: float | None = None
        self._seq = 0
        self.resting = True  # in its home stand until first enabled, as the real arm is parked at power-up

    def advance(self, now_s: float) -> None:
        """Physics up to now; while resting in the stand the arm stays at home and time just passes."""
        if self.resting:
            self.world.t_s = now_s
        else:
            self.world.advance_to(now_s)

    def handle(self, data: bytes) -> bytes:
        """Bytes from the host in, reply bytes out (one STATE per valid host frame)."""
        replies = []
        for frame in self.decoder.feed(data):
            if self.stalled:
                continue
            now = self.world.clock.now()
            self.check_watchdog(now)
            self._last_host_frame_s = now
            if frame.kind == codec.COMMAND:
                self._apply(codec.decode_command(frame.payload))
            replies.append(self._state(frame.seq))
        return b"".join(replies)

    def check_watchdog(self, now_s: float) -> None:
        """Trip when the amplifiers are on and the host has been silent for a whole watchdog period."""
        last = self._last_host_frame_s
        if self.world.amplifiers_on and last is not None and now_s - last > self.watchdog_s:
            self.tripped = True
            self._amplifiers_off()

    def _apply(self, command: codec.Command) -> None:
        if command.watchdog_ms:
            self.watchdog_s = command.watchdog_ms / 1000.0
        if command.enable and command.clear_faults:
            self.tripped = False
        if not command.enable or self.tripped:
            self._amplifiers_off()
            return
        if self.world.estop:
            return
        self.advance(self.world.clock.now())
        self.resting = False
        self.world.amplifiers_on = True
        i0, i1, i2 = command.currents_ma
        self.world.currents_a = (i0 / 1000.0, i1 / 1000.0, i2 / 1000.0)

    def _amplifiers_off(self) -> None:
        self.world.currents_a = NO_FORCE
        self.world.amplifiers_on = False

    def _state(self, ack_seq: int) -> bytes:
        world = self.world
        self.advance(world.clock.now())
        status = world.status() | (STATUS_WATCHDOG_TRIPPED if self.tripped else 0)
        self._seq += 1
        state = codec.State(world.encoder_counts(), status, int(world.t_s * 1e6), ack_seq,
                            self.decoder.rejected_frames)
        return codec.encode_state(self._seq, state)

    def press_estop(self) -> None:
        self.world.press_estop()


class SimBridgeTransport(Transport):
    """``sim://``: the bridge in this process; bytes still go through the codec both ways."""

    def __init__(self, url: str = "sim://", timeout_s: float = 0.05, world=None, device=None,
                 watchdog_s: float = DEFAULT_WATCHDOG_S) -> None:
        if device is None and world is None:
            raise DriverInitializationError(f"{url}: the simulated bridge needs a simulated world (a scene)")
        self.url = url
        self.device = device or BridgeDevice(world, watchdog_s)
        self.unplugged = False
        self._pending = bytearray()

    def write(self, data: bytes) -> None:
        if self.unplugged:
            raise DriverOperationError(f"{self.url}: write failed (device unplugged)")
        self._pending += self.device.handle(data)

    def read(self, timeout_s: float) -> bytes:
        if self.unplugged:
            raise DriverOperationError(f"{self.url}: read failed (device unplugged)")
        if not self._pending:
            time.sleep(timeout_s)  # nothing can arrive in-process: wait out the timeout as a real port would
            return b""
        data = bytes(self._pending)
        self._pending.clear()
        return data
