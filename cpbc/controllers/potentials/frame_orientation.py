"""Smooth bounded orientation springs on a frame (TASKSPACE §2.2): the trace spring toward a
rotation R_d, and the axis spring "tool axis a_b points along world axis a_w" (free about it).

Both are smooth everywhere (unlike ½θ² of the log map, not differentiable at θ = π), and
their gradients are bounded, so they keep the bounded-torque laws' bounds (7.32), (7.40).
With ω = J_ω ẋ in world axes, δR = [J_ω δx]× R.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.packing import Packed
from cpbc.controllers.potentials.potential import GradientBound, OnOneFrame, Placed, frame_at
from cpbc.errors import ParameterError
from cpbc.kernels.task import (
    axis_spring,
    orientation_spring,
    pack_axis_spring,
    pack_orientation_spring,
)
from cpbc.model.frames import jacobian_bounds
from cpbc.model.robot_model import RobotModel


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise ParameterError(name, f"{name} must be finite and > 0, got {value!r}")
    return v


def _unit(value: object, name: str) -> Array:
    a = np.array(value, dtype=float)
    norm = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
    if not (np.isfinite(norm) and norm > 0):
        raise ParameterError(name, f"{name} must be a nonzero 3-vector, got {value!r}")
    a = a / norm
    a.setflags(write=False)
    return a


def _rotation(value: object) -> Array:
    r = np.array(value, dtype=float)
    if r.shape != (3, 3) or not np.allclose(r.T @ r, np.eye(3), atol=1e-9) or (
            np.linalg.det(r) <= 0):
        raise ParameterError("rotation", f"rotation must be a 3 × 3 rotation matrix, got {r}")
    r.setflags(write=False)
    return r


def _angular_reach(model: RobotModel, frame: int) -> float:
    return jacobian_bounds(model.model, model.coordinates.inverse, frame)[1]


@dataclass(frozen=True)
class FrameOrientationSpring(OnOneFrame):
    """U = k (3 − tr(R_dᵀR)) = 4k sin²(θ/2) ≤ 4k, θ the angle of R_dᵀR, with

        ∂U/∂x = k J_ωᵀ vee(R R_dᵀ − R_d Rᵀ),   ‖∂U/∂x‖ = 2k sin θ ‖·‖ ≤ 2k J̄_ω

    (from δ tr(R_dᵀR) = tr([a]× R R_dᵀ) = −aᵀ vee(M − Mᵀ), M = R R_dᵀ, a = J_ω δx).

    Attributes:
        frame: the frame id.
        rotation: R_d, the goal's axes in the world, shape (3, 3).
        stiffness: k [N·m/rad], > 0 (the small-angle stiffness is 2k).
        reach: J̄_ω ≥ ‖J_ω(x)‖₂ over every configuration (:meth:`named` computes it).
    """

    frame: int
    rotation: Array
    stiffness: float
    reach: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "rotation", _rotation(self.rotation))
        object.__setattr__(self, "stiffness", _positive(self.stiffness, "stiffness"))

    @classmethod
    def named(cls, model: RobotModel, frame: str, rotation: object, stiffness: float
              ) -> FrameOrientationSpring:
        fid = model.frame_id(frame)
        return cls(fid, np.asarray(rotation, dtype=float), stiffness, _angular_reach(model, fid))

    @property
    def gradient_bound(self) -> GradientBound:
        bound = 2.0 * self.stiffness * self.reach
        return GradientBound(bound, bound)

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        """(cpbc.kernels.task.orientation_spring)"""
        return self.evaluate_toward(at, self.rotation)

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]:
        """U and ∂U/∂x with R_d = ``goal`` in place of the spring's own (a streamed
        orientation, cpbc.reference.target)."""
        kin = frame_at(at, self.frame)
        grad = np.empty(kin.jacobian.shape[1])
        value = orientation_spring(kin.rotation, kin.jacobian, goal, self.stiffness, grad)
        return value, grad

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """R_d and k for a law's kernel, unless a subclass overrides ``evaluate``; with
        ``toward`` (3 × 3), R_d is that array, read again before each step (a streamed
        orientation: ``Packed.live``)."""
        cls = type(self)
        if cls.evaluate is not FrameOrientationSpring.evaluate or (
                cls.evaluate_toward is not FrameOrientationSpring.evaluate_toward):
            return None
        goal = self.rotation if toward is None else toward
        return (pack_orientation_spring(goal, self.stiffness, self.frame,
                                        moving=toward is not None),)


@dataclass(frozen=True)
class FrameAxisSpring(OnOneFrame):
    """U = k (1 − a_wᵀ R a_b) = k (1 − cos θ) ≤ 2k, θ the angle between the tool axis R a_b and
    the world axis a_w (the rotation about a_w is free), with

        ∂U/∂x = k J_ωᵀ (a_w × R a_b),   ‖∂U/∂x‖ ≤ k sin θ J̄_ω ≤ k J̄_ω

    (from δ(R a_b) = (J_ω δx) × R a_b).

    Attributes:
        frame: the frame id.
        tool: a_b, the axis in the frame's axes (normalised).
        world: a_w, the axis in the world (normalised).
        stiffness: k [N·m/rad], > 0.
        reach: J̄_ω (:meth:`named` computes it).
    """

    frame: int
    tool: Array
    world: Array
    stiffness: float
    reach: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "tool", _unit(self.tool, "tool"))
        object.__setattr__(self, "world", _unit(self.world, "world"))
        object.__setattr__(self, "stiffness", _positive(self.stiffness, "stiffness"))

    @classmethod
    def named(cls, model: RobotModel, frame: str, tool: object, world: object,
              stiffness: float) -> FrameAxisSpring:
        fid = model.frame_id(frame)
        return cls(fid, np.asarray(tool, dtype=float), np.asarray(world, dtype=float),
                   stiffness, _angular_reach(model, fid))

    @property
    def gradient_bound(self) -> GradientBound:
        bound = self.stiffness * self.reach
        return GradientBound(bound, bound)

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        """(cpbc.kernels.task.axis_spring)"""
        return self.evaluate_toward(at, self.world)

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]:
        """U and ∂U/∂x with a_w = ``goal`` (a unit vector) in place of the spring's own (a
        streamed orientation R_r: a_w = R_r a_b, cpbc.reference.target)."""
        kin = frame_at(at, self.frame)
        grad = np.empty(kin.jacobian.shape[1])
        value = axis_spring(kin.rotation, kin.jacobian, self.tool, goal, self.stiffness, grad)
        return value, grad

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """a_b, a_w and k for a law's kernel, unless a subclass overrides ``evaluate``; with
        ``toward``, the rows [a_b; a_w] (2 × 3) are that array, read again before each step
        (a streamed orientation R_r, a_w = R_r a_b: ``Packed.live``)."""
        cls = type(self)
        if cls.evaluate is not FrameAxisSpring.evaluate or (
                cls.evaluate_toward is not FrameAxisSpring.evaluate_toward):
            return None
        axes = np.vstack([self.tool, self.world]) if toward is None else toward
        return (pack_axis_spring(axes, self.stiffness, self.frame, moving=toward is not None),)
