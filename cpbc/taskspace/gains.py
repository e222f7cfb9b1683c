"""Task gains in physical units (TASKSPACE §3.1): a frame's stiffness and damping from the
arm's task-space inertia at the posture x_n, the posture spring and joint damping from D(x_n),
and the linear stiffness and damping of the whole law near the goal (for the zero-order-hold
check of cpbc.scenario.gain_check).

    K_n = ω_n² D_ii(x_n),  K_D = 2 ζ_n ω_n D_ii(x_n)                       (posture, joints)
    Λ_v = S_v⁺,  S_v = M_vv − M_vr M_rr⁺ M_rv,  M = J D⁻¹ Jᵀ, J = [J_v; P J_ω]
    K_p = (ω_t² − ω_n²) Λ_v,  D_x = 2 (ζ_t ω_t − ζ_n ω_n) Λ_v             (translation)
    λ_ω = tr((J_ω D⁻¹ J_ωᵀ)⁺)/3,  stiffness (ω_r² − ω_n²) λ_ω,
          angular damping d_ω = 2 (ζ_t ω_r − ζ_n ω_n) λ_ω                 (rotation)

so that the task closes to ë + 2ζ_t ω_t ė + ω_t² e ≈ 0 at the posture:

* Λ_v is the point's inertia with the rotations the goal fixes held (P: I for a full
  orientation, the two axes across an axis goal's, none without one), a Schur complement of
  the task's mobility M. The orientation spring does hold them, so the point moves against
  this inertia, not against (J_v D⁻¹ J_vᵀ)⁻¹ (the rotation free), which is 1.1–1.6× lighter
  on the Panda, UR5 and xArm7 goals of scripts/reach_ratio.py: with the lighter one the
  translation closed at ω_t/√c with damping ratio ζ_t/√c, and panda_goal_pose reached in
  3.64 s instead of 2.2 s.
* The posture spring and the joint damping act along the task too: their task-space images
  are ω_n² Λ and 2 ζ_n ω_n Λ (exactly so were they ∝ D rather than diag D). On top of the
  task's own terms they over-damp it, splitting its double pole at ω_t into a slow one
  (≈ 6.8 /s for ω_t = 12, ζ_n ω_n = 2); so the task terms give only the rest. The task
  needs ω_t > ω_n and ζ_t ω_t > ζ_n ω_n (and ω_r > ω_n, ζ_t ω_r > ζ_n ω_n).
* λ_ω stays the free rotation's mean inertia: held, the rotation's inertia is far from
  isotropic (the xArm7's wrist roll), and one scalar stiffness on its mean pushed the light
  axis beyond what the held loop at 1 kHz tolerates.

The pseudo-inverse keeps Λ finite for arms that cannot move along every world axis (the
planar arm's normal; see :func:`task_inertia`). Λ is evaluated once, offline; the law
never inverts anything.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ParameterError
from cpbc.model.frames import FrameKinematics
from cpbc.model.robot_model import RobotModel
from cpbc.taskspace.goal import AxisGoal, FrameGoal

#: Directions of J D⁻¹ Jᵀ with less than this share of its largest eigenvalue count as ones
#: the arm cannot move along (at or near a singular posture, as the outstretched closest pose
#: of an unreachable goal): Λ there would be huge, and so would K_p = ω² Λ, which no
#: sampled loop could hold.
RCOND = 1e-3


@dataclass(frozen=True)
class TaskGainSpec:
    """The physical gains: task ω_t, ζ_t, rotation ω_r (None: ω_t), posture ω_n, ζ_n."""

    omega: float = 8.0
    zeta: float = 1.0
    rotation_omega: float | None = None
    posture_omega: float = 2.0
    posture_zeta: float = 1.0


@dataclass(frozen=True)
class TaskGains:
    """The law's gains for a goal.

    Attributes:
        position: K_p, 3 × 3 [N/m]; position_damping: D_x, 3 × 3 [N·s/m].
        rotation: the orientation stiffness [N·m/rad] (2k of the trace spring, k of the
            axis spring); angular_damping: d_ω [N·m·s/rad].
        posture: K_n (n,); joint_damping: K_D (n,).
    """

    position: Array
    position_damping: Array
    rotation: float
    angular_damping: float
    posture: Array
    joint_damping: Array


def task_inertia(jacobian: Array, inertia: Array) -> Array:
    """Λ = (J D⁻¹ Jᵀ)⁺ for a 3 × n block J (:func:`inverse_mobility`)."""
    return inverse_mobility(jacobian @ np.linalg.solve(inertia, jacobian.T))


def inverse_mobility(mobility: Array) -> Array:
    """Λ = M⁺ of a 3 × 3 mobility M, with the directions the arm cannot move along
    (eigenvalues of M below ``RCOND`` of its largest: the planar arm's normal, a singular
    posture's) given the mean of the other eigenvalues of Λ, so that the spring stays
    positive definite and bounded (along those directions J_vᵀ all but kills its force)."""
    values, vectors = np.linalg.eigh(0.5 * (mobility + mobility.T))
    moving = values > RCOND * max(float(values.max()), 1e-300)
    if not moving.any():
        return np.eye(len(values))
    inverse = np.where(moving, 1.0 / np.where(moving, values, 1.0), 0.0)
    inverse[~moving] = inverse[moving].mean()
    return (vectors * inverse) @ vectors.T


def fixed_rotations(goal: FrameGoal) -> Array:
    """P: the world axes of the rotations an orientation goal fixes, (k, 3): all three for a
    full orientation, the two across an axis goal's axis, none without one."""
    if goal.rotation is None:
        return np.zeros((0, 3))
    if not isinstance(goal.rotation, AxisGoal):
        return np.eye(3)
    a = goal.rotation.world
    u = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    u = u / np.linalg.norm(u)
    return np.vstack([u, np.cross(a, u)])


def held_mobility(linear: Array, rotation: Array, inertia: Array) -> Array:
    """S_v = M_vv − M_vr M_rr⁺ M_rv: the point's mobility with the rotation rows ``rotation``
    (k × n, k ≥ 0) held, M = J D⁻¹ Jᵀ for J = [``linear``; ``rotation``]."""
    j = np.vstack([linear, rotation])
    m = j @ np.linalg.solve(inertia, j.T)
    if len(j) == 3:
        return m
    rr = np.linalg.pinv(m[3:, 3:], rcond=RCOND, hermitian=True)
    s = m[:3, :3] - m[:3, 3:] @ rr @ m[3:, :3]
    return 0.5 * (s + s.T)


def _net(task: float, posture: float, what: str) -> float:
    """The task's own share of a gain the posture terms supply ``posture`` of."""
    if task <= posture:
        raise ParameterError(what, f"the task's {what} ({task:g}) must exceed the posture's "
                             f"({posture:g}): the posture spring and joint damping act along "
                             "the task too, so the task terms give only the rest")
    return task - posture


def task_gains(model: RobotModel, goal: FrameGoal, posture: Array, spec: TaskGainSpec
               ) -> TaskGains:
    """The gains of the module docstring at the posture x_n."""
    state = model.state(posture, np.zeros(model.n), frames=[goal.frame])
    kin = state.frames[goal.frame]
    inertia = state.inertia
    held = fixed_rotations(goal) @ kin.angular
    lam = inverse_mobility(held_mobility(kin.point(goal.offset)[1], held, inertia))
    omega_r = spec.rotation_omega or spec.omega
    lam_w = float(np.trace(task_inertia(kin.angular, inertia))) / 3.0 if (
        goal.rotation is not None) else 0.0
    diag = np.diag(inertia)
    wn, damped = spec.posture_omega, spec.posture_zeta * spec.posture_omega
    stiffness = _net(spec.omega**2, wn**2, "stiffness ω_n²")
    damping = 2.0 * _net(spec.zeta * spec.omega, damped, "damping ζ ω_n")
    rotation = _net(omega_r**2, wn**2, "rotation stiffness ω_n²") if lam_w else 0.0
    angular = 2.0 * _net(spec.zeta * omega_r, damped, "rotation damping ζ ω_n") if lam_w \
        else 0.0
    return TaskGains(
        stiffness * lam, damping * lam, rotation * lam_w, angular * lam_w,
        wn**2 * diag, 2.0 * damped * diag)


def linear_terms(goal: FrameGoal, gains: TaskGains, kin: FrameKinematics
                 ) -> tuple[Array, Array]:
    """The law's stiffness ∂²U/∂x² at zero task error and its damping matrix, (n, n) each:
    J_vᵀK_pJ_v + k_R J_ωᵀP J_ω + K_n and J_vᵀD_xJ_v + d_ω J_ωᵀP J_ω + K_D, with P the identity
    (full orientation) or the projector across the world axis (axis goal)."""
    jv, jw = kin.point(goal.offset)[1], kin.angular
    across = np.eye(3)
    if isinstance(goal.rotation, AxisGoal):
        a = goal.rotation.world
        across = across - np.outer(a, a)
    stiffness = jv.T @ gains.position @ jv + np.diag(gains.posture)
    damping = jv.T @ gains.position_damping @ jv + np.diag(gains.joint_damping)
    if goal.rotation is not None:
        stiffness = stiffness + gains.rotation * (jw.T @ across @ jw)
        damping = damping + gains.angular_damping * (jw.T @ across @ jw)
    return stiffness, damping
