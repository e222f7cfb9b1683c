"""The task-space terms on a frame of the per-step state (TASKSPACE §2.2): the point of a
frame and its Jacobian, the position spring, the orientation springs and the task damping,
quadratic and bounded (cpbc.controllers.potentials, cpbc.controllers.task_damping: their
Python methods call these; the ln cosh position spring, which reads the joint ln cosh sum,
is in cpbc.kernels.law_terms).

A frame arrives as its origin (3,), axes R (3, 3) and Jacobian [J_v; J_ω] (6, n) in world
axes (cpbc.model.frames.FrameKinematics); a point fixed in it as ``offset`` = [o has_offset]
(4,), o in the frame's axes.

Beside each term: its kind's code in a law's plan (cpbc.kernels.law_terms' registry), its
tables (``pack_*``, cpbc.kernels.tables; a ``moving`` goal or feed-forward is read again
from its array before each step, ``Packed.live``) and its row reader (``*_row``).
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel
from cpbc.kernels.tables import Ints, Packed, float_table

FRAME = f"{READ_ONLY}, {READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}"
# a potential row's arguments (the tables, its row, x, the frame, ∂U/∂x) and a damping
# row's (the tables, its row, ẋ, the frame, the force)
ROW = f"int64[:, :], float64[:, :], int64, float64[:], {FRAME}, float64[:]"
# the length of a frame's place on its joint, [s, s p_l, R_l row-major], before its support
# mask (``frame_on_joints``'s ``local``)
PLACE = 13


@inner("void(float64[:, :], float64[:, :], int64, float64[:], float64[:, :], float64[:, :])")
def frame_on_joints(y: Array, jac: Array, column: int, local: Array, placement: Array,
                    jacobian: Array) -> None:
    """A frame's placement [R p; 0 1] into ``placement`` and its Jacobian [J_v; J_ω] (6, n)
    at its origin in world axes into ``jacobian``, from a pass's joint placements ``y``
    (Pinocchio's static regressor, Y[:, c:c+4] = [t_j R_j]/s for the frame's joint j at
    column c = ``column``) and world joint Jacobians ``jac`` = [v_k; ω_k] (6, n) — what
    Pinocchio's frame placement and LOCAL_WORLD_ALIGNED frame Jacobian give:

        p = t_j + R_j p_l = Y[:, c:c+4] [s, s p_l],   R = s Y[:, c+1:c+4] R_l,
        J_v[:, k] = v_k + ω_k × p,   J_ω[:, k] = ω_k   for the joints k that move j, else 0.

    ``local``: [s, s p_l (3), R_l row-major (9), the support mask (n)], p_l and R_l the
    frame's placement on its joint (cpbc.model.robot_model.RobotModel.frame_on_joints)."""
    n = jac.shape[1]
    for i in range(3):
        placement[i, 3] = (y[i, column] * local[0] + y[i, column + 1] * local[1]
                           + y[i, column + 2] * local[2] + y[i, column + 3] * local[3])
        for k in range(3):
            placement[i, k] = local[0] * (y[i, column + 1] * local[4 + k]
                                          + y[i, column + 2] * local[7 + k]
                                          + y[i, column + 3] * local[10 + k])
        placement[3, i] = 0.0
    placement[3, 3] = 1.0
    p0, p1, p2 = placement[0, 3], placement[1, 3], placement[2, 3]
    for k in range(n):
        if local[PLACE + k] == 0.0:
            for r in range(6):
                jacobian[r, k] = 0.0
            continue
        w0, w1, w2 = jac[3, k], jac[4, k], jac[5, k]
        jacobian[0, k] = jac[0, k] + (w1 * p2 - w2 * p1)
        jacobian[1, k] = jac[1, k] + (w2 * p0 - w0 * p2)
        jacobian[2, k] = jac[2, k] + (w0 * p1 - w1 * p0)
        jacobian[3, k], jacobian[4, k], jacobian[5, k] = w0, w1, w2


@inner(f"void({FRAME}, {READ_ONLY}, float64[:], float64[:, :])")
def point_on_frame(origin: Array, rotation: Array, jacobian: Array, offset: Array,
                   point: Array, linear: Array) -> None:
    """p = origin + R o into ``point`` and J_p = J_v − [R o]× J_ω (v_p = v + ω × R o) into
    ``linear`` (3, n)."""
    r0 = r1 = r2 = 0.0
    if offset[3] != 0.0:
        r0 = rotation[0, 0] * offset[0] + rotation[0, 1] * offset[1] + rotation[0, 2] * offset[2]
        r1 = rotation[1, 0] * offset[0] + rotation[1, 1] * offset[1] + rotation[1, 2] * offset[2]
        r2 = rotation[2, 0] * offset[0] + rotation[2, 1] * offset[1] + rotation[2, 2] * offset[2]
    point[0], point[1], point[2] = origin[0] + r0, origin[1] + r1, origin[2] + r2
    for k in range(jacobian.shape[1]):
        w0, w1, w2 = jacobian[3, k], jacobian[4, k], jacobian[5, k]
        linear[0, k] = jacobian[0, k] - (r1 * w2 - r2 * w1)
        linear[1, k] = jacobian[1, k] - (r2 * w0 - r0 * w2)
        linear[2, k] = jacobian[2, k] - (r0 * w1 - r1 * w0)


@kernel(f"float64({FRAME}, {READ_ONLY}, {READ_ONLY}, {READ_ONLY_MATRIX}, float64[:])")
def position_spring(origin: Array, rotation: Array, jacobian: Array, offset: Array,
                    goal: Array, stiffness: Array, grad: Array) -> float:
    """U = ½ eᵀ K e, e = p − p_d, ∂U/∂x = J_pᵀ K e into ``grad`` (Takegaki–Arimoto's
    spring on the point); returns U."""
    n = grad.shape[0]
    point, linear = np.empty(3), np.empty((3, n))
    point_on_frame(origin, rotation, jacobian, offset, point, linear)
    e0, e1, e2 = point[0] - goal[0], point[1] - goal[1], point[2] - goal[2]
    f = np.empty(3)
    for i in range(3):
        f[i] = stiffness[i, 0] * e0 + stiffness[i, 1] * e1 + stiffness[i, 2] * e2
    for k in range(n):
        grad[k] = linear[0, k] * f[0] + linear[1, k] * f[1] + linear[2, k] * f[2]
    return 0.5 * (e0 * f[0] + e1 * f[1] + e2 * f[2])


POSITION_SPRING = 1  # its code; its tables: the point (1, 4), p_d (1, 3), K (3, 3)
POSITION_POINT, POSITION_GOAL, POSITION_STIFFNESS = range(3)


def pack_position_spring(point: Array, goal: Array, stiffness: Array, frame: int,
                         moving: bool = False) -> Packed:
    """The position spring's tables on ``frame`` (``moving``: p_d read from ``goal``)."""
    return Packed(POSITION_SPRING, (point[None, :], goal[None, :], stiffness), frame=frame,
                  live=((POSITION_GOAL, goal),) if moving else ())


@inner(f"float64({ROW})")
def position_spring_row(plan: Ints, floats: Array, row: int, x: Array, origin: Array,
                        rotation: Array, jacobian: Array, grad: Array) -> float:
    """A packed position spring (``position_spring``)."""
    return position_spring(origin, rotation, jacobian,
                           float_table(plan, floats, row, POSITION_POINT)[0],
                           float_table(plan, floats, row, POSITION_GOAL)[0],
                           float_table(plan, floats, row, POSITION_STIFFNESS), grad)


@kernel(f"float64({READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, float64,"
        " float64[:])")
def orientation_spring(rotation: Array, jacobian: Array, goal: Array, stiffness: float,
                       grad: Array) -> float:
    """U = k (3 − tr(R_dᵀR)), ∂U/∂x = k J_ωᵀ vee(M − Mᵀ), M = R R_dᵀ, into ``grad``;
    returns U."""
    m = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            m[i, j] = rotation[i, 0] * goal[j, 0] + rotation[i, 1] * goal[j, 1] + (
                rotation[i, 2] * goal[j, 2])
    v0, v1, v2 = m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]
    for k in range(grad.shape[0]):
        grad[k] = stiffness * (jacobian[3, k] * v0 + jacobian[4, k] * v1 + jacobian[5, k] * v2)
    return stiffness * (3.0 - (m[0, 0] + m[1, 1] + m[2, 2]))


ORIENTATION_SPRING = 3  # its code; its tables: R_d (3, 3), k (1, 1)
ORIENTATION_GOAL, ORIENTATION_STIFFNESS = range(2)


def pack_orientation_spring(goal: Array, stiffness: float, frame: int, moving: bool = False
                            ) -> Packed:
    """The orientation spring's tables on ``frame`` (``moving``: R_d read from ``goal``)."""
    return Packed(ORIENTATION_SPRING, (goal, np.array([[stiffness]])), frame=frame,
                  live=((ORIENTATION_GOAL, goal),) if moving else ())


@inner(f"float64({ROW})")
def orientation_spring_row(plan: Ints, floats: Array, row: int, x: Array, origin: Array,
                           rotation: Array, jacobian: Array, grad: Array) -> float:
    """A packed orientation spring (``orientation_spring``)."""
    return orientation_spring(rotation, jacobian,
                              float_table(plan, floats, row, ORIENTATION_GOAL),
                              float_table(plan, floats, row, ORIENTATION_STIFFNESS)[0, 0], grad)


@kernel(f"float64({READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, {READ_ONLY}, {READ_ONLY}, float64,"
        " float64[:])")
def axis_spring(rotation: Array, jacobian: Array, tool: Array, world: Array,
                stiffness: float, grad: Array) -> float:
    """U = k (1 − a_wᵀ R a_b), ∂U/∂x = k J_ωᵀ (a_w × R a_b) into ``grad``; returns U."""
    a = np.empty(3)
    for i in range(3):
        a[i] = rotation[i, 0] * tool[0] + rotation[i, 1] * tool[1] + rotation[i, 2] * tool[2]
    c0 = world[1] * a[2] - world[2] * a[1]
    c1 = world[2] * a[0] - world[0] * a[2]
    c2 = world[0] * a[1] - world[1] * a[0]
    for k in range(grad.shape[0]):
        grad[k] = stiffness * (jacobian[3, k] * c0 + jacobian[4, k] * c1 + jacobian[5, k] * c2)
    return stiffness * (1.0 - (world[0] * a[0] + world[1] * a[1] + world[2] * a[2]))


AXIS_SPRING = 2  # its code; its tables: [a_bᵀ; a_wᵀ] (2, 3), k (1, 1)
AXIS_AXES, AXIS_STIFFNESS = range(2)


def pack_axis_spring(axes: Array, stiffness: float, frame: int, moving: bool = False
                     ) -> Packed:
    """The axis spring's tables on ``frame``, ``axes`` [a_b; a_w] (``moving``: read from
    ``axes`` before each step)."""
    return Packed(AXIS_SPRING, (axes, np.array([[stiffness]])), frame=frame,
                  live=((AXIS_AXES, axes),) if moving else ())


@inner(f"float64({ROW})")
def axis_spring_row(plan: Ints, floats: Array, row: int, x: Array, origin: Array,
                    rotation: Array, jacobian: Array, grad: Array) -> float:
    """A packed axis spring (``axis_spring``)."""
    axes = float_table(plan, floats, row, AXIS_AXES)
    return axis_spring(rotation, jacobian, axes[0], axes[1],
                       float_table(plan, floats, row, AXIS_STIFFNESS)[0, 0], grad)


@kernel(f"void({FRAME}, {READ_ONLY}, {READ_ONLY_MATRIX}, {READ_ONLY}, {READ_ONLY},"
        " float64[:])")
def task_damping(origin: Array, rotation: Array, jacobian: Array, offset: Array,
                 gain: Array, feedforward: Array, dx: Array, force: Array) -> None:
    """F = Jᵀ (G J ẋ − b), J = [J_p; J_ω] of the point, G = diag(D_x, D_ω) (6, 6) ``gain``,
    b = G [ṗ_ff; ω_ff] (``feedforward``: ṗ_ff (3,), ω_ff = 0, or [ṗ_ff; ω_ff] (6,)), into
    ``force``."""
    n = dx.shape[0]
    point, linear = np.empty(3), np.empty((3, n))
    point_on_frame(origin, rotation, jacobian, offset, point, linear)
    v = np.zeros(6)
    for k in range(n):
        for i in range(3):
            v[i] += linear[i, k] * dx[k]
            v[3 + i] += jacobian[3 + i, k] * dx[k]
    w = np.empty(6)
    for i in range(6):
        b = 0.0
        for j in range(feedforward.shape[0]):
            b += gain[i, j] * feedforward[j]
        s = -b
        for j in range(6):
            s += gain[i, j] * v[j]
        w[i] = s
    for k in range(n):
        s = 0.0
        for i in range(3):
            s += linear[i, k] * w[i] + jacobian[3 + i, k] * w[3 + i]
        force[k] = s


TASK_DAMPING = 6  # its code; its tables: the point (1, 4), G (6, 6), ṗ_ff or [ṗ_ff ω_ff]
TASK_POINT, TASK_GAIN, TASK_FEEDFORWARD = range(3)


def pack_task_damping(point: Array, gain: Array, feedforward: Array, frame: int,
                      moving: bool = False) -> Packed:
    """The task damping's tables on ``frame`` (``moving``: the feed-forward read from
    ``feedforward``)."""
    return Packed(TASK_DAMPING, (point[None, :], gain, feedforward[None, :]), frame=frame,
                  live=((TASK_FEEDFORWARD, feedforward),) if moving else ())


@inner(f"void({ROW})")
def task_damping_row(plan: Ints, floats: Array, row: int, dx: Array, origin: Array,
                     rotation: Array, jacobian: Array, force: Array) -> None:
    """A packed task damping (``task_damping``)."""
    task_damping(origin, rotation, jacobian, float_table(plan, floats, row, TASK_POINT)[0],
                 float_table(plan, floats, row, TASK_GAIN),
                 float_table(plan, floats, row, TASK_FEEDFORWARD)[0], dx, force)


@kernel(f"void({FRAME}, {READ_ONLY}, {READ_ONLY_MATRIX}, {READ_ONLY}, {READ_ONLY},"
        " float64[:])")
def task_tanh_damping(origin: Array, rotation: Array, jacobian: Array, offset: Array,
                      gains: Array, feedforward: Array, dx: Array, force: Array) -> None:
    """F = J_pᵀ D_x tanh(Γ_x (J_p ẋ − ṗ_ff)) on the point, ``gains`` [diag D_x; diag Γ_x]
    (2, 3), ``feedforward`` ṗ_ff, into ``force``: bounded by ‖J_p‖ ‖diag D_x‖₂ (BPBC's
    bounded task damping, TASKSPACE §2.2)."""
    n = dx.shape[0]
    point, linear = np.empty(3), np.empty((3, n))
    point_on_frame(origin, rotation, jacobian, offset, point, linear)
    w = np.empty(3)
    for i in range(3):
        v = 0.0
        for k in range(n):
            v += linear[i, k] * dx[k]
        w[i] = gains[0, i] * np.tanh(gains[1, i] * (v - feedforward[i]))
    for k in range(n):
        force[k] = linear[0, k] * w[0] + linear[1, k] * w[1] + linear[2, k] * w[2]


TASK_TANH_DAMPING = 10  # its code; its tables: the point (1, 4), [D_x; Γ_x] (2, 3), ṗ_ff
TANH_POINT, TANH_GAINS, TANH_FEEDFORWARD = range(3)


def pack_task_tanh_damping(point: Array, gains: Array, feedforward: Array, frame: int,
                           moving: bool = False) -> Packed:
    """The bounded task damping's tables on ``frame`` (``moving``: ṗ_ff read from
    ``feedforward``)."""
    return Packed(TASK_TANH_DAMPING, (point[None, :], gains, feedforward[None, :]),
                  frame=frame, live=((TANH_FEEDFORWARD, feedforward),) if moving else ())


@inner(f"void({ROW})")
def task_tanh_damping_row(plan: Ints, floats: Array, row: int, dx: Array, origin: Array,
                          rotation: Array, jacobian: Array, force: Array) -> None:
    """A packed bounded task damping (``task_tanh_damping``)."""
    task_tanh_damping(origin, rotation, jacobian,
                      float_table(plan, floats, row, TANH_POINT)[0],
                      float_table(plan, floats, row, TANH_GAINS),
                      float_table(plan, floats, row, TANH_FEEDFORWARD)[0], dx, force)
