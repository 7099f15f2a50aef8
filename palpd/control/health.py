"""Force-sensor health, watched every tick beside the safety supervisor: a frozen sensor and a drifting zero.

Frozen: a live Nano17 never repeats itself exactly (its noise moves every gauge by counts from sample to
sample), so new readings identical in all six axes for `safety.frozen_window_s` mean a stuck sensor, amplifier
or DAQ, even though fresh readings keep coming. A stream that stops (no new reading: the driver hands out the
last one again, flagged SAMPLE_REPEAT) is the stale-sample check's.

Drift: strain gauges warm up and their zero wanders, so the force read in contact is off by the drift since
the tare, and the tissue takes more than palpd reads. At every approach, the force measured over the last
`safety.drift_window_s` out of contact (the tip at clearance height above the tissue) is compared with the tare
(zero): beyond `drift_retare_n` the sensor is tared again there, beyond `drift_fault_n` it is a fault (a zero
that moved that much between two palpations is a broken sensor, or the probe is touching something).

Mismatch: between two approaches the zero can wander far while the probe presses (the issue-51 bench: 4 N read
where the tissue took 6 N). So every tick the force read along the tissue normal is held against the force the
last command's motor currents put on the tip (the controller's Jᵀ force, gravity aside): with the arm moving
gently the two balance but for the arm's inertia, which an impact or a release makes large only for a few ms.
Low-passed over MISMATCH_FILTER_S, further apart than `safety.force_mismatch_n` for `force_mismatch_window_s`,
the sensor is wrong: a `sensor_drift` fault, in contact or out of it, long before the true force can pass the cap
(the controller itself never pushes harder than the cap).
"""
from __future__ import annotations

import math
from collections import deque

from drivers.geometry import TissueFrame
from drivers.interfaces import SAMPLE_REPEAT
from drivers.phantom import model
from palpd.control.safety import Fault

CLEARANCE_SLACK_MM = 1.0  # the tip counts as out of contact this close under the clearance height (tracking)
MISMATCH_FILTER_S = 0.01  # the read and pushed forces low-passed over this: an impact's inertia lasts a few ms
INERTIA_MEMORY_S = 0.05  # the arm lags its path's acceleration: what that acceleration takes is allowed this long


class SensorHealth:
    def __init__(self, safety, forces, clearance_mm: float, period_s: float) -> None:
        """safety: palpd.config.SafetySettings; forces: the loop's ForceReader (tared again here)."""
        self.s, self.forces = safety, forces
        self.above_mm = clearance_mm - CLEARANCE_SLACK_MM
        self._window: deque = deque(maxlen=max(2, round(safety.drift_window_s / period_s)))
        self._smoothing = 1.0 - math.exp(-period_s / MISMATCH_FILTER_S)
        self._inertia_decay = math.exp(-period_s / INERTIA_MEMORY_S)
        self.retares = 0
        self.max_drift_n = 0.0  # the largest drift found at an approach since start-up
        self.recovering = False  # set by the supervisor while the arm is brought back from wherever it lay
        self.hand_guided = False  # set by the supervisor while a person moves the arm (a manual session)
        self.reset()

    def reset(self) -> None:
        self._window.clear()
        self._last_reading = None
        self._same_since_s: float | None = None
        self._was_above = False
        self._mismatch_n = 0.0
        self._inertia_n = 0.0
        self._apart_since_s: float | None = None

    def check(self, tick) -> Fault | None:
        return self._frozen(tick) or self._drift(tick) or self._mismatch(tick)

    def _mismatch(self, tick) -> Fault | None:
        """The normal force read against the normal force the motors push with (both low-passed)."""
        if tick.setpoint_mm is None or self.recovering or self.hand_guided:  # nothing pushes yet, the arm is pulled
            # off the tissue, or a person's hand pushes it (the motors only hold up its weight)
            return None
        read_n, pushed_n = tick.force_tissue_n[2], -tick.commanded_force_n[2]
        self._mismatch_n += (read_n - pushed_n - self._mismatch_n) * self._smoothing
        # Part of the push accelerates the arm along its path (a travel's start, a slide's swing), not the tissue;
        # the arm takes it up late, so the tolerance widens by what the path's acceleration takes, for a while.
        self._inertia_n = max(abs(_inertia_z_n(tick)), self._inertia_n * self._inertia_decay)
        if abs(self._mismatch_n) <= self.s.force_mismatch_n + self._inertia_n:
            self._apart_since_s = None
            return None
        if self._apart_since_s is None:
            self._apart_since_s = tick.t_s
        apart_s = tick.t_s - self._apart_since_s
        if apart_s < self.s.force_mismatch_window_s:
            return None
        return Fault("sensor_drift", f"force sensor reads {read_n:.2f} N along the tissue normal where the motors "
                     f"push {pushed_n:.2f} N ({self._mismatch_n:+.2f} N apart for {1000 * apart_s:.0f} ms, beyond "
                     f"safety.force_mismatch_n {self.s.force_mismatch_n} N): its zero has drifted", tick.t_s)

    def _frozen(self, tick) -> Fault | None:
        """New readings (a sample flagged SAMPLE_REPEAT is an old one handed out again: the stale check's)
        identical in all six axes for frozen_window_s."""
        if tick.sample.flags & SAMPLE_REPEAT:
            return None
        reading = (tick.sample.force_n, tick.sample.torque_n_mm)
        if reading != self._last_reading:
            self._last_reading, self._same_since_s = reading, tick.t_s
            return None
        same_s = tick.t_s - self._same_since_s
        if same_s >= self.s.frozen_window_s:
            return Fault("sensor_frozen", f"force sensor repeated the same reading for {1000 * same_s:.1f} ms "
                         "(frozen sensor, amplifier or DAQ)", tick.t_s)
        return None

    def _drift(self, tick) -> Fault | None:
        above = tick.tip_mm[2] >= self.above_mm
        if above:
            self._window.append((tick.sample, tick.force_tissue_n))
        approaching, self._was_above = self._was_above and not above, above
        if not approaching or len(self._window) < self._window.maxlen:
            if not above:
                self._window.clear()
            return None
        return self._judge(tick.t_s)

    def _judge(self, t_s: float) -> Fault | None:
        """The tip just went below clearance height: how far is the zero from the tare?"""
        n = len(self._window)
        drift = [sum(force[i] for _, force in self._window) / n for i in range(3)]
        drift_n = math.sqrt(sum(v * v for v in drift))
        self.max_drift_n = max(self.max_drift_n, drift_n)
        samples = [sample for sample, _ in self._window]
        self._window.clear()
        if drift_n > self.s.drift_fault_n:
            return Fault("sensor_drift", f"force sensor reads {drift_n:.3f} N out of contact, beyond "
                         f"safety.drift_fault_n ({self.s.drift_fault_n} N) from its tare", t_s)
        if drift_n > self.s.drift_retare_n:
            self.forces.tare(samples)
            self.retares += 1
        return None

    def summary(self) -> dict:
        return {"retares": self.retares, "max_drift_n": round(self.max_drift_n, 4)}


def _inertia_z_n(tick) -> float:
    """The force along the normal that the path's acceleration takes to accelerate the arm at its pose."""
    a = tick.path_accel_mm_s2
    if a == (0.0, 0.0, 0.0):
        return 0.0
    robot = model.tip_inertia_force_n(tick.q, TissueFrame.vector_to_robot((a[0] / 1000.0, a[1] / 1000.0,
                                                                            a[2] / 1000.0)))
    return TissueFrame.vector_from_robot(robot)[2]
