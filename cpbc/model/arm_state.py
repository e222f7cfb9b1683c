"""The per-step state a law reads: :class:`ArmState`, made by ``RobotModel.state``."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import NamedTuple

from cpbc.arrays import Array
from cpbc.model.frames import FrameKinematics

NO_FRAMES: Mapping[int, FrameKinematics] = MappingProxyType({})


class ArmState(NamedTuple):
    """Everything a law and its constraints read at one control step, computed once by
    ``RobotModel.state``: the state and the terms of D(q) q̈ + C(q, q̇) q̇ + g(q) + f(q̇) = τ
    (eq. 6.1), in controller coordinates.

    It is the only place a law, its constraints and its potential read the arm from: none of
    them reads the model's Pinocchio data behind it. What a reader needs beyond the dynamics
    terms it asks for when the state is built (``RobotModel.state``: ``kinematics``,
    ``frames``, ``coriolis``); the fields it did not ask for are None or empty.

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

    x: Array
    dx: Array
    q: Array
    dq: Array
    inertia: Array
    coriolis_force: Array
    gravity: Array
    dissipation: Array
    frames: Mapping[int, FrameKinematics] = NO_FRAMES
    coriolis_matrix: Array | None = None
    joint_jacobians: Array | None = None
    regressor: Array | None = None
