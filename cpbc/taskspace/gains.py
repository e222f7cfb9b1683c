"""Task gains in physical units (TASKSPACE §3.1): a frame's stiffness and damping from the
arm's task-space inertia at the posture x_n, the posture spring and joint damping from D(x_n),
and the linear stiffness and damping of the whole law near the goal (for the zero-order-hold
check of cpbc.scenario.gains).

    Λ_v = (J_v D⁻¹ J_vᵀ)⁺,  K_p = ω_t² Λ_v,  D_x = 2 ζ_t ω_t Λ_v          (translation)
    λ_ω = tr((J_ω D⁻¹ J_ωᵀ)⁺)/3,  stiffness ω_r² λ_ω,
          angular damping d_ω = 2 ζ_t ω_r λ_ω                             (rotation)
    K_n = ω_n² D_ii(x_n),  K_D = 2 ζ_n ω_n D_ii(x_n)                       (posture, joints)

The pseudo-inverse keeps Λ finite for arms that cannot move along every world axis (the
planar arm's normal; see :func:`task_inertia`). Λ is evaluated once, offline; the law
never inverts anything.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
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
    """Λ = (J D⁻¹ Jᵀ)⁺ for a 3 × n block J, with the directions the arm cannot move along
    (eigenvalues of J D⁻¹ Jᵀ below ``RCOND`` of its largest: the planar arm's normal, a
    singular posture's) given the mean of the other eigenvalues of Λ, so that the spring
    stays positive definite and bounded (along those directions J_vᵀ all but kills its
    force)."""
    mobility = jacobian @ np.linalg.solve(inertia, jacobian.T)
    values, vectors = np.linalg.eigh(0.5 * (mobility + mobility.T))
    moving = values > RCOND * max(float(values.max()), 1e-300)
    if not moving.any():
        return np.eye(len(values))
    inverse = np.where(moving, 1.0 / np.where(moving, values, 1.0), 0.0)
    inverse[~moving] = inverse[moving].mean()
    return (vectors * inverse) @ vectors.T


def task_gains(model: RobotModel, goal: FrameGoal, posture: Array, spec: TaskGainSpec
               ) -> TaskGains:
    """The gains of the module docstring at the posture x_n."""
    state = model.state(posture, np.zeros(model.n), frames=[goal.frame])
    kin = state.frames[goal.frame]
    inertia = state.inertia
    lam = task_inertia(kin.point(goal.offset)[1], inertia)
    omega_r = spec.rotation_omega or spec.omega
    lam_w = float(np.trace(task_inertia(kin.angular, inertia))) / 3.0 if (
        goal.rotation is not None) else 0.0
    diag = np.diag(inertia)
    return TaskGains(
        spec.omega**2 * lam, 2.0 * spec.zeta * spec.omega * lam,
        omega_r**2 * lam_w, 2.0 * spec.zeta * omega_r * lam_w,
        spec.posture_omega**2 * diag, 2.0 * spec.posture_zeta * spec.posture_omega * diag)


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
