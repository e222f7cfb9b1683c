"""The per-step state finished from one Pinocchio pass (cpbc.model.state_pass): D, C ẋ, g,
f and C in controller coordinates, the joint kinematics and every frame the state holds,
written into one flat array (its ``terms``), which the laws' kernels and the state's fields
(cpbc.model.arm_state.ArmState, views of it) read.

The pass's choices and constants are packed once per pass (``pack_state``): the state's
tables. A pass that gives the joint kinematics leaves g to the finishing, which computes it
from them (``joint_gravity``): Pinocchio's CRBA in world axes gives the joint Jacobians with
D, and computeAllTerms' centroidal terms, centre of mass and energies are not computed.
``finish_into`` is the one finishing: ``finish_state`` calls it alone, and a law's kernel
(cpbc.kernels.laws) calls it first when it is handed the pass unfinished.

The terms' layout (``terms_size``, ``state_views``): D (n²), C ẋ (n), g (n), f (n), C (c²;
c = n when the state holds C, else 0), the joint Jacobians (6n) and placements (3 × the
static regressor's columns) when it holds the joint kinematics, then each frame's placement
(16) and Jacobian (6n), in the order of the pass's frames.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.coordinate_maps import congruence, joint_friction, to_controller
from cpbc.kernels.task import PLACE, frame_on_joints
from cpbc.kernels.views import Ints, borrowed, float_rows

# the state's ints: n, c, whether it holds the joint kinematics, the static regressor's
# columns, whether the coordinates are the joints', whether the arm has friction, the number
# of frames, where the gravity's constants start in the floats (−1: the pass gives g); then
# per frame its joint's column in the regressor (−1: welded to the world) and where its
# constants start in the floats
N, CORIOLIS, KINEMATICS, Y_COLUMNS, JOINTS, FRICTION, FRAMES, GRAVITY = range(8)
HEADER = 8
WORLD = -1  # a frame welded to the world: its placement is constant, its Jacobian zero


def pack_state(n: int, coriolis: bool, kinematics: bool, y_columns: int, t_inv: Array,
               friction: Array, coulomb: Array, smoothing: float,
               frames: tuple[tuple[int, Array], ...], gravity: Array) -> tuple[Ints, Array]:
    """The state's tables: its ints and floats [T⁻¹, F_d, F_c, ε, the gravity's constants,
    each frame's constants]. ``frames``: per frame its joint's column in the static
    regressor and its place on the joint [s, s p_l, R_l, the support mask]
    (cpbc.model.robot_model.RobotModel.frame_on_joints), or (``WORLD``, its constant
    placement (4, 4)). ``gravity``: what ``joint_gravity`` reads (RobotModel
    .gravity_on_joints) when the pass leaves g to the finishing, else empty."""
    at = 2 * n * n + n + 1
    ints = [n, n if coriolis else 0, int(kinematics), y_columns,
            int(np.array_equal(t_inv, np.eye(n))),
            int(bool(np.any(friction) or np.any(coulomb))), len(frames),
            at if gravity.size else -1]
    floats = [t_inv.ravel(), friction.ravel(), np.asarray(coulomb, dtype=float),
              np.array([smoothing]), np.asarray(gravity, dtype=float).ravel()]
    at += gravity.size
    for column, constants in frames:
        ints += [column, at]
        floats.append(np.asarray(constants, dtype=float).ravel())
        at += floats[-1].size
    return np.array(ints, dtype=np.int64), np.concatenate(floats).astype(float)


def layout(n: int, coriolis: bool, kinematics: bool, y_columns: int, frames: int
           ) -> dict[str, int]:
    """Where each term starts in the terms, and their length (``size``), for Python's views
    of them (cpbc.model.arm_state): the layout ``state_views`` and ``frame_views`` read."""
    c = n if coriolis else 0
    k = n * n
    joints = k + 3 * n + c * c
    first_frame = joints + (6 * n + 3 * y_columns if kinematics else 0)
    return {"inertia": 0, "coriolis_force": k, "gravity": k + n, "dissipation": k + 2 * n,
            "coriolis_matrix": k + 3 * n, "joint_jacobians": joints,
            "regressor": joints + 6 * n, "frames": first_frame,
            "size": first_frame + frames * (16 + 6 * n)}


@inner("int64(int64[::1], int64)")
def frames_at(ints: Ints, at: int) -> int:
    """Where the frames start in the terms (the state's ints from ``at``)."""
    n, c = ints[at + N], ints[at + CORIOLIS]
    joints = 6 * n + 3 * ints[at + Y_COLUMNS] if ints[at + KINEMATICS] == 1 else 0
    return n * n + 3 * n + c * c + joints


@inner("int64(int64[::1], int64)")
def terms_size(ints: Ints, at: int) -> int:
    """The length of the terms (the state's ints from ``at``)."""
    n = ints[at + N]
    return frames_at(ints, at) + ints[at + FRAMES] * (16 + 6 * n)


STATE = ("Tuple((float64[:, :], float64[:], float64[:], float64[:], float64[:, :],"
         " float64[:, :], float64[:, :]))")


@inner(f"{STATE}(int64[::1], int64, float64[::1])")
def state_views(ints: Ints, at: int, terms: Array
                ) -> tuple[Array, Array, Array, Array, Array, Array, Array]:
    """D, C ẋ, g, f, C, the joint placements and the joint Jacobians (empty without the
    joint kinematics) as views of the terms (the state's ints from ``at``)."""
    n, c = ints[at + N], ints[at + CORIOLIS]
    k = n * n
    columns = ints[at + Y_COLUMNS] if ints[at + KINEMATICS] == 1 else 0
    joints = k + 3 * n + c * c
    rows = 6 if columns > 0 else 0
    return (float_rows(terms, 0, n, n), terms[k:k + n], terms[k + n:k + 2 * n],
            terms[k + 2 * n:k + 3 * n], float_rows(terms, k + 3 * n, c, c),
            float_rows(terms, joints + rows * n, 3, columns),
            float_rows(terms, joints, rows, n))


@inner("UniTuple(float64[:, :], 2)(int64[::1], int64, float64[::1], int64)")
def frame_views(ints: Ints, at: int, terms: Array, frame: int) -> tuple[Array, Array]:
    """The placement (4, 4) and Jacobian (6, n) of the state's ``frame``-th frame."""
    n = ints[at + N]
    start = frames_at(ints, at) + frame * (16 + 6 * n)
    return float_rows(terms, start, 4, 4), float_rows(terms, start + 16, 6, n)


@inner("void(float64[::1], int64, float64[:, :], float64[:, :], float64[:])")
def joint_gravity(floats: Array, start: int, y: Array, jac: Array, gravity: Array) -> None:
    """g(q), the gradient of the potential energy, from a pass's joint placements ``y``
    (Pinocchio's static regressor, Y[:, 4i:4i+4] = [t_i R_i]/s) and world joint Jacobians
    ``jac`` = [v_k; ω_k] (6, n), into ``gravity`` (joint coordinates):

        g_k = −[v_k; ω_k]ᵀ Σ_i [m_i g₀; p_i × m_i g₀],   p_i = t_i + R_i c_i,

    over the links i that joint k moves (the wrench of their weights at the world's origin),
    m_i and c_i each link's mass and centre of mass on its joint — what Pinocchio's
    computeGeneralizedGravity gives (to 1e-14). ``floats`` from ``start``: [g₀ (3), s, then
    per link m_i, c_i (3) and its support mask (n)] (RobotModel.gravity_on_joints)."""
    n = jac.shape[1]
    g0, g1, g2, scale = floats[start], floats[start + 1], floats[start + 2], floats[start + 3]
    for k in range(n):
        gravity[k] = 0.0
    for i in range(y.shape[1] // 4):
        at = start + 4 + i * (4 + n)
        mass = floats[at]
        if mass == 0.0:
            continue
        c, cx, cy, cz = 4 * i, floats[at + 1], floats[at + 2], floats[at + 3]
        p0 = scale * (y[0, c] + y[0, c + 1] * cx + y[0, c + 2] * cy + y[0, c + 3] * cz)
        p1 = scale * (y[1, c] + y[1, c + 1] * cx + y[1, c + 2] * cy + y[1, c + 3] * cz)
        p2 = scale * (y[2, c] + y[2, c + 1] * cx + y[2, c + 2] * cy + y[2, c + 3] * cz)
        f0, f1, f2 = mass * g0, mass * g1, mass * g2
        n0, n1, n2 = p1 * f2 - p2 * f1, p2 * f0 - p0 * f2, p0 * f1 - p1 * f0
        for k in range(n):
            if floats[at + 4 + k] != 0.0:
                gravity[k] -= (jac[0, k] * f0 + jac[1, k] * f1 + jac[2, k] * f2
                               + jac[3, k] * n0 + jac[4, k] * n1 + jac[5, k] * n2)


@inner("float64[:](int64[::1], float64[::1], int64, int64, float64[:], float64[:, :],"
       " float64[:, :], float64[:])")
def pass_gravity(ints: Ints, floats: Array, at: int, at_floats: int, gravity_q: Array,
                 y: Array, jac: Array, scratch: Array) -> Array:
    """g_q: the pass's, or — when it leaves g to the finishing — ``joint_gravity`` from its
    joint kinematics, into ``scratch`` (the place of f, which the finishing writes after)."""
    if ints[at + GRAVITY] < 0:
        return gravity_q
    joint_gravity(floats, at_floats + ints[at + GRAVITY], y, jac, scratch)
    return scratch


@inner("void(int64[::1], float64[::1], int64, int64, float64[:], float64[:, :], float64[:],"
       " float64[:], float64[:, :], float64[:, :], float64[:, :], float64[::1])")
def finish_into(ints: Ints, floats: Array, at: int, at_floats: int, dx: Array,
                inertia_q: Array, nle: Array, gravity_q: Array, coriolis_q: Array, y: Array,
                jac: Array, terms: Array) -> None:
    """The state's terms from the pass in joint coordinates (D_q, nle = C q̇ + g_q, g_q, C_q,
    the joint placements Y and Jacobians; g_q empty: ``joint_gravity`` from Y and the
    Jacobians) into ``terms``: D = T⁻ᵀ D_q T⁻¹, C ẋ = T⁻ᵀ (nle − g_q),
    g = T⁻ᵀ g_q (cpbc.kernels.coordinate_maps.to_controller), f (``joint_friction``),
    C = T⁻ᵀ C_q T⁻¹, Y and the joint Jacobians copied, and each frame's placement and Jacobian
    J_q T⁻¹ from the joint kinematics (cpbc.kernels.task.frame_on_joints). The state's tables
    start at ``at`` in ``ints`` and at ``at_floats`` in ``floats``."""
    n, c = ints[at + N], ints[at + CORIOLIS]
    joints = ints[at + JOINTS] == 1
    t_inv = float_rows(floats, at_floats, n, n)
    inertia, bias, gravity, dissipation, coriolis, placements, joint_jacobians = state_views(
        ints, at, terms)
    gravity_q = pass_gravity(ints, floats, at, at_floats, gravity_q, y, jac, dissipation)
    if joints:
        for i in range(n):
            bias[i] = nle[i] - gravity_q[i]
            gravity[i] = gravity_q[i]
            for j in range(n):
                inertia[i, j] = inertia_q[i, j]
        for i in range(c):
            for j in range(c):
                coriolis[i, j] = coriolis_q[i, j]
    else:
        to_controller(t_inv, inertia_q, nle, gravity_q, inertia, bias, gravity)
        if c > 0:
            congruence(t_inv, coriolis_q, coriolis)
    if ints[at + FRICTION] == 1:
        k = at_floats + n * n
        joint_friction(joints, t_inv, float_rows(floats, k, n, n),
                       floats[k + n * n:k + n * n + n], floats[k + n * n + n], dx, dissipation)
    else:
        dissipation[:] = 0.0
    for i in range(placements.shape[0]):
        for j in range(placements.shape[1]):
            placements[i, j] = y[i, j]
    for i in range(joint_jacobians.shape[0]):
        for j in range(n):
            joint_jacobians[i, j] = jac[i, j]
    _frames_into(ints, floats, at, at_floats, joints, t_inv, y, jac, terms)


@inner("void(int64[::1], float64[::1], int64, int64, boolean, float64[:, :], float64[:, :],"
       " float64[:, :], float64[::1])")
def _frames_into(ints: Ints, floats: Array, at: int, at_floats: int, joints: bool,
                 t_inv: Array, y: Array, jac: Array, terms: Array) -> None:
    """Each frame's placement and Jacobian (controller coordinates) into the terms."""
    n = ints[at + N]
    count = ints[at + FRAMES]
    work = np.empty((6, n if count > 0 and not joints else 0))
    for f in range(count):
        column, start = ints[at + HEADER + 2 * f], at_floats + ints[at + HEADER + 2 * f + 1]
        placement, jacobian = frame_views(ints, at, terms, f)
        if column == WORLD:
            for i in range(4):
                for j in range(4):
                    placement[i, j] = floats[start + 4 * i + j]
            jacobian[:, :] = 0.0
            continue
        local = floats[start:start + PLACE + n]
        if joints:
            frame_on_joints(y, jac, column, local, placement, jacobian)
            continue
        frame_on_joints(y, jac, column, local, placement, work)
        for r in range(6):
            for j in range(n):
                s = 0.0
                for k in range(n):
                    s += work[r, k] * t_inv[k, j]
                jacobian[r, j] = s


@kernel(f"void(int64[::1], float64[::1], {READ_ONLY}, float64[:, :], float64[:], float64[:],"
        " float64[:, :], float64[:, :], float64[:, :], float64[::1])")
def finish_state(ints: Ints, floats: Array, dx: Array, inertia_q: Array, nle: Array,
                 gravity_q: Array, coriolis_q: Array, y: Array, jac: Array, terms: Array
                 ) -> None:
    """``finish_into`` on its own: the state's terms for a reader outside a law's kernel."""
    ints, floats, terms = borrowed(ints), borrowed(floats), borrowed(terms)  # held by the caller
    finish_into(ints, floats, 0, 0, dx, inertia_q, nle, gravity_q, coriolis_q, y, jac, terms)
