"""The simulated bench: arm, tissue and sensor advancing together on one clock.

The world keeps the truth the host cannot see: the contact force at every
physics step (its peak is what the tissue really took, whatever the host's
samples say). With its amplifiers off the arm falls under gravity, except in
its stand at home, where the real Phantom is parked at power-up and where a
controlled stop leaves it.
"""
from __future__ import annotations

import math
import random

from drivers.geometry import TissueFrame, rotate_xy
from drivers.interfaces import STATUS_AMPLIFIERS_ON, STATUS_ESTOP, ForceSample
from drivers.phantom import model
from drivers.sim.arm import SimArm
from drivers.sim.faults import RigidObject, SimFaults
from drivers.sim.mechanics.table import TableField, cached_table
from drivers.sim.nano17 import SimNano17
from drivers.sim.scene import Scene
from drivers.sim.tissue import StiffnessField, hunt_crossley_n, sliding_friction_n

PHYSICS_STEP_S = 0.0005
NO_FORCE = (0.0, 0.0, 0.0)
HOME_Q = model.HOME_Q
STAND_CAPTURE_MM = 3.0  # powered off this close to home, the arm settles into its stand
_HOME = list(HOME_Q)


class SimWorld:
    """Advances lazily: whoever reads it first after the clock moved pays for the physics."""

    def __init__(self, scene: Scene, clock, seed: int = 0) -> None:
        self.scene = scene
        self.clock = clock
        self.frame = TissueFrame(tuple(v / 1000.0 for v in scene.placement.origin_mm))
        self.q_aligned = model.inverse(self.frame.to_robot((0.0, 0.0, 0.0)))
        self._tilt = model.SensorTilt(self.q_aligned)
        # a 3-D layer: its finite-element force table (built once per scene, then cached); else the felt field
        self.table = TableField(cached_table(scene), scene.tissue.damping_n_s_per_mm) if scene.tissue.is_3d else None
        self.field = self.table if self.table is not None else StiffnessField(scene)
        # A 3-D layer is bonded to a rigid base: a tip pressed through the layer's thickness meets it (the table,
        # linear elastic, would go on as if the layer were deeper: 2.8 mm into a 1 mm layer at 2.6 N)
        self.base = RigidObject((0.0, 0.0), math.inf, scene.tissue.thickness_mm) if scene.tissue.is_3d else None
        rng = random.Random(hash((scene.seed, seed)) & 0xFFFFFFFF)
        self.sensor = SimNano17(scene.sensor.noise_n, scene.sensor.bias_n, rng)
        self.arm = SimArm()
        self.t_s = clock.now()
        self.currents_a: model.Vec3 = NO_FORCE
        self._amplifiers_on = False
        self.in_stand = True  # parked at home, as at power-up: the stand holds it while unpowered
        self.estop = False
        self.contact_force_robot: model.Vec3 = NO_FORCE
        self.contact_force_n = 0.0  # normal force the tissue takes now
        self.max_contact_force_n = 0.0  # its peak over every physics step (reset_peak() starts afresh)
        self.indentation_mm = 0.0  # how far the tip is below the true surface now (0 above it)...
        self.max_indentation_mm = 0.0  # ...and the deepest it went, over every physics step (reset_peak() too)
        self.faults = SimFaults(scene.faults, self.t_s)  # fault injection: the scene's [faults], and tests
        self.hand = None  # when set, a person moves the arm: hand.q_at(t_s) overrides the dynamics
        self.step_hook = None  # called after every physics step (tests and benchmarks watch the truth here)
        self.cpu_s = 0.0  # CPU time spent simulating the devices (the bridge's and the DAQ's side), for benchmarks
        self._rotation_deg = scene.placement.rotation_deg
        self._tissue = scene.tissue

    # -- device side -------------------------------------------------------------------------
    @property
    def amplifiers_on(self) -> bool:
        return self._amplifiers_on

    @amplifiers_on.setter
    def amplifiers_on(self, on: bool) -> None:
        """Powered, the motors lift the arm out of its stand; unpowered near home, it settles back in."""
        self._amplifiers_on = on
        self.in_stand = not on and self.hand is None and self._near_home()
        if self.in_stand:
            self.arm.q, self.arm.qd = list(HOME_Q), [0.0, 0.0, 0.0]
            self.contact_force_robot, self.contact_force_n = NO_FORCE, 0.0

    def advance_to(self, t_s: float) -> None:
        if self.in_stand and self.hand is None and self.arm.q == _HOME:  # parked, unpowered: only time passes
            steps = int((t_s + 1e-12 - self.t_s) / PHYSICS_STEP_S)
            self.t_s += max(steps, 0) * PHYSICS_STEP_S
            return
        while self.t_s + PHYSICS_STEP_S <= t_s + 1e-12:
            self.step()
        if t_s - self.t_s > 1e-9:  # on the wall clock: the rest of the way, so a reading is never a step old
            self.step(t_s - self.t_s)

    def step(self, dt_s: float = PHYSICS_STEP_S) -> None:
        """One physics step (in as many sub-steps as the tissue's damping needs to stay stable)."""
        substeps = self._damping_substeps(dt_s)
        for _ in range(substeps):
            self._step(dt_s / substeps)
        self.t_s += dt_s
        if self.step_hook is not None:
            self.step_hook(self)

    def reset_peak(self) -> float:
        """The true peak contact force so far, and start a new one."""
        peak, self.max_contact_force_n = self.max_contact_force_n, self.contact_force_n
        self.max_indentation_mm = self.indentation_mm
        return peak

    def tip_mm(self) -> model.Vec3:
        """Where the tip truly is, in the tissue frame."""
        x, y, z = self.frame.from_robot(model.forward(tuple(self.arm.q)))  # type: ignore[arg-type]
        return (1000.0 * x, 1000.0 * y, 1000.0 * z)

    def _near_home(self) -> bool:
        home = model.forward(HOME_Q)
        return 1000.0 * math.dist(model.forward(tuple(self.arm.q)), home) <= STAND_CAPTURE_MM  # type: ignore[arg-type]

    def press_estop(self) -> None:
        """The red button on the bench: the amplifiers drop at once, whatever the host says."""
        self.estop = True
        self.currents_a = NO_FORCE
        self.amplifiers_on = False

    def status(self) -> int:
        bits = (STATUS_AMPLIFIERS_ON if self.amplifiers_on else 0) | (STATUS_ESTOP if self.estop else 0)
        return self.faults.status(bits)

    def encoder_counts(self) -> tuple[int, int, int]:
        return self.faults.counts(model.angles_to_counts(self.arm.q))  # type: ignore[arg-type]

    def sensor_sample(self) -> ForceSample:
        """What an ideal DAQ in force units would report (the sim-direct path, no wire format)."""
        return self.faults.sample(self.sensor.sample(self.t_s, self._force_on_sensor()))

    def sensor_reading(self) -> tuple[float, list[float]]:
        """(time of the reading, load on the Nano17 in N and N*mm with its bias and noise), before any DAQ.

        A frozen sensor keeps handing out its last reading's values with fresh times (stuck gauges).
        """
        return self.faults.wrench(self.t_s, self.sensor.wrench(self._force_on_sensor()))

    def sensor_wrench(self) -> list[float]:
        return self.sensor_reading()[1]

    def _force_on_sensor(self) -> model.Vec3:
        force = self.contact_force_robot
        if self.scene.sensor.tilt:
            force = self._tilt.from_base(tuple(self.arm.q), force)  # type: ignore[arg-type]
        return self.frame.vector_from_robot(force)

    # -- physics -----------------------------------------------------------------------------
    def felt_stiffness(self, x_mm: float, y_mm: float) -> float:
        """Stiffness under a point of the tissue frame as placed (after the scene's rotation); a 3-D tissue's is
        its force at 1 mm over 1 mm."""
        return self.field.k_at(*self._scene_xy(x_mm, y_mm))

    def _scene_xy(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """A point of the tissue frame as placed, in the scene's own frame (before its rotation)."""
        if self._rotation_deg:
            return rotate_xy(x_mm, y_mm, -self._rotation_deg)
        return x_mm, y_mm

    def _step(self, dt: float) -> None:
        q = tuple(self.arm.q)
        force = self._contact_force(q)
        self.contact_force_robot = force
        normal_n = force[1]  # the tissue's normal is the robot's y axis
        self.contact_force_n = normal_n
        if normal_n > self.max_contact_force_n:
            self.max_contact_force_n = normal_n
        if self.indentation_mm > self.max_indentation_mm:
            self.max_indentation_mm = self.indentation_mm
        tau_external = model.joint_torques(q, force) if force is not NO_FORCE else NO_FORCE
        tau_motor = model.currents_to_torques(self.currents_a) if self._amplifiers_on else NO_FORCE
        if self.hand is not None:
            self.arm.q = list(self.hand.q_at(self.t_s + dt))
        else:
            self.arm.step(dt, tau_motor, tau_external)

    def _damping_substeps(self, dt_s: float) -> int:
        """Sub-steps that keep the tissue's damping from reversing the tip within one: the velocity is explicit
        in the damping force, so a step longer than the lightest tip mass over the damping coefficient
        overshoots, and past twice that it grows. Soft tissue damped 0.01 N·s/mm at exponent 2, 5 mm in, is
        0.25 N·s/mm against 0.075 kg: 1.7 per 0.5 ms step, and the tip chattered with ±1 N that the
        max(0, ·) of the contact law rectified into a force the tissue does not have."""
        damping = self._tissue.damping_n_s_per_mm
        if not damping:
            return 1
        q = tuple(self.arm.q)
        depth_mm = -1000.0 * self.frame.from_robot(model.forward(q))[2]
        if depth_mm <= 0.0:
            return 1
        coefficient_n_s_per_m = 1000.0 * damping * depth_mm ** self._tissue.exponent
        return max(1, math.ceil(coefficient_n_s_per_m * dt_s / model.lightest_tip_mass_kg(q)))

    def _contact_force(self, q) -> model.Vec3:
        tip = self.frame.from_robot(model.forward(q))
        depth_mm = -1000.0 * tip[2]
        self.indentation_mm = max(depth_mm, 0.0)
        if depth_mm <= 0.0:
            return NO_FORCE
        vx = vy = vz = 0.0
        if self._tissue.damping_n_s_per_mm or self._tissue.friction:  # the Jacobian costs: only when it matters
            vx, vy, vz = (1000.0 * v for v in self.frame.vector_from_robot(model.tip_velocity(q, tuple(self.arm.qd))))
        if self.table is not None:
            normal_n = self.table.force_n(*self._scene_xy(1000.0 * tip[0], 1000.0 * tip[1]), depth_mm, -vz)
            normal_n += self.base.force_n(0.0, 0.0, depth_mm)
        else:
            k = self.felt_stiffness(1000.0 * tip[0], 1000.0 * tip[1])
            normal_n = hunt_crossley_n(k, self._tissue.exponent, self._tissue.damping_n_s_per_mm, depth_mm, -vz)
        normal_n += self.faults.extra_normal_force_n(1000.0 * tip[0], 1000.0 * tip[1], depth_mm)
        # The tissue drags the sliding tip along its surface; the indenter's normal response is the same moving
        # or not (a soft tissue relaxes under a smooth probe faster than it slides: no ploughing term).
        drag_x, drag_y = sliding_friction_n(normal_n, self._tissue.friction, vx, vy)
        return self.frame.vector_to_robot((drag_x, drag_y, normal_n))
