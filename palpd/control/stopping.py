"""How the servo loop stops (IEC 60204-1 stop categories), mixed into ServoLoop.

Category 0, only where the amplifiers, the encoders or the e-stop demand it:
the current goes at once. Category 1, for every other fault: the probe backs
out along the tissue normal (from where the tip is, so a press releases at
once), the arm is taken to its rest pose in the stand under gravity
compensation, and only there is the power cut, so a stop never leaves the
probe pressing on or sliding across the tissue. During a stop only what would
demand category 0 is checked (the stop is already under way); a stop that
cannot back out within retract_timeout_s, or park in time, cuts the current.
stop() (the end of a scan, probe or tare) parks the same way before the
amplifiers go off.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

from drivers.errors import DriverError
from palpd.control.safety import Fault
from palpd.control.tasks import Park
from palpd.errors import ScanFault

RETRACT_ACCEL_MM_S2 = 2000.0
PARK_SLACK_S = 1.0  # allowed on top of the park's own duration before the stop gives up and cuts


class Stopping:
    def stop(self, park: bool = True) -> None:
        """Park at the rest pose (supervised), then power off; raises ScanFault if safety stops the park
        (the motors are off either way). park=False powers off where the arm is: only for a person holding
        it (a manual session), who then holds its weight."""
        if not self.motors_on or not park:
            self._power_off()
            return
        tip = self.last_tick.tip_mm if self.last_tick is not None else self.rest_mm
        try:
            self.run(self.park_task(), timeout_s=self.retract_timeout_s + self._park_time_s(tip))
        finally:
            self._power_off()

    def home(self) -> None:
        """To the rest pose from wherever the arm is, supervised (limits widened to take in where it starts)."""
        tip = self.last_tick.tip_mm if self.last_tick is not None else self.rest_mm
        self.run(self.park_task(from_anywhere=True), timeout_s=self.retract_timeout_s + self._park_time_s(tip) + 60.0)

    def park_task(self, from_anywhere: bool = False) -> Park:
        return Park(self.rest_mm, self.clear_z_mm, self.retract_speed_mm_s, RETRACT_ACCEL_MM_S2, from_anywhere)

    def _stop_for(self, fault: Fault, tick) -> None:
        """Latch the fault, stop by its category, raise ScanFault; the motors are off afterwards."""
        self.fault = Fault(fault.code, fault.message, fault.t_s, tuple(self.history))
        outcome = "motors were off" if not self.motors_on else "current cut at once (category 0)"
        try:
            if self.fault.category == 1 and self.motors_on:
                outcome = self._controlled_stop(tick)
        finally:
            self._power_off()
            self.fault = replace(self.fault, stop=outcome)
        raise ScanFault(f"{fault.code}: {fault.message} at t = {fault.t_s:.3f} s; {outcome}")

    def _controlled_stop(self, tick) -> str:
        park = self.park_task(from_anywhere=True)
        lift_by = tick.t_s + self.retract_timeout_s
        give_up = lift_by + self._park_time_s(tick.tip_mm)
        try:
            while not park.done:
                started = time.perf_counter()
                tick = self._sense()
                fault = self._estop_fault(tick) or self.supervisor.check_category_0(tick)
                if fault is not None:
                    return f"category 1 stop cut short by {fault.code}: current cut"
                if (not park.lifted and tick.t_s > lift_by) or tick.t_s > give_up:
                    return f"category 1 stop not {'parked' if park.lifted else 'backed out'} in time: current cut"
                self._command(tick, park.step(tick))
                self._end_tick(tick, started)
        except DriverError as exc:
            return f"category 1 stop cut short, robot link lost ({exc})"
        return "category 1: backed out, parked at the rest pose, powered off"

    def _estop_fault(self, tick) -> Fault | None:
        return Fault("estop", "e-stop requested", tick.t_s) if self._estop_wanted() else None

    def _park_time_s(self, tip_mm) -> float:
        x, y, z = tip_mm
        up = (x, y, max(z, self.clear_z_mm))
        distance = (up[2] - z) + math.dist(up, self.rest_mm)
        speed = self.retract_speed_mm_s
        return distance / speed + 4.0 * speed / RETRACT_ACCEL_MM_S2 + PARK_SLACK_S

    def _power_off(self) -> None:
        self.motors_on = False
        try:
            self.robot.disable()
        except DriverError:
            pass  # the link is gone: the bridge's watchdog holds the arm, then cuts

    def _link_lost(self, exc: DriverError) -> None:
        """The robot stopped answering: nothing can be commanded (category 0); the bridge's watchdog takes over."""
        if self.fault is None:
            t_s = self.last_tick.t_s if self.last_tick is not None else self.clock.now()
            self.fault = Fault("robot_link", f"robot link lost: {exc}", t_s, tuple(self.history),
                               stop="nothing to command: the bridge's watchdog holds, then cuts")
        self._power_off()
        raise ScanFault(f"{self.fault.code}: {self.fault.message}; motors off") from exc
