"""Task-space damping on a point of a frame (TASKSPACE §2.2):

    F(x, ẋ) = J_vᵀ D_x (J_v ẋ − ṗ_ff)                    (quadratic, CPBC, CPBC-KE, PD + g)
    F(x, ẋ) = J_vᵀ D_x tanh(Γ_x (J_v ẋ − ṗ_ff))           (bounded, BPBC, BPBC-KE)

added to the joint damping of a law: a = −∂U/∂x − K_D ẋ − F + ρ(b_φ + b_ψ). With the
feed-forward ṗ_ff = 0 (a fixed goal) ẋᵀF = (J_vẋ)ᵀD_x(J_vẋ) ≥ 0 (or Σ D_i v_i tanh(Γ_i v_i) ≥ 0),
so each law keeps its V̇ identity with K_D ẋ replaced by K_D ẋ + F (Claim A: any damping with
ẋᵀF ≥ 0). A nonzero ṗ_ff (a moving reference) makes ẋᵀF sign-indefinite: that case is paid for
by the reference governor (§2.4), not here.

The bounded form is bounded by J̄_v ‖diag D_x‖₂, J̄_v ≥ ‖J_v(x)‖₂ over every configuration
(:func:`cpbc.model.frames.jacobian_bounds`), so BPBC's torque bound (7.32) keeps holding with
that term added.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.packing import Packed
from cpbc.controllers.controller import positive_vector, vector3
from cpbc.controllers.potentials.frame_position import point_offset
from cpbc.controllers.potentials.potential import Placed, frame_at
from cpbc.errors import ParameterError
from cpbc.kernels.task import (
    pack_task_damping,
    pack_task_tanh_damping,
    task_damping,
    task_tanh_damping,
)
from cpbc.model.frames import jacobian_bounds
from cpbc.model.robot_model import RobotModel

ZERO3 = np.zeros(3)
ZERO3.setflags(write=False)


def _gain_matrix(value: object) -> Array:
    """D_x ⪰ 0 as a symmetric 3 × 3 matrix (a number or 3 numbers: diagonal)."""
    a = np.array(value, dtype=float)
    d = np.diag(np.broadcast_to(a, (3,))) if a.ndim < 2 else a
    if d.shape != (3, 3) or not np.all(np.isfinite(d)) or not np.allclose(d, d.T) or (
            np.linalg.eigvalsh(d).min() < 0):
        raise ParameterError(
            "task damping", "the task damping D_x must be ≥ 0: a number, 3 numbers or a "
            f"symmetric positive semidefinite 3 × 3 matrix, got {value!r}")
    d = d.copy()
    d.setflags(write=False)
    return d


@dataclass(frozen=True)
class TaskDamping:
    """F = J_vᵀ D_x (J_v ẋ − ṗ_ff) + J_ωᵀ D_ω J_ω ẋ on the point ``offset`` of ``frame``
    (module docstring; the angular term damps the frame's rotation, ẋᵀ of it is ωᵀD_ωω ≥ 0).

    Attributes:
        frame: the frame id.
        gain: D_x [N·s/m], symmetric positive semidefinite 3 × 3 (world axes).
        offset: the point in the frame's axes (None: the frame's origin) [m].
        feedforward: ṗ_ff [m/s], world axes; zero for a fixed goal.
        angular: D_ω [N·m·s/rad], symmetric positive semidefinite 3 × 3 (a number: d_ω I);
            an axis goal damps only the rotation across its axis, (I − a aᵀ) d_ω, leaving
            the free yaw to the posture spring and joint damping.
    """

    frame: int
    gain: Array
    offset: Array | None = None
    feedforward: Array = field(default_factory=lambda: ZERO3)
    angular: Array | float = 0.0
    _gain6: Array = field(init=False, repr=False, compare=False)
    _point: Array = field(init=False, repr=False, compare=False)  # the kernel's [o has]

    def __post_init__(self) -> None:
        object.__setattr__(self, "gain", _gain_matrix(self.gain))
        object.__setattr__(self, "angular", _gain_matrix(self.angular))
        # F = Jᵀ(G J ẋ − b) with J = [J_v; J_ω], G = diag(D_x, D_ω), b = G [ṗ_ff; 0]
        gain6 = np.zeros((6, 6))
        gain6[:3, :3], gain6[3:, 3:] = self.gain, self.angular
        object.__setattr__(self, "_gain6", gain6)
        object.__setattr__(self, "feedforward", vector3(self.feedforward, "feedforward"))
        if self.offset is not None:
            object.__setattr__(self, "offset", vector3(self.offset, "offset"))
        object.__setattr__(self, "_point", point_offset(self.offset))

    @property
    def frames(self) -> tuple[int, ...]:
        return (self.frame,)

    @property
    def force_bound(self) -> float | None:
        """sup ‖F‖₂: none (it grows with ẋ)."""
        return None

    def force(self, at: Placed, dx: Array) -> Array:
        """F, shape (n,), at a state holding the frame."""
        return self.force_with(at, dx, self.feedforward)

    def force_with(self, at: Placed, dx: Array, feedforward: Array) -> Array:
        """F with the feed-forward ṗ_ff = ``feedforward`` in place of the damping's own (a
        moving reference, cpbc.reference.target), or [ṗ_ff; ω_ff] (6,) with an angular
        one: F = J_vᵀ D_x (J_v ẋ − ṗ_ff) + J_ωᵀ D_ω (J_ω ẋ − ω_ff)
        (cpbc.kernels.task.task_damping)."""
        kin = frame_at(at, self.frame)
        force = np.empty(dx.shape[0])
        task_damping(kin.position, kin.rotation, kin.jacobian, self._point, self._gain6,
                     feedforward, dx, force)
        return force

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """The point, G and ṗ_ff for a law's kernel (cpbc.kernels.law_terms), unless a
        subclass overrides ``force`` or ``force_with``; with ``toward``, ṗ_ff (or
        [ṗ_ff; ω_ff]) is that array, read again before each step (a moving reference:
        ``Packed.live``)."""
        cls = type(self)
        if cls.force is not TaskDamping.force or cls.force_with is not TaskDamping.force_with:
            return None
        feedforward = self.feedforward if toward is None else toward
        return (pack_task_damping(self._point, self._gain6, feedforward, self.frame,
                                  moving=toward is not None),)


@dataclass(frozen=True)
class TaskTanhDamping:
    """F = J_vᵀ D_x tanh(Γ_x (J_v ẋ − ṗ_ff)), diagonal D_x, Γ_x (world axes), bounded by
    J̄_v ‖diag D_x‖₂ (module docstring).

    Attributes:
        frame, offset, feedforward: as :class:`TaskDamping`.
        gain: diag D_x [N], 3 numbers > 0: the force saturates at D_x.
        gamma: diag Γ_x [s/m], 3 numbers > 0 (the slope at zero is D_x Γ_x).
        reach: J̄_v (:meth:`named` computes it).
    """

    frame: int
    gain: Array
    gamma: Array
    reach: float
    offset: Array | None = None
    feedforward: Array = field(default_factory=lambda: ZERO3)
    _point: Array = field(init=False, repr=False, compare=False)  # the kernel's [o has]
    _gains: Array = field(init=False, repr=False, compare=False)  # [D_x; Γ_x] (2, 3)

    def __post_init__(self) -> None:
        object.__setattr__(self, "gain", positive_vector(self.gain, 3, "task damping"))
        object.__setattr__(self, "gamma", positive_vector(self.gamma, 3, "task gamma"))
        object.__setattr__(self, "feedforward", vector3(self.feedforward, "feedforward"))
        if self.offset is not None:
            object.__setattr__(self, "offset", vector3(self.offset, "offset"))
        object.__setattr__(self, "_point", point_offset(self.offset))
        gains = np.vstack([self.gain, self.gamma])
        gains.setflags(write=False)
        object.__setattr__(self, "_gains", gains)

    @classmethod
    def named(cls, model: RobotModel, frame: str, gain: object, gamma: object,
              offset: object = None) -> TaskTanhDamping:
        """The damping on the frame named ``frame``, with its Jacobian bound."""
        fid = model.frame_id(frame)
        point = None if offset is None else vector3(offset, "offset")
        reach, _ = jacobian_bounds(model.model, model.coordinates.inverse, fid, point)
        return cls(fid, np.asarray(gain, dtype=float), np.asarray(gamma, dtype=float),
                   reach, point)

    @property
    def frames(self) -> tuple[int, ...]:
        return (self.frame,)

    @property
    def force_bound(self) -> float:
        return self.reach * float(np.linalg.norm(self.gain))

    def force(self, at: Placed, dx: Array) -> Array:
        return self.force_with(at, dx, self.feedforward)

    def force_with(self, at: Placed, dx: Array, feedforward: Array) -> Array:
        """F with ṗ_ff = ``feedforward`` in place of the damping's own
        (cpbc.kernels.task.task_tanh_damping)."""
        kin = frame_at(at, self.frame)
        force = np.empty(dx.shape[0])
        task_tanh_damping(kin.position, kin.rotation, kin.jacobian, self._point, self._gains,
                          feedforward, dx, force)
        return force

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """The point, [D_x; Γ_x] and ṗ_ff for a law's kernel (cpbc.kernels.law_terms),
        unless a subclass overrides ``force`` or ``force_with``; ``toward`` as
        :meth:`TaskDamping.packed`."""
        cls = type(self)
        if cls.force is not TaskTanhDamping.force or (
                cls.force_with is not TaskTanhDamping.force_with):
            return None
        feedforward = self.feedforward if toward is None else toward
        return (pack_task_tanh_damping(self._point, self._gains, feedforward, self.frame,
                                       moving=toward is not None),)
