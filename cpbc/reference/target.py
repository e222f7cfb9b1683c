"""The moving target a law's springs and task damping read each step, without rebuilding
the law (TASKSPACE §2.4): the frame goal p_d, the feed-forward ṗ_ff and the posture x_n.

:func:`steer` rewrites a law's task potential and task damping so that the frame position
spring reads p_d, the joint (posture) spring x_n and the damping ṗ_ff from one
:class:`MovingTarget`, whose arrays are written in place. The formulas stay in the springs
(``evaluate_toward``) and the damping (``force_with``). While the target does not move, the
law is the same law with a fixed goal: its V̇ identity holds unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.packing import Packed
from cpbc.controllers.controller import Controller
from cpbc.controllers.pd import PDGravity
from cpbc.controllers.potentials import (
    FrameAxisSpring,
    FrameOrientationSpring,
    FramePositionLogCosh,
    FramePositionSpring,
    GradientBound,
    JointLogCoshSpring,
    JointSpring,
    Placed,
    Potential,
    PotentialSum,
)
from cpbc.controllers.task_damping import TaskDamping, TaskTanhDamping
from cpbc.controllers.terms import LinearDamping
from cpbc.errors import CpbcError
from cpbc.kernels.law_terms import joint_feedforward, pack_joint_feedforward


class MovingTarget:
    """The applied reference: ``position`` p_d (3,), ``velocity`` ṗ_ff (3,),
    ``angular_velocity`` ω_ff (3,) (world axes; the two are the halves of ``twist``
    [ṗ_ff; ω_ff], which the task damping reads), ``posture`` x_n (n,) and its feed-forward
    ``posture_velocity`` ẋ_n,ff (n,), written in place by :meth:`set`; and ``rotation``
    R_d (3, 3), written in place by :meth:`turn`, once a streamed orientation steers the
    law's orientation spring (None before), with ``axes`` [a_b; R_d a_b] (2, 3) when it
    steers an axis spring of tool axis a_b (None otherwise)."""

    def __init__(self, position: Array, posture: Array) -> None:
        self.position = np.array(position, dtype=float)
        self.twist = np.zeros(6)
        self.velocity, self.angular_velocity = self.twist[:3], self.twist[3:]
        self.posture = np.array(posture, dtype=float)
        self.posture_velocity = np.zeros_like(self.posture)
        self.rotation: Array | None = None
        self.axes: Array | None = None
        self._fed = self._posture_fed = False  # a feed-forward is nonzero (set by set)

    @property
    def fed(self) -> bool:
        """Whether a feed-forward (ṗ_ff, ω_ff or ẋ_n,ff) was last set nonzero."""
        return self._fed or self._posture_fed

    def set(self, position: Array, velocity: Array | None = None,
            posture: Array | None = None, posture_velocity: Array | None = None,
            angular_velocity: Array | None = None) -> None:
        """Move the target (velocities to zero when not given; the posture kept). A zero
        feed-forward is written once, not at every step (the tracker's hot path)."""
        self.position[:] = position
        fed = velocity is not None or angular_velocity is not None
        if fed or self._fed:
            self.velocity[:] = 0.0 if velocity is None else velocity
            self.angular_velocity[:] = 0.0 if angular_velocity is None else angular_velocity
            self._fed = fed
        if posture is not None:
            self.posture[:] = posture
        if posture_velocity is not None or self._posture_fed:
            self.posture_velocity[:] = 0.0 if posture_velocity is None else posture_velocity
            self._posture_fed = posture_velocity is not None

    def orient(self, rotation: Array, tool: Array | None = None) -> None:
        """Give the target an orientation R_d = ``rotation`` (new arrays: a law steered
        after this reads them), and with ``tool`` a_b the axes [a_b; R_d a_b] too."""
        self.rotation = np.array(rotation, dtype=float)
        self.axes = None if tool is None else np.vstack([tool, self.rotation @ tool])

    def turn(self, rotation: Array) -> None:
        """Turn the target's orientation to ``rotation`` (in place, with its axes)."""
        assert self.rotation is not None  # oriented first
        self.rotation[:] = rotation
        if self.axes is not None:
            self.axes[1] = self.rotation @ self.axes[0]


class _Steerable(Protocol):
    @property
    def frames(self) -> tuple[int, ...]: ...

    @property
    def anchored(self) -> bool: ...

    @property
    def gradient_bound(self) -> GradientBound | None: ...

    def evaluate(self, at: Placed) -> tuple[float, Array]: ...

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]: ...


@dataclass(frozen=True)
class Steered:
    """A spring whose goal is the target's ``position`` (a frame spring), ``posture`` (a
    joint spring), ``rotation`` (an orientation spring) or the ``axis`` R_d a_b of its
    rotation (an axis spring, which leaves the rotation about that axis free)."""

    spring: _Steerable
    target: MovingTarget
    reads: str

    @property
    def frames(self) -> tuple[int, ...]:
        return self.spring.frames

    @property
    def anchored(self) -> bool:
        return self.spring.anchored

    @property
    def gradient_bound(self) -> GradientBound | None:
        return self.spring.gradient_bound

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        return self.spring.evaluate_toward(at, self._goal)

    @property
    def _goal(self) -> Array:
        if self.reads == "position":
            return self.target.position
        if self.reads == "posture":
            return self.target.posture
        rotation = self.target.rotation
        assert rotation is not None  # steered only once the target has one
        return rotation if self.reads == "rotation" else rotation @ self.spring.tool  # type: ignore[attr-defined]

    def packed(self) -> tuple[Packed, ...] | None:
        """The spring's terms for a law's kernel with its goal read from the target before
        each step (``Packed.live``), unless the spring does not pack: an axis spring reads
        the target's ``axes`` (which :meth:`MovingTarget.turn` keeps at R_d a_b), and takes
        the general path when they are another tool axis's."""
        packed = getattr(self.spring, "packed", None)
        if packed is None:
            return None
        if self.reads == "axis":
            axes = self.target.axes
            if axes is None or not np.array_equal(axes[0], self.spring.tool):  # type: ignore[attr-defined]
                return None
            return packed(toward=axes)
        return packed(toward=self._goal)


@dataclass(frozen=True)
class SteeredDamping:
    """Task damping whose feed-forward is the target's ``twist`` [ṗ_ff; ω_ff] (its
    ``velocity`` ṗ_ff for tanh damping, which damps no rotation), less K_D ẋ_n,ff when the
    law's joint damping ``joint`` K_D is linear (module docstring)."""

    damping: TaskDamping | TaskTanhDamping
    target: MovingTarget
    joint: Array | None = None

    @property
    def frames(self) -> tuple[int, ...]:
        return self.damping.frames

    @property
    def force_bound(self) -> float | None:
        return self.damping.force_bound

    @property
    def _feedforward(self) -> Array:
        target = self.target
        return target.twist if isinstance(self.damping, TaskDamping) else target.velocity

    def force(self, at: Placed, dx: Array) -> Array:
        force = self.damping.force_with(at, dx, self._feedforward)
        if self.joint is None:
            return force
        share = np.empty(force.shape[0])
        joint_feedforward(self.joint, self.target.posture_velocity, share)
        return force + share

    def packed(self) -> tuple[Packed, ...] | None:
        """The damping's terms for a law's kernel with the feed-forward read from the target
        before each step (``Packed.live``), and the joint feed-forward's; None when the damping
        does not pack."""
        found = self.damping.packed(toward=self._feedforward)
        if found is None or self.joint is None:
            return found
        return (*found, pack_joint_feedforward(self.joint, self.target.posture_velocity))


@runtime_checkable
class Follower(Protocol):
    """A controller whose nominal reads the target itself (the CBF-QP peer's
    operational-space nominal, cpbc.peers.osc), with no spring to steer."""

    def follow(self, target: MovingTarget) -> None: ...


def _steer_part(part: Potential, target: MovingTarget) -> Potential:
    if isinstance(part, Steered):  # steered before (an earlier run): to the new target
        if part.reads in ("rotation", "axis") and target.rotation is None:
            return part.spring  # its own goal again: the new target streams no orientation
        return Steered(part.spring, target, part.reads)
    if isinstance(part, FramePositionSpring | FramePositionLogCosh):
        return Steered(part, target, "position")
    if isinstance(part, JointSpring | JointLogCoshSpring):
        return Steered(part, target, "posture")
    if target.rotation is not None and isinstance(part, FrameOrientationSpring):
        return Steered(part, target, "rotation")
    if target.rotation is not None and isinstance(part, FrameAxisSpring):
        return Steered(part, target, "axis")
    return part


def steer(law: Controller, target: MovingTarget) -> Controller:
    """Make ``law`` read its frame goal, posture and feed-forward (and, once ``target`` has a
    rotation, its orientation or axis goal) from ``target`` (in place;
    the law is returned; a law steered before reads the new target). The law needs a task
    potential (a sum with one frame position spring) and, for the feed-forward, task
    damping. A :class:`Follower` is handed the target instead."""
    if isinstance(law, Follower):
        law.follow(target)
        return law
    potential = law.potential
    parts = potential.parts if isinstance(potential, PotentialSum) else (
        () if potential is None else (potential,))
    steered = tuple(_steer_part(p, target) for p in parts)
    if sum(isinstance(p, Steered) and p.reads == "position" for p in steered) != 1:
        raise CpbcError(f"{law.type_name}: a moving reference needs a task potential with "
                        "exactly one frame position spring (build the law for a goal)")
    law.potential = PotentialSum(steered)
    damping = law.task_damping
    if isinstance(damping, SteeredDamping):
        law.task_damping = SteeredDamping(damping.damping, target, damping.joint)
    elif isinstance(damping, TaskDamping | TaskTanhDamping):
        linear = isinstance(getattr(law, "damping", None), LinearDamping) or isinstance(
            law, PDGravity)
        law.task_damping = SteeredDamping(damping, target, law.kd if linear else None)  # type: ignore[attr-defined]
    return law
