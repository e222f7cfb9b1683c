"""A robot without a network: a MuJoCo plant that takes one physics step per command, adds
gravity compensation and clips to its torque box as a Franka does. Deterministic (no clock,
no thread), so the hardware runner's tests can compare two runs number for number."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ParameterError
from cpbc.hardware.backend import MeasuredState, RobotDynamics, RobotFault, RobotLimits
from cpbc.simulation.plant import MujocoPlant

JointMap = Callable[[Array], Array]


class LockstepBackend:
    """A :class:`~cpbc.hardware.backend.RobotBackend` over a MuJoCo plant.

    Args:
        plant: the arm's MuJoCo plant (its timestep must divide the period).
        joint_names: the driven joints, in the plant's order.
        limits: the torque box clipped to, the rate and velocity limits declared, and the
            period (a whole number of the plant's timesteps).
        gravity: the gravity torque the "robot" adds, from its own model (q → g(q)).
        mass: the robot's own mass matrix (q → M(q)), for the dry run's comparison.
        position: the joint positions the plant starts from [rad].
        velocity: the joint velocities it starts with [rad/s].
    """

    def __init__(self, plant: MujocoPlant, joint_names: tuple[str, ...], limits: RobotLimits,
                 gravity: JointMap, mass: JointMap, position: Array, velocity: Array) -> None:
        n = plant.n
        if len(joint_names) != n:
            raise ParameterError("joint_names", f"needs {n} names, one per joint of the plant, "
                                 f"got {len(joint_names)}")
        for name, value in (("position", position), ("velocity", velocity)):
            if np.shape(value) != (n,) or not np.all(np.isfinite(value)):
                raise ParameterError(name, f"needs {n} finite numbers, got {value!r}")
        ratio = limits.period / plant.model.opt.timestep
        if round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise ParameterError("limits", f"period {limits.period} s is not a whole multiple "
                                 f"of the plant's timestep {plant.model.opt.timestep} s")
        self._plant, self._names, self._limits = plant, joint_names, limits
        self._gravity, self._mass = gravity, mass
        self._substeps = round(ratio)
        self._cycle = 0
        self._moving = False
        self._held = np.zeros(n)
        plant.reset(np.asarray(position, dtype=float), np.asarray(velocity, dtype=float))

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self._names

    def limits(self) -> RobotLimits:
        return self._limits

    def read(self) -> MeasuredState:
        q, dq = self._plant.state()
        return MeasuredState(q, dq, self._cycle * self._limits.period, 0, self._held.copy())

    def start(self) -> MeasuredState:
        self._moving = True
        return self.read()

    def write(self, torque: Array) -> None:
        if not self._moving:
            raise RobotFault("not_moving", "a torque was written outside a motion")
        box = self._limits.torque
        q = self._plant.data.qpos
        # the robot's own additions: its torque box first, then its gravity compensation
        self._held = np.clip(torque, -box, box)
        self._plant.apply(self._held + self._gravity(q.copy()))
        self._plant.step(self._substeps)
        if self._plant.unstable():
            raise RobotFault("instability_detected", "the plant's physics went unstable",
                             self.read())
        self._cycle += 1

    def finish(self, torque: Array) -> None:
        self.write(torque)
        self._moving = False

    def added_torque(self, state: MeasuredState) -> Array:
        return self._gravity(state.position)

    def dynamics(self, state: MeasuredState) -> RobotDynamics:
        return RobotDynamics(self._mass(state.position), self._gravity(state.position))

    def close(self) -> None:
        self._moving = False
