"""The per-step state a law reads: :class:`ArmState`, made by one producer
(cpbc.model.state_pass.StatePass: ``RobotModel.state``, a law's ``state``)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from cpbc.arrays import Array
from cpbc.model.frames import FrameKinematics

if TYPE_CHECKING:
    from cpbc.model.state_pass import StatePass

NO_FRAMES: Mapping[int, FrameKinematics] = MappingProxyType({})
FIELDS = ("x", "dx", "q", "dq", "inertia", "coriolis_force", "gravity", "dissipation",
          "frames", "coriolis_matrix", "joint_jacobians", "regressor")
# the fields a state from a pass takes from its terms only when each is read (StatePass.fill)
LATER = ("frames", "coriolis_matrix", "joint_jacobians", "regressor")


class ArmState:
    """Everything a law and its constraints read at one control step, computed once by
    ``RobotModel.state``: the state and the terms of D(q) q̈ + C(q, q̇) q̇ + g(q) + f(q̇) = τ
    (eq. 6.1), in controller coordinates.

    It is the only place a law, its constraints and its potential read the arm from: none of
    them reads the model's Pinocchio data behind it. A state from a pass (``StatePass``) is
    finished when it is first read: its fields are then views of one fresh array (its
    ``terms``, cpbc.kernels.state_terms), which a law's kernel reads whole; a law's kernel
    handed it unfinished finishes it itself (cpbc.kernels.laws.finished). What a reader
    needs beyond the dynamics terms it asks for when the state is built
    (``RobotModel.state``: ``kinematics``, ``frames``, ``coriolis``); the fields it did not
    ask for are None or empty.

    Attributes:
        x, dx: the state, shape (n,).
        q, dq: the same in the model's joint coordinates (the same arrays with the identity map).
        inertia: D, shape (n, n).
        coriolis_force: C(x, ẋ) ẋ, shape (n,) (from RNEA; the matrix C is
            ``RobotModel.coriolis``).
        gravity: g, shape (n,).
        dissipation: f(ẋ) = F_d ẋ + T⁻ᵀ F_c tanh(q̇/ε), shape (n,) (RobotModel.dissipation).
        frames: the placement and Jacobian of every frame asked for (``frames=`` of
            ``RobotModel.state``, e.g. those a task potential reads), by frame id; empty
            when none was asked for.
        coriolis_matrix: C(x, ẋ) in Christoffel form, shape (n, n), with ``coriolis=True``
            (the kinetic-energy limit's ∂ψ/∂x = −Cᵀẋ), else None.
        joint_jacobians: Pinocchio's world joint Jacobians J = [v; ω] (6, n) in *joint*
            coordinates, with ``kinematics=True`` (clearance), else None.
        regressor: every joint placement Y = [t_1 R_1 … t_m R_m]/M (3, 4m), Pinocchio's
            static regressor (M the total mass), with ``kinematics=True``, else None.
    """

    __slots__ = (*FIELDS, "source", "raw", "terms")
    x: Array
    dx: Array
    q: Array
    dq: Array
    inertia: Array
    coriolis_force: Array
    gravity: Array
    dissipation: Array
    frames: Mapping[int, FrameKinematics]
    coriolis_matrix: Array | None
    joint_jacobians: Array | None
    regressor: Array | None
    source: StatePass | None  # the pass it comes from (None: its fields were given)
    raw: tuple[Array, ...] | None  # the pass's arrays, until it is finished
    terms: Array | None  # its finished terms (a state from a pass)

    def __init__(self, x: Array, dx: Array, q: Array, dq: Array, inertia: Array,
                 coriolis_force: Array, gravity: Array, dissipation: Array,
                 frames: Mapping[int, FrameKinematics] = NO_FRAMES,
                 coriolis_matrix: Array | None = None, joint_jacobians: Array | None = None,
                 regressor: Array | None = None) -> None:
        self.x, self.dx, self.q, self.dq = x, dx, q, dq
        self.inertia, self.coriolis_force, self.gravity = inertia, coriolis_force, gravity
        self.dissipation, self.frames, self.coriolis_matrix = dissipation, frames, coriolis_matrix
        self.joint_jacobians, self.regressor = joint_jacobians, regressor
        self.source = self.raw = self.terms = None

    def __iter__(self) -> Iterator[Any]:
        """Its fields in order (as the tuple it was)."""
        return iter([getattr(self, name) for name in FIELDS])

    def __getattr__(self, name: str) -> Any:
        """A field of a state from a pass not read yet: taken from its terms now, the state
        finished first where it is not (StatePass.fill)."""
        if name in FIELDS:
            source = object.__getattribute__(self, "source")
            if source is not None:
                source.fill(self, name)
                return object.__getattribute__(self, name)
        raise AttributeError(name)
