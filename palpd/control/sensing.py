"""What the servo loop knows at each tick, and how it comes to know it (mixed into ServoLoop).

The encoders' reading (the last command's reply), the force sample, the tip in
the tissue frame, the real gaps between samples (the bridge's own clock when it
has one), a filtered tip velocity over those gaps, the tissue force; and the
tick's place on the loop's own tick clock, which is what motion follows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.errors import DriverError
from drivers.interfaces import SAMPLE_STALE, ForceSample
from drivers.phantom import model
from palpd.control.surface import held_lead_mm

Vec3 = tuple[float, float, float]
DEVICE_CLOCK_WRAP_S = 2**32 * 1e-6  # the bridge's microsecond counter is 32 bits
NO_FORCE = (0.0, 0.0, 0.0)


@dataclass(slots=True)
class Tick:
    """What the loop knows at one instant, handed to the safety supervisor and the task."""

    t_s: float
    q: Vec3
    tip_mm: Vec3
    velocity_mm_s: Vec3
    force_tissue_n: Vec3
    normal_force_n: float
    sample: ForceSample
    status: int
    gap_s: float = 0.0  # since the previous tick, on the host's clock
    sample_gap_s: float = 0.0  # between the two encoder samples: the device's clock when it has one
    motion_t_s: float = 0.0  # the loop's tick clock: one period per tick whatever the gap; motion follows it
    setpoint_mm: Vec3 | None = None  # where the last command sent the tip (None: no command yet)
    commanded_n: float = 0.0  # the force the last command asked for (clamped to the cap)
    lost_s: float = 0.0  # periods the loop skipped (missed deadlines) just before this tick
    commanded_force_n: Vec3 = NO_FORCE  # the force the last command's motor currents put on the tip (tissue frame)
    floor_z_mm: float = -math.inf  # the deepest the tip may go here (palpd.control.surface; -inf: no floor known)
    path_accel_mm_s2: Vec3 = NO_FORCE  # the acceleration the last command's path asked of the tip (tissue frame)
    held_lead_mm: float = 0.0  # how far the tissue's push surely holds the tip above its setpoint (surface.held_lead_mm)



class Sensing:
    def _sense(self) -> Tick:
        state = self.robot.read()
        sample = self._read_sensor()
        q = state.angles_rad
        tip_m = self.frame.from_robot(model.forward(q))
        tip = (tip_m[0] * 1000.0, tip_m[1] * 1000.0, tip_m[2] * 1000.0)
        t_s = state.t_s
        gap = 0.0 if self._previous_t is None else t_s - self._previous_t
        self._previous_t = t_s
        sample_gap = self._sample_gap_s(state.device_t_s, gap)
        self._update_velocity(tip, sample_gap)
        force = self.forces.tissue_force(sample, q)
        normal = self.forces.normal_force(sample, q, force)
        if normal > self.max_contact_force_n:
            self.max_contact_force_n = normal
        self._motion_t += self.period_s
        tick = Tick(t_s, q, tip, self._velocity, force, normal, sample, state.status, gap, sample_gap,
                    self._motion_t, self._setpoint, self.controller.last_force_n, self._lost_s,
                    self.controller.last_force_vec_n,
                    self.surface.floor_z_mm(tip) if self.surface is not None else -math.inf, self._path_accel,
                    held_lead_mm(normal, self.forces.noise, self.controller.kp))
        self._lost_s = 0.0
        self.last_tick = tick
        self.history.append((t_s, tip, force))
        return tick

    def _read_sensor(self) -> ForceSample:
        """A sensor that stops answering is a sensor_link fault (category 1): the stop needs only the
        encoders, so from then on the last sample stands in, flagged stale, and the sensor is left alone."""
        if self._sensor_lost is None:
            try:
                self._last_sample = self.sensor.read()
                return self._last_sample
            except DriverError as exc:
                self._sensor_lost = f"force sensor lost: {exc}"
        last = self._last_sample or ForceSample(0.0, NO_FORCE, NO_FORCE)
        return ForceSample(last.t_s, last.force_n, last.torque_n_mm, last.flags | SAMPLE_STALE)

    def _sample_gap_s(self, device_t_s: float | None, host_gap_s: float) -> float:
        """The real time between this encoder sample and the previous one. A bridge stamps its samples
        with its own microsecond clock (wrapping at 2**32 us); the host's receive times add the transport's
        jitter, so a late reply followed by a prompt one would shrink the gap and inflate the speed. A
        device clock that stands still or leaps is not believed: the host's gap is used instead."""
        previous, self._previous_device_t = self._previous_device_t, device_t_s
        if device_t_s is None or previous is None or host_gap_s <= 0.0:
            return host_gap_s
        device_gap_s = (device_t_s - previous) % DEVICE_CLOCK_WRAP_S
        return device_gap_s if 0.0 < device_gap_s < 1.0 else host_gap_s

    def _update_velocity(self, tip: Vec3, dt_s: float) -> None:
        """Low-pass filtered differences over the real time between ticks, so a late tick is no speed spike."""
        previous = self._previous_tip
        self._previous_tip = tip
        if previous is None or dt_s <= 0.0:
            return
        a = self._smoothing if dt_s == self.period_s else math.exp(-self._filter_rad_s * dt_s)
        rate = (1.0 - a) / dt_s
        v = self._velocity
        self._velocity = (
            a * v[0] + rate * (tip[0] - previous[0]),
            a * v[1] + rate * (tip[1] - previous[1]),
            a * v[2] + rate * (tip[2] - previous[2]),
        )
