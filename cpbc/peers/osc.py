"""An operational-space nominal for the CBF-QP peer (``nominal: osc``), written as a
practitioner writes it (Khatib, IEEE J-RA 3(1), 1987; the form of OSCBF's pose-task
controller, TASKSPACE §1.1):

    τ_nom = Jᵀ Λ (a_task − J̇ẋ) + Nᵀ D a_null + C ẋ + g
    Λ = (J D⁻¹ Jᵀ)⁻¹,   Nᵀ = I − Jᵀ Λ J D⁻¹          (dynamically consistent null space)
    a_task = [ω_t² (p_d − p) + 2 ζ_t ω_t (ṗ_ff − ṗ);  −ω_r² e_R − 2 ζ_t ω_r ω]
    a_null = −ω_n² (x − x_n) − 2 ζ_n ω_n (ẋ − ẋ_n,ff)

with J the task rows of the frame's Jacobian: J_v alone (no orientation), [J_v; J_ω] with
e_R = ½ vee(R R_dᵀ − R_d Rᵀ) (a full orientation: ½ the trace spring's gradient, OSCBF's
``orientation_error_3D``), or [J_v; P J_ω] with e_R = a_w × R a_b and P the two world axes
across a_w (an axis goal: its yaw is left to the null space). J̇ẋ, the task rows'
acceleration at ẍ = 0 (the point's classical acceleration: the origin's from Pinocchio, plus
α × r + ω × (ω × r) for an offset r), makes the task close exactly to
ë = −2ζ_t ω_t ė − ω_t² e (OSCBF leaves it out; without it a fast task is bent by the
centripetal terms), so ``task: {omega_n, zeta, rotation_omega_n}`` and ``posture: {omega_n,
zeta}`` mean what they mean for the task-space laws. Λ is inverted every step with a
Tikhonov floor of 1e-9 of the trace of J D⁻¹ Jᵀ (a practitioner's guard; near a kinematic
singularity Λ still grows large).

It reads its goal, feed-forward and posture from a :class:`TaskTarget` (its own fixed one,
or a moving reference's, cpbc.reference.target.MovingTarget, after :meth:`follow`; a
streamed target, cpbc.reference.tracker.ReferenceTracker.set_target, moves that one).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.controllers.linalg import solve_spd
from cpbc.model.frames import cross3
from cpbc.model.robot_model import ArmState, RobotModel
from cpbc.taskspace.gains import fixed_rotations
from cpbc.taskspace.goal import AxisGoal, FrameGoal

TIKHONOV = 1e-9  # of tr(J D⁻¹ Jᵀ), added to its diagonal before the inversion


class TaskTarget(Protocol):
    """What the nominal steers to: p_d (3,), ṗ_ff (3,), x_n (n,) and ẋ_n,ff (n,)."""

    position: Array
    velocity: Array
    posture: Array
    posture_velocity: Array


@dataclass
class HeldTarget:
    """A fixed goal: p_d and x_n, no feed-forward."""

    position: Array
    velocity: Array
    posture: Array
    posture_velocity: Array

    @classmethod
    def at(cls, position: Array, posture: Array) -> HeldTarget:
        return cls(np.array(position, dtype=float), np.zeros(3),
                   np.array(posture, dtype=float), np.zeros(len(posture)))


@dataclass(frozen=True)
class OSCGains:
    """Physical gains: task ω_t [rad/s], ζ_t, rotation ω_r [rad/s], posture ω_n, ζ_n."""

    omega: float
    zeta: float
    rotation_omega: float
    posture_omega: float
    posture_zeta: float


class OperationalSpace:
    """The nominal of the module docstring for ``goal`` with posture x_n, on ``model``.

    Attributes:
        goal: the frame goal (frame, offset, orientation).
        gains: the physical gains.
        target: what it steers to (:meth:`follow` replaces it).
    """

    def __init__(self, model: RobotModel, goal: FrameGoal, posture: Array, gains: OSCGains
                 ) -> None:
        self.model, self.goal, self.gains = model, goal, gains
        self.target: TaskTarget = HeldTarget.at(goal.position, posture)
        self._across = fixed_rotations(goal)
        self._data = model.model.createData()  # J̇ẋ's kinematics, apart from the state's
        self._rest = np.zeros(model.model.nv)

    @property
    def frames(self) -> tuple[int, ...]:
        return (self.goal.frame,)

    def follow(self, target: TaskTarget) -> None:
        """Steer to ``target`` from now on (a moving reference writes it in place)."""
        self.target = target

    def _task(self, state: ArmState) -> tuple[Array, Array, Array]:
        """The task rows J (k, n), the error e (k,) and the desired task acceleration
        a_task (k,) at the state."""
        g, tg = self.gains, self.target
        kin = state.frames[self.goal.frame]
        p, jv = kin.point(self.goal.offset)
        e = p - tg.position
        accel = -g.omega**2 * e - 2.0 * g.zeta * g.omega * (jv @ state.dx - tg.velocity)
        rotation = self.goal.rotation
        if rotation is None:
            return jv, e, accel
        jw = kin.angular
        if isinstance(rotation, AxisGoal):
            jw = self._across @ jw
            e_r = self._across @ cross3(rotation.world, kin.rotation @ rotation.tool)
        else:
            m = kin.rotation @ rotation.T
            e_r = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
        a_r = -g.rotation_omega**2 * e_r - 2.0 * g.zeta * g.rotation_omega * (jw @ state.dx)
        return np.vstack([jv, jw]), np.concatenate([e, e_r]), np.concatenate([accel, a_r])

    def drift(self, state: ArmState) -> Array:
        """J̇ẋ of the task rows (k,): the point's linear and the frame's angular acceleration
        at ẍ = 0 (world axes), the angular one across an axis goal's axis."""
        m, data = self.model.model, self._data
        pin.forwardKinematics(m, data, state.q, state.dq, self._rest)
        acc = pin.getFrameClassicalAcceleration(m, data, self.goal.frame,
                                                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        linear, angular = np.array(acc.linear), np.array(acc.angular)
        if self.goal.offset is not None:
            kin = state.frames[self.goal.frame]
            r = kin.rotation @ self.goal.offset
            omega = kin.angular @ state.dx
            linear = linear + cross3(angular, r) + cross3(omega, cross3(omega, r))
        if self.goal.rotation is None:
            return linear
        if isinstance(self.goal.rotation, AxisGoal):
            angular = self._across @ angular
        return np.concatenate([linear, angular])

    def _task_inertia(self, j: Array, d_inv_jt: Array) -> Array:
        mobility = j @ d_inv_jt
        mobility = mobility + TIKHONOV * float(np.trace(mobility)) * np.eye(len(mobility))
        return solve_spd(mobility, np.eye(len(mobility)))

    def evaluate(self, state: ArmState) -> tuple[Array, float]:
        """τ_nom of the module docstring, and the nominal's closed-loop energy

            ½ẋᵀDẋ + ½ (K^½e)ᵀ Λ (K^½e) + ½ ω_n² (x − x_n)ᵀ diag(D) (x − x_n)

        with K the task stiffnesses (ω_t² on position, ω_r² on rotation): the value the
        governor reads in place of a law's V [J]."""
        g, tg = self.gains, self.target
        j, e, accel = self._task(state)
        d = state.inertia
        d_inv_jt = solve_spd(d, j.T)  # D⁻¹ Jᵀ, (n, k)
        lam = self._task_inertia(j, d_inv_jt)
        offset = state.x - tg.posture
        a_null = -g.posture_omega**2 * offset - (
            2.0 * g.posture_zeta * g.posture_omega * (state.dx - tg.posture_velocity))
        tau_null = d @ a_null
        # Nᵀ τ_0 = τ_0 − Jᵀ Λ J D⁻¹ τ_0 (J D⁻¹ τ_0 = (D⁻¹Jᵀ)ᵀ τ_0, D symmetric)
        projected = tau_null - j.T @ (lam @ (d_inv_jt.T @ tau_null))
        tau = j.T @ (lam @ (accel - self.drift(state))) + projected + (
            state.coriolis_force + state.gravity)
        scale = np.full(len(e), g.omega)
        scale[3:] = g.rotation_omega
        se = scale * e
        energy = 0.5 * float(state.dx @ d @ state.dx + se @ lam @ se) + (
            0.5 * g.posture_omega**2 * float(offset @ (np.diag(d) * offset)))
        return tau, energy

    def torque(self, state: ArmState) -> Array:
        return self.evaluate(state)[0]
