"""What cpbc needs of a torque-controlled arm: the :class:`RobotBackend` protocol, the
measured state it reads, the limits it declares and the faults it raises.

A backend speaks in the robot's *commanded* convention: the torque written is the one the
robot adds its own torque to (on a Franka, gravity compensation), and
:meth:`RobotBackend.added_torque` says what that addition is at a state, so that the runner
commands τ_d = τ − (what the robot adds). The next torque-controlled arm is one more module
that implements this protocol.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import CpbcError, ParameterError
from cpbc.model.velocity_limits import PositionDependentVelocity


@dataclass(frozen=True)
class MeasuredState:
    """One state as the robot reports it.

    Attributes:
        position, velocity: q [rad], q̇ [rad/s], shape (n,).
        time: the robot's clock [s] (its own, not this computer's).
        lost: control cycles the robot ran since the previous state was read, beyond the
            one expected (states this controller never saw; 0 in lock-step).
        held: the command the robot holds (commanded convention) [N·m], or None when it
            does not say: where a rate-limited first command starts from.
    """

    position: Array
    velocity: Array
    time: float
    lost: int = 0
    held: Array | None = None


@dataclass(frozen=True)
class RobotLimits:
    """The robot's own rules for a torque command (commanded convention, per joint).

    Attributes:
        torque: |τ_d,i| ≤ torque_i [N·m]; the robot clips beyond.
        torque_rate: |τ_d,i(k) − τ_d,i(k−1)| ≤ torque_rate_i · period [N·m/s]; a real
            Franka aborts the motion beyond (a simulator may not check it).
        velocity: |q̇_i| ≤ velocity_i [rad/s].
        period: the robot's control period [s].
        velocity_limits: the robot's position-dependent velocity limits L(q) ≤ q̇ ≤ U(q)
            (a Franka aborts beyond: ``joint_velocity_violation``), or None.
    """

    torque: Array
    torque_rate: Array
    velocity: Array
    period: float
    velocity_limits: PositionDependentVelocity | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.period) and self.period > 0):
            raise ParameterError("period", f"must be a number > 0 [s], got {self.period}")
        n = np.shape(self.torque)
        for name in ("torque", "torque_rate", "velocity"):
            value = np.array(getattr(self, name), dtype=float)
            if value.shape != n or value.ndim != 1 or not np.all(value > 0):
                raise ParameterError(name, f"needs one number > 0 per joint ({n[0] if n else 0}"
                                     f" like torque), got {getattr(self, name)!r}")
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        if self.velocity_limits is not None and self.velocity_limits.n != n[0]:
            raise ParameterError("velocity_limits", f"has {self.velocity_limits.n} joints, "
                                 f"the robot {n[0]}")

    @property
    def torque_step(self) -> Array:
        """The largest change of a joint's command in one cycle [N·m]."""
        return np.asarray(self.torque_rate * self.period)


@dataclass(frozen=True)
class RobotDynamics:
    """The robot's own model at a state: mass matrix M(q) and gravity torque g(q)."""

    mass: Array
    gravity: Array


class RobotFault(CpbcError):
    """The robot ended the motion on its own: a reflex, a lost connection, a refused command.

    Attributes:
        name: the robot's name for it (``communication_constraints_violation``,
            ``network``, …).
        state: the last state read before it, or None when none was.
    """

    def __init__(self, name: str, detail: str, state: MeasuredState | None = None) -> None:
        self.name = name
        self.detail = detail
        self.state = state
        super().__init__(f"robot error {name}: {detail}")


class RobotBackend(Protocol):
    """A torque-controlled arm, driven one control cycle at a time.

    Outside a motion, :meth:`read` returns the current state. :meth:`start` begins torque
    control and returns the first state of the motion; then each cycle is one
    :meth:`write` followed by one :meth:`read` (which waits for the robot's next cycle);
    :meth:`finish` sends the last command and ends the motion. Every method may raise
    :class:`RobotFault`.
    """

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The robot's joints, in the order of its states and commands."""

    def limits(self) -> RobotLimits:
        """The robot's rules for a command."""

    def read(self) -> MeasuredState:
        """The current state (outside a motion), or the next cycle's (inside one)."""

    def start(self) -> MeasuredState:
        """Begin torque control; the motion's first state."""

    def write(self, torque: Array) -> None:
        """Command τ_d (commanded convention) for the cycle of the last state read."""

    def finish(self, torque: Array) -> None:
        """Command τ_d as the motion's last command and end the motion."""

    def added_torque(self, state: MeasuredState) -> Array:
        """What the robot adds to every command at this state (a Franka: gravity)."""

    def dynamics(self, state: MeasuredState) -> RobotDynamics:
        """The robot's own mass matrix and gravity at this state."""

    def close(self) -> None:
        """Release the connection (idempotent)."""
