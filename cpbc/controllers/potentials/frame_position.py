"""Position springs on a point fixed in a frame, e = p(x) − p_d (TASKSPACE §2.2):
quadratic, and a bounded ln cosh variant for the bounded-torque laws."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.packing import Packed
from cpbc.controllers.controller import positive_vector, vector3
from cpbc.controllers.potentials.log_cosh import LogCoshSum
from cpbc.controllers.potentials.potential import GradientBound, OnOneFrame, Placed, frame_at
from cpbc.errors import ParameterError
from cpbc.kernels.law_terms import pack_position_log_cosh, position_log_cosh
from cpbc.kernels.task import pack_position_spring, position_spring
from cpbc.model.frames import jacobian_bounds
from cpbc.model.robot_model import RobotModel


def point_offset(offset: Array | None) -> Array:
    """A point's offset in its frame as the task kernels read it, [o has_offset] (4,)."""
    out = np.zeros(4) if offset is None else np.append(offset, 1.0)
    out.setflags(write=False)
    return out


def _stiffness_matrix(value: object) -> Array:
    """K as a symmetric positive definite 3 × 3 matrix (a number or 3 numbers: diagonal)."""
    a = np.array(value, dtype=float)
    k = np.diag(positive_vector(a, 3, "stiffness")) if a.ndim < 2 else a
    if k.shape != (3, 3) or not np.all(np.isfinite(k)) or not np.allclose(k, k.T) or (
            np.linalg.eigvalsh(k).min() <= 0):
        raise ParameterError(
            "stiffness", "stiffness must be > 0: a number, 3 numbers or a symmetric positive "
            f"definite 3 × 3 matrix, got {value!r}")
    k.setflags(write=False)
    return k


@dataclass(frozen=True)
class FramePositionSpring(OnOneFrame):
    """U = ½ eᵀ K e, e = p(x) − p_d, ∂U/∂x = J_vᵀ K e (Takegaki–Arimoto's spring).

    Attributes:
        frame: the frame id (:meth:`RobotModel.frame_id`).
        goal: p_d in the world, shape (3,) [m].
        stiffness: K [N/m]: a number, 3 numbers (diagonal, world axes) or an SPD 3 × 3 matrix.
        offset: the point in the frame's axes (None: the frame's origin) [m].
    """

    frame: int
    goal: Array
    stiffness: Array
    offset: Array | None = None
    _point: Array = field(init=False, repr=False, compare=False)  # the kernel's [o has]

    def __post_init__(self) -> None:
        object.__setattr__(self, "goal", vector3(self.goal, "goal"))
        object.__setattr__(self, "stiffness", _stiffness_matrix(self.stiffness))
        if self.offset is not None:
            object.__setattr__(self, "offset", vector3(self.offset, "offset"))
        object.__setattr__(self, "_point", point_offset(self.offset))

    @classmethod
    def named(cls, model: RobotModel, frame: str, goal: object, stiffness: object,
              offset: object = None) -> FramePositionSpring:
        """The spring on the frame named ``frame`` of ``model``."""
        return cls(model.frame_id(frame), np.asarray(goal, dtype=float),
                   np.asarray(stiffness, dtype=float),
                   None if offset is None else np.asarray(offset, dtype=float))

    @property
    def gradient_bound(self) -> GradientBound | None:
        return None

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        return self.evaluate_toward(at, self.goal)

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]:
        """U and ∂U/∂x with the goal p_d = ``goal`` in place of the spring's own (a moving
        reference, cpbc.reference.target) (cpbc.kernels.task.position_spring)."""
        kin = frame_at(at, self.frame)
        grad = np.empty(kin.jacobian.shape[1])
        value = position_spring(kin.position, kin.rotation, kin.jacobian, self._point, goal,
                                self.stiffness, grad)
        return value, grad

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """The point, p_d and K for a law's kernel (cpbc.kernels.law_terms), unless a
        subclass overrides ``evaluate`` or ``evaluate_toward``; with ``toward``, p_d is that
        array, read again before each step (a moving reference: ``Packed.live``)."""
        cls = type(self)
        if cls.evaluate is not FramePositionSpring.evaluate or (
                cls.evaluate_toward is not FramePositionSpring.evaluate_toward):
            return None
        goal = self.goal if toward is None else toward
        return (pack_position_spring(self._point, goal, self.stiffness, self.frame,
                                     moving=toward is not None),)


@dataclass(frozen=True)
class FramePositionLogCosh(OnOneFrame):
    """U = Σ (K_i/ξ_i) ln cosh(ξ_i e_i) per world axis, e = p(x) − p_d (the ln cosh of
    eq. 7.18 on the position error), ∂U/∂x = J_vᵀ K tanh(Ξe).

    ‖∂U/∂x‖₂ ≤ J̄_v ‖diag K‖₂, with J̄_v ≥ ‖J_v(x)‖₂ over every configuration
    (:func:`cpbc.model.frames.jacobian_bounds`, from the chain's geometry).

    Attributes:
        frame, goal, offset: as :class:`FramePositionSpring`.
        stiffness: K [N/m], a number or 3 numbers (world axes), > 0.
        xi: ξ [1/m], a number or 3 numbers, > 0: the force saturates at K beyond |e| ≫ 1/ξ.
        reach: J̄_v, the Jacobian bound (:meth:`named` computes it).
    """

    frame: int
    goal: Array
    stiffness: Array
    xi: Array
    reach: float
    offset: Array | None = None
    _point: Array = field(init=False, repr=False, compare=False)  # the kernel's [o has]
    _gains: Array = field(init=False, repr=False, compare=False)  # [K; ξ; K/ξ] (3, 3)
    _log_offset: float = field(init=False, repr=False, compare=False)  # Σ K_i/ξ_i · ln 2

    def __post_init__(self) -> None:
        stiffness = positive_vector(self.stiffness, 3, "stiffness")
        xi = positive_vector(self.xi, 3, "xi")
        object.__setattr__(self, "goal", vector3(self.goal, "goal"))
        object.__setattr__(self, "stiffness", stiffness)
        object.__setattr__(self, "xi", xi)
        if self.offset is not None:
            object.__setattr__(self, "offset", vector3(self.offset, "offset"))
        object.__setattr__(self, "_point", point_offset(self.offset))
        gains, log_offset = LogCoshSum(stiffness, xi).tables()
        gains.setflags(write=False)
        object.__setattr__(self, "_gains", gains)
        object.__setattr__(self, "_log_offset", float(log_offset[0, 0]))

    @classmethod
    def named(cls, model: RobotModel, frame: str, goal: object, stiffness: object,
              xi: object, offset: object = None) -> FramePositionLogCosh:
        """The spring on the frame named ``frame`` of ``model``, with its Jacobian bound."""
        fid = model.frame_id(frame)
        point = None if offset is None else vector3(offset, "offset")
        reach, _ = jacobian_bounds(model.model, model.coordinates.inverse, fid, point)
        return cls(fid, np.asarray(goal, dtype=float), np.asarray(stiffness, dtype=float),
                   np.asarray(xi, dtype=float), reach, point)

    @property
    def gradient_bound(self) -> GradientBound:
        bound = self.reach * float(np.linalg.norm(self.stiffness))
        return GradientBound(bound, bound)

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        return self.evaluate_toward(at, self.goal)

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]:
        """U and ∂U/∂x toward ``goal`` in place of the spring's own
        (cpbc.kernels.law_terms.position_log_cosh)."""
        kin = frame_at(at, self.frame)
        grad = np.empty(kin.jacobian.shape[1])
        value = position_log_cosh(kin.position, kin.rotation, kin.jacobian, self._point, goal,
                                  self._gains, self._log_offset, grad)
        return value, grad

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """The point, p_d, [K; ξ; K/ξ] and Σ K_i/ξ_i · ln 2 for a law's kernel
        (cpbc.kernels.law_terms), unless a subclass overrides ``evaluate`` or
        ``evaluate_toward``; ``toward`` as :meth:`FramePositionSpring.packed`."""
        cls = type(self)
        if cls.evaluate is not FramePositionLogCosh.evaluate or (
                cls.evaluate_toward is not FramePositionLogCosh.evaluate_toward):
            return None
        goal = self.goal if toward is None else toward
        return (pack_position_log_cosh(self._point, goal, self._gains, self._log_offset,
                                       self.frame, moving=toward is not None),)
