"""The potential U(x) ≥ 0 of a law's L = ½ẋᵀDẋ + U, read from the per-step state.

Theorem 6.9 (eqs. 6.26–6.32) uses U only through U ≥ 0 and ∂U/∂x, so any C¹ potential keeps
the arm in S provided U > 0 on ∂S (TASKSPACE §2.2, Claim A). A joint spring toward a point
inside S gives that; a frame spring alone does not (on a redundant arm it vanishes on a whole
self-motion manifold, which may touch ∂S). So a law refuses a potential that has no posture
spring with K_n ≻ 0 (:func:`require_posture`).

Potentials are evaluated on anything with ``x`` and ``frames`` (:class:`Placed`): the law's
per-step :class:`~cpbc.model.robot_model.ArmState`, whose ``frames`` hold every frame the
potential declared in ``frames``, from the state's one kinematics pass.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import NamedTuple, Protocol

from cpbc.arrays import Array
from cpbc.errors import CpbcError
from cpbc.model.frames import FrameKinematics

NO_FRAMES: Mapping[int, FrameKinematics] = MappingProxyType({})


class Placed(Protocol):
    """What a potential reads: the configuration and the frames it asked for."""

    @property
    def x(self) -> Array: ...

    @property
    def frames(self) -> Mapping[int, FrameKinematics]: ...


class Configuration(NamedTuple):
    """A configuration without kinematics, for potentials that read no frame."""

    x: Array
    frames: Mapping[int, FrameKinematics] = NO_FRAMES



class OfTheJoints:
    """A spring on the joint configuration alone: it reads no frame, and (stiff in every
    coordinate) it anchors the posture — the joint set-point springs."""

    @property
    def frames(self) -> tuple[int, ...]:
        return ()

    @property
    def anchored(self) -> bool:
        return True


class OnOneFrame:
    """A task term read from one frame of the per-step state (``frame``), which never anchors
    the posture: the frame springs."""

    frame: int

    @property
    def frames(self) -> tuple[int, ...]:
        return (self.frame,)

    @property
    def anchored(self) -> bool:
        return False

@dataclass(frozen=True)
class GradientBound:
    """sup ‖∂U/∂x‖₂ over every configuration, for the torque bounds (7.32) and (7.40).

    Attributes:
        norm: a proven bound (‖diag K‖₂ for a joint ln cosh spring).
        stated: the same in the thesis's form (λmax(K) for a joint ln cosh spring, which
            ‖K tanh(Ξx̃)‖ exceeds when several entries saturate together); equal to ``norm``
            for the other springs.
    """

    norm: float
    stated: float

    def __add__(self, other: GradientBound) -> GradientBound:
        return GradientBound(self.norm + other.norm, self.stated + other.stated)


class Potential(Protocol):
    """U(x) ≥ 0 and ∂U/∂x in controller coordinates."""

    @property
    def frames(self) -> tuple[int, ...]:
        """The frame ids whose kinematics ``evaluate`` reads from the state."""
        ...

    @property
    def anchored(self) -> bool:
        """Whether U contains a joint (posture) spring with K ≻ 0, so that U > 0 on ∂S
        whenever its set point is inside S."""
        ...

    @property
    def gradient_bound(self) -> GradientBound | None:
        """sup ‖∂U/∂x‖₂, or None when it is unbounded (quadratic springs)."""
        ...

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        """U and ∂U/∂x, shape (n,), at a state."""
        ...


def frame_at(at: Placed, frame_id: int) -> FrameKinematics:
    """The frame's kinematics held by the state, or a clear error when it was not asked for."""
    try:
        return at.frames[frame_id]
    except KeyError:
        raise CpbcError(
            f"the state holds no kinematics of frame {frame_id}: build it with the law's "
            "state(x, dx) (RobotModel.state(..., frames=potential.frames))"
        ) from None


def require_posture(potential: Potential, law: str) -> Potential:
    """The potential, if it has a posture spring; else a CpbcError saying why one is needed."""
    if not potential.anchored:
        raise CpbcError(
            f"{law}: the potential has no posture spring. Add a joint spring toward a posture "
            "x_n inside S with K_n > 0 on every joint (JointSpring or JointLogCoshSpring): "
            "without it U can vanish on the boundary of S (a redundant arm's whole "
            "self-motion manifold of the goal), and V = L/s(ΦΨ) no longer keeps the arm inside"
        )
    return potential


def require_bounded(potential: Potential, law: str) -> GradientBound:
    """The potential's gradient bound, or a CpbcError when it has none (a bounded-torque law's
    bound (7.32)/(7.40) needs bounded springs)."""
    bound = potential.gradient_bound
    if bound is None or not math.isfinite(bound.norm):
        raise CpbcError(
            f"{law}: its torque bound needs a potential with a bounded gradient; use the "
            "ln cosh springs (JointLogCoshSpring, FramePositionLogCosh) and the orientation "
            "springs, not the quadratic ones"
        )
    return bound
