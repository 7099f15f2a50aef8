"""The device side of the Phantom bridge protocol, played by the simulator.

BridgeDevice turns host frames into STATE replies against a SimWorld, exactly
as the bridge board's firmware would, watchdog included (PROTOCOL.md): when
host frames stop for hold_after_s it ramps the currents over hold_ramp_s to
the hold the host last sent (gravity compensation), braked once the host has
been silent HOLD_DAMP_AFTER_S, and after watchdog_s of
silence it cuts the amplifiers and latches the trip. The physics runs through
those instants as they fall due, not when the next frame happens to arrive.
SimBridgeTransport puts it behind ``sim://`` in the same process; the servers
in drivers/sim/servers.py put it behind TCP and a pty.
"""
from __future__ import annotations

import time

from drivers.errors import DriverInitializationError, DriverOperationError
from drivers.interfaces import STATUS_HOLDING, STATUS_WATCHDOG_TRIPPED
from drivers.phantom import codec, model
from drivers.sim.world import NO_FORCE, PHYSICS_STEP_S
from drivers.transport import Transport

DEFAULT_WATCHDOG_S = 10.0
DEFAULT_HOLD_AFTER_S = 0.0015
DEFAULT_HOLD_RAMP_S = 0.001
# A host silent this long is not late but gone (the host rides out isolated stalls of a few ms on the hold
# alone, as its gains are designed for): the hold then brakes each joint, so that what the last command set
# moving comes to rest instead of coasting on a frictionless arm (a servo killed mid-correction: 3 mm in 0.3 s).
HOLD_DAMP_AFTER_S = 0.02
HOLD_DAMPING_TAU_S = 0.01  # the braked joint's velocity time constant (explicit physics step: 0.5 ms, stable)


def brake_currents(qd) -> tuple[float, float, float]:
    """What the hold adds to brake joints turning at qd (rad/s): −(J/τ)·q̇ as motor currents (PROTOCOL.md)."""
    inertia = model.JOINT_INERTIA_KG_M2
    return model.torques_to_currents(tuple(-inertia[j] / HOLD_DAMPING_TAU_S * qd[j] for j in range(3)))


class BridgeDevice:
    def __init__(self, world, watchdog_s: float = DEFAULT_WATCHDOG_S, hold_after_s: float = DEFAULT_HOLD_AFTER_S,
                 hold_ramp_s: float = DEFAULT_HOLD_RAMP_S) -> None:
        self.world = world
        self.watchdog_s, self.hold_after_s, self.hold_ramp_s = watchdog_s, hold_after_s, hold_ramp_s
        self.decoder = codec.FrameDecoder()
        self.tripped = False
        self.stalled = False  # a hung bridge: swallows frames, answers nothing
        self.holds = 0  # how many times a silent host made it ramp to the hold
        self._last_host_frame_s: float | None = None
        self._last_command_s: float | None = None
        self._commanded_a = NO_FORCE  # the last COMMAND's currents
        self._hold_a = NO_FORCE  # and the hold it came with
        self._holding = False
        self._seq = 0

    def advance(self, now_s: float) -> None:
        """Physics up to now, with the watchdog's ramp, hold and trip applied at the instants they fall due.

        Currents come only with COMMANDs, so the hold counts from the last COMMAND; the cut counts from the
        last valid frame of any kind."""
        world, commanded = self.world, self._last_command_s
        if commanded is None or not world.amplifiers_on:
            world.advance_to(now_s)
            return
        hold_at = commanded + self.hold_after_s
        world.advance_to(min(now_s, hold_at))
        if now_s < hold_at:
            return
        if not self._holding:
            self._holding, self.holds = True, self.holds + 1
        off_at = self._last_host_frame_s + self.watchdog_s
        end = min(now_s, off_at)
        damp_at = commanded + HOLD_DAMP_AFTER_S
        while world.t_s + PHYSICS_STEP_S <= end + 1e-12:  # the currents follow the ramp, then the brake
            world.currents_a = self._held(world.t_s - hold_at, world.t_s >= damp_at)
            world.step()
        world.currents_a = self._held(world.t_s - hold_at, world.t_s >= damp_at)
        world.advance_to(end)
        if now_s >= off_at:
            self.tripped = True
            self._amplifiers_off()
            world.advance_to(now_s)

    def _held(self, into_s: float, damped: bool) -> tuple[float, float, float]:
        """The hold's currents: the ramp, then the hold, braked once the host has been silent too long."""
        i0, i1, i2 = self._ramped(into_s)
        if not damped:
            return i0, i1, i2
        b0, b1, b2 = brake_currents(self.world.arm.qd)
        return i0 + b0, i1 + b1, i2 + b2

    def _ramped(self, into_s: float) -> tuple[float, float, float]:
        """Currents into_s after the ramp began: from the last command straight to the hold."""
        s = 1.0 if into_s >= self.hold_ramp_s else max(into_s, 0.0) / self.hold_ramp_s
        c, h = self._commanded_a, self._hold_a
        return (c[0] + s * (h[0] - c[0]), c[1] + s * (h[1] - c[1]), c[2] + s * (h[2] - c[2]))

    def handle(self, data: bytes) -> bytes:
        """Bytes from the host in, reply bytes out (one STATE per valid host frame)."""
        replies = []
        for frame in self.decoder.feed(data):
            if self.stalled:
                continue
            now = self.world.clock.now()
            self.advance(now)
            self._last_host_frame_s = now
            if frame.kind == codec.COMMAND:
                self._apply(codec.decode_command(frame.payload))
            replies.append(self._state(frame.seq))
        return b"".join(replies)

    def check_watchdog(self, now_s: float) -> None:
        """Bring the physics and the watchdog up to now (a serving loop calls this between frames)."""
        self.advance(now_s)

    def _apply(self, command: codec.Command) -> None:
        if command.watchdog_ms:
            self.watchdog_s = command.watchdog_ms / 1000.0
        if command.hold_after_us:
            self.hold_after_s = command.hold_after_us / 1e6
        if command.hold_ramp_us:
            self.hold_ramp_s = command.hold_ramp_us / 1e6
        if command.enable and command.clear_faults:
            self.tripped = False
        if not command.enable or self.tripped:
            self._amplifiers_off()
            return
        if self.world.estop:
            return
        self._holding, self._last_command_s = False, self._last_host_frame_s
        i0, i1, i2 = command.currents_ma
        h0, h1, h2 = command.hold_ma
        self._commanded_a = self.world.currents_a = (i0 / 1000.0, i1 / 1000.0, i2 / 1000.0)
        self._hold_a = (h0 / 1000.0, h1 / 1000.0, h2 / 1000.0)
        self.world.amplifiers_on = True

    def _amplifiers_off(self) -> None:
        self._holding, self._last_command_s = False, None
        self.world.currents_a = self._commanded_a = self._hold_a = NO_FORCE
        self.world.amplifiers_on = False

    def _state(self, ack_seq: int) -> bytes:
        world = self.world
        status = world.status() | (STATUS_WATCHDOG_TRIPPED if self.tripped else 0) | \
            (STATUS_HOLDING if self._holding else 0)
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
        started = time.perf_counter()
        self._pending += self.device.handle(data)
        self.device.world.cpu_s += time.perf_counter() - started  # the device's share of the host's tick

    def read(self, timeout_s: float) -> bytes:
        if self.unplugged:
            raise DriverOperationError(f"{self.url}: read failed (device unplugged)")
        if not self._pending:
            time.sleep(timeout_s)  # nothing can arrive in-process: wait out the timeout as a real port would
            return b""
        data = bytes(self._pending)
        self._pending.clear()
        return data
