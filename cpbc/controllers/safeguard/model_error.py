"""A declared model error, held by the safeguard as a disturbance: the floors of (S1) raised by
what an acceleration error within the declared bound can take off each margin in one period.

The guard predicts with the controller's model. Where the arm's acceleration differs from the
model's by d, |d_j| ≤ ā_j (``simulation.model_error.acceleration``: friction the model does
not know, a mass off by some per cent, an unmodelled payload — whatever the user bounds), the
period's end moves by c h² d (c of the prediction's end, ``travel``: ½ in continuous time) and
its mid-point by ⅛ h² d, and the rates by h d. To first order a margin loses at most

    configuration φ_i:   c h² Σ_j |∂φ_i/∂x_j| ā_j        at the end,   ⅛ h² (…) at mid-period,
    velocity ψ_k = ω_k − ½ ẋᵀΠ_k ẋ:   h Σ_j |(Π_k ẋ)_j| ā_j + ½ h² āᵀ|Π_k| ā   at the end

(Π_k: ``VelocityConstraint.weights``: r rᵀ for a rate, D for the kinetic energy; the second
term is exact for a constant Π). Holding every predicted margin that much above the floor of
(S1) makes the true margin keep (S1) whatever d within the bound does: by induction it never
falls below its cushion δ_i > 0. The rescue's rollouts are the model's (checked again from
each measured state while a brake is held: cpbc.controllers.rescue); the braking set's
deceleration is lowered by the error's share along the motion
(:class:`cpbc.constraints.stopping.Braking`, ``disturbance``). The curvature of φ and the
change of Π_k over the period are left out (second order in h).

**The Coulomb friction's own error.** The model's Coulomb friction is smooth, F_c tanh(q̇/ε);
a real joint's is set-valued at rest and has its own shape at low speed. Both lie in
[−F_c, F_c], and through D⁻¹ their difference moves every coordinate's acceleration
(:func:`friction_error`, added to the declared bound whenever the model has Coulomb
friction). How far they differ depends on whether the joint *slides*
(cpbc.model.coulomb.DryFriction): the plant's dry friction on joint j is exactly
F_j sign(q̇_j) while

    |q̇_j| ≥ T_f α_j + v_c,j      (α_j ≥ 0: the joint's deceleration, −sign(q̇_j) q̈_j),

and anywhere in [−F_j, F_j] otherwise. An ideal Coulomb friction has T_f = v_c = 0 (it
opposes any nonzero rate). MuJoCo's ``frictionloss`` — the plant here, and franky-sim's — is
a soft constraint: its force is −clamp((q̈_j + b q̇_j)/R_j, −F_j, F_j), with b = 2/(d_w t_c)
and R_j = (1 − d₀)/d₀ A_j (solref's time constant t_c, solimp's d₀ and d_w; A_j MuJoCo's
estimate of (D⁻¹)_jj), so it opposes the rate the joint would have 1/b later, not the rate
it has: it is F_j sign(q̇_j) when b|q̇_j| − α_j ≥ R_j F_j, i.e. T_f = 1/b (9.5 ms with the
default solref 0.02 and solimp 0.9, 0.95) and v_c,j = R_j F_j/b (MuJoCo's A_j is a constant
taken at the model's reference pose, the rotor inertia included: v_c ≤ 0.008 rad/s on the
campaign's three arms, 0.21 rad/s on the xArm7's wrist with 2 N·m on 0.01 kg·m² of rotor;
:func:`mujoco_friction` takes it from the model, never below 0.15). While
a brake decelerates a joint harder than b|q̇_j| its friction pulls *with* the motion (on the
UR5 of the rate campaign, seed 49: −2 N·m against the model's +1.35 N·m at 0.04 rad/s).
Over a period on which the rate moves by at most h α'_j (α'_j bounding |q̈_j|: so
s_j = |q̇_j(0)| − h α'_j ≤ |q̇_j| ≤ S_j = |q̇_j(0)| + h α'_j throughout), the force error is

    e_j = F_j (1 − tanh(s_j/ε))   if s_j ≥ T_f α_j + v_c,j   (the joint slides: same sign),
    e_j = F_j (1 + tanh(S_j/ε))   otherwise                  (opposite signs at worst),

with the model's friction taken at the period's start, as the guard's prediction takes it.
The acceleration error is |D⁻¹| |T⁻ᵀ| e. α_j and α'_j are bounded by what the torques the
step may hold give in the model (under a torque-rate limit the box one step reaches; without
one the whole torque box, which takes no joint to slide) plus the coarse error |D⁻¹|·2F of
the plant's friction itself — except, in α_j, the joint's own: whether a joint slides is
decided by the deceleration it would have if it slid (short of F_j its friction would
decelerate it less, and b|q̇_j| ≥ R_j F_j + α_j would hold the more), so its own friction
differs from the model's by at most F_j (1 − tanh(s_j/ε)) there. The coarse 2F_j of its own
took the xArm7's light wrist (2 N·m on about 0.01 kg·m²: 400 rad/s²) never to slide below
4 rad/s. Where every joint slides fast e vanishes; where joints rest or
turn it does not, which is why holding it over a whole brake (½t²|D⁻¹|e, tried) rejects
nearly every brake on light wrists. The earlier bound, F_j at every speed, assumed the two
frictions agree in sign once the joint moves: under a hard brake it was too small. The guard
holds max(e_j, F_j): e_j alone lowered its floors at speed so far (it acted on 11–18 % of
the Panda's and FR3's steps at 1 kHz instead of 55 %) that both arms' joint 1 crossed its
rate bound at 500 Hz from seed 34 of the rate campaign while the friction's error stayed
inside e all along: the F_j at speed covers some other error of the one-period prediction
there, not yet found. On the FR3 (franky-sim's friction, 1000 N·m/s, 1 kHz) the error reached
0.8–1.2 rad/s² on joints 2 and 4 as a wrist joint's rate passed through zero, and pushed
joint 1 through its rate bound before the guard held it.

This is why the bare guard let velocity margins break under a ±20 % mass error (docs/
ROBUSTNESS.md, "Model mismatch"): a law that rides a velocity bound cancels the *model's*
acceleration there, and the model error alone pushes through; the raised floor keeps the
rate h ā_j (1 kHz, 10 rad/s²: 0.01 rad/s) inside its bound instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.margin_slopes import MarginSlopes
from cpbc.errors import ParameterError
from cpbc.kernels import friction_error as kernels
from cpbc.kernels.small_solves import inverse_inertia
from cpbc.model.coulomb import MUJOCO_FRICTION, MUJOCO_IMPEDANCE, DryFriction
from cpbc.model.robot_model import ArmState, RobotModel

_NONE = np.zeros(0)  # no accelerations given (friction_error)


def acceleration_bound(value: Array | float, n: int) -> Array:
    """ā as n finite numbers ≥ 0 (one number for every coordinate), or a ParameterError
    naming ``model_error``."""
    found = np.asarray(value, dtype=float)
    if found.ndim == 0:
        found = np.full(n, float(found))
    if found.shape != (n,) or not np.all(np.isfinite(found)) or np.any(found < 0):
        raise ParameterError("model_error", "model_error must be one number or one per "
                             f"coordinate ({n}), finite and ≥ 0 [rad/s² or m/s²], got "
                             f"{np.asarray(value).tolist()}")
    return found


def _joint_inverse(model: RobotModel, inertia: Array,
                   inverse: Array | None = None) -> tuple[Array, Array]:
    """(D⁻¹ T⁻ᵀ in controller coordinates, T⁻¹ D⁻¹ T⁻ᵀ: the joint accelerations a joint
    torque gives); ``inverse``: D⁻¹ when the caller has it."""
    inv = inverse_inertia(inertia) if inverse is None else inverse
    coords = model.coordinates
    if coords.is_identity:
        return inv, inv
    to_force = coords.inverse.T
    return inv @ to_force, coords.inverse @ inv @ to_force


def mujoco_friction(model: RobotModel) -> DryFriction:
    """MuJoCo's frictionloss on the model's joints (the module docstring): its T_f, and the
    creep v_c = max_j R_j F_j / b with A_j = (T⁻¹D⁻¹T⁻ᵀ)_jj at the reference pose x = 0 (how
    MuJoCo takes its dof_invweight0, the rotor inertia included), but never below
    :data:`cpbc.model.coulomb.MUJOCO_CREEP`. A plant whose links are lighter than the
    model's has a larger A_j, which the constant's margin covers on the campaign's arms
    (their v_c ≤ 0.008 rad/s) and not on a light wrist with heavy friction (the xArm7 with
    0.01 kg·m² of rotor and 2 N·m: 0.21 rad/s from the model)."""
    levels = model.coulomb_friction
    if not levels.any():
        return MUJOCO_FRICTION
    d0 = MUJOCO_IMPEDANCE
    joint_inv = _joint_inverse(model, model.inertia(np.zeros(model.n)))[1]
    # v_c = R_j F_j / b, 1/b = T_f
    creep = float(np.max((1.0 - d0) / d0 * np.diag(joint_inv) * levels)) * (
        MUJOCO_FRICTION.build_up)
    return DryFriction(MUJOCO_FRICTION.build_up, max(creep, MUJOCO_FRICTION.creep))


def friction_error(model: RobotModel, state: ArmState,
                   accel: tuple[Array, Array] | None = None, period: float = 0.0,
                   plant: DryFriction = MUJOCO_FRICTION, inverse: Array | None = None,
                   torques: tuple[Array, Array, Array] | None = None) -> Array | None:
    """The bound on the acceleration error of the model's smooth Coulomb friction over one
    period from ``state`` (the module docstring): |D⁻¹| |T⁻ᵀ| max(e, F) per coordinate, or
    None for a model without Coulomb friction. ``accel``: (centre, radius), controller
    coordinates, of the model accelerations the torques that may be held over the period
    give; None for any (no joint is then taken to slide, and over a period ``period`` > 0 a
    rate may reach any speed: e_j = 2F_j). ``inverse``: D⁻¹ when the caller has it.
    ``torques``: (b, lower, upper) in place of ``accel``: the accelerations are those of the
    joint torques lower ≤ τ_q ≤ upper at the bias b (:func:`reachable_accelerations`), found
    in the same call (cpbc.kernels.friction_error: the accelerations' reach, e_j and the sum
    in one call)."""
    levels = model.coulomb_friction
    if not levels.any():
        return None
    inv = inverse_inertia(state.inertia) if inverse is None else inverse
    coords = model.coordinates
    out = np.empty(model.n)
    if torques is not None:
        kernels.held_friction_error(inv, coords.inverse, not coords.is_identity, levels,
                                    model.friction_smoothing, plant.build_up, plant.creep,
                                    state.dx, *torques, period, out)
        return out
    centre, radius = (_NONE, _NONE) if accel is None else accel
    kernels.friction_error(inv, coords.inverse, not coords.is_identity, levels,
                           model.friction_smoothing, plant.build_up, plant.creep, state.dx,
                           centre, radius, accel is not None, period, out)
    return out


def reachable_accelerations(model: RobotModel, state: ArmState, bias: Array, lower: Array,
                            upper: Array, inverse: Array | None = None
                            ) -> tuple[Array, Array]:
    """(centre, radius) of the model accelerations D⁻¹(T⁻ᵀ τ_q − b) of the joint torques
    lower ≤ τ_q ≤ upper, per controller coordinate (an infinite bound: an infinite radius;
    cpbc.kernels.friction_error); ``inverse``: D⁻¹ when the caller has it."""
    inv = inverse_inertia(state.inertia) if inverse is None else inverse
    coords = model.coordinates
    centre, radius = np.empty(model.n), np.empty(model.n)
    kernels.reachable_accelerations(inv, coords.inverse, not coords.is_identity, bias, lower,
                                    upper, centre, radius)
    return centre, radius


def margin_losses(constraints: ConstraintSet, state: ArmState, bound: Array, period: float,
                  travel: float, slopes: MarginSlopes | None = None) -> tuple[Array, Array]:
    """What an acceleration error |d_j| ≤ ``bound``_j can take off each margin of
    ``constraints`` over one period (the module docstring): the position off by c h² ā at
    the end and ⅛h² ā at mid-period, the rate by h ā (:meth:`MarginSlopes.losses`;
    ``slopes`` at the state when the caller has them)."""
    h = period
    reach = slopes if slopes is not None else MarginSlopes.at(constraints, state)
    return reach.losses(travel * h * h * bound, 0.125 * h * h * bound, h * bound)


@dataclass(frozen=True)
class DeclaredError:
    """What the scenario declares its model and measurements may get wrong besides an
    acceleration bound (``simulation.model_error``), held by the safeguard.

    Attributes:
        inertia: e ∈ [0, 1), the relative error of every link's mass and rotational inertia
            (:class:`InertiaError`); the kinetic-energy limits the laws keep are lowered to
            Ω/(1 + e) by the scenario (the arm's energy ½ẋᵀDẋ ≤ (1 + e) ½ẋᵀD̂ẋ).
        armature, damping, friction: what the plant may add to each joint that the model
            does not have: rotor inertia [0, A] [kg·m²], viscous damping [0, c]
            [N·m·s/rad], dry friction [0, F] [N·m] (joint coordinates), or None.
        position: p̄, a bound on the error of each measured coordinate [rad or m], or None.
        velocity: v̄, a bound on the error of each measured rate [rad/s or m/s], or None
            (:func:`measurement_losses`).
    """

    inertia: float = 0.0
    armature: Array | None = None
    damping: Array | None = None
    friction: Array | None = None
    position: Array | None = None
    velocity: Array | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.inertia) and 0.0 <= self.inertia < 1.0):
            raise ValueError(f"inertia error must be in [0, 1), got {self.inertia}")
        for name in ("armature", "damping", "friction", "position", "velocity"):
            value = getattr(self, name)
            if value is not None and not (np.all(np.isfinite(value)) and np.all(
                    np.asarray(value) >= 0.0)):
                raise ValueError(f"{name} error must be finite and ≥ 0, got {value}")

    @property
    def dynamic(self) -> bool:
        """Whether an error of the dynamics is declared (:class:`InertiaError`)."""
        return bool(self.inertia) or any(
            v is not None for v in (self.armature, self.damping, self.friction))

    def acceleration_bound(self, model: RobotModel) -> InertiaError | None:
        """The bound on the acceleration error it makes, or None when none is declared."""
        if not self.dynamic:
            return None
        return InertiaError(model, self.inertia, self.armature, self.damping, self.friction)

    @property
    def measured(self) -> bool:
        """Whether a measurement error is declared."""
        return self.position is not None or self.velocity is not None


def _contracts(g: Array) -> bool:
    """Whether G ≥ 0 has spectral radius below 1: at once when a row or column sum bound
    says so, else from its eigenvalues."""
    if min(float(g.sum(axis=1).max()), float(g.sum(axis=0).max())) < 1.0:
        return True
    return float(np.max(np.abs(np.linalg.eigvals(g)))) < 1.0


def measurement_losses(constraints: ConstraintSet, state: ArmState, declared: DeclaredError,
                       period: float, slopes: MarginSlopes | None = None
                       ) -> tuple[Array, Array]:
    """What a measured state off by |x̃ − x| ≤ p̄, |ẋ̃ − ẋ| ≤ v̄ can hide of each margin of
    ``constraints`` at the period's end and mid-period (the order of ``margin_losses``).

    The guard predicts from the measured state; the true state's prediction differs by
    p̄ + t v̄ in position at time t into the period and by v̄ in rate. A configuration margin
    φ_i loses Σ_j |∂φ_i/∂x_j| (p̄_j + t v̄_j) to first order; a velocity margin
    ψ_k = ω_k − ½ẋᵀΠ_k ẋ, taken at the measured rate, exceeds the true one by at most
    Σ_j |(Π_k ẋ)_j| v̄_j + ½ v̄ᵀ|Π_k| v̄ (exact for a constant Π_k; the change of ω_k and Π_k
    with the position error is left out). Holding every measured margin at least that much
    above its cushion δ_i (a floor of its own beside (S1)'s, which is taken from the
    measured margin and so cannot carry (S1)'s induction to the true one) keeps the true
    margins above δ_i while the measurement errors stay inside the declared bounds (a
    Gaussian noise does not: declare a few σ and count the rest). ``slopes``: at the state,
    when the caller has them (:meth:`MarginSlopes.losses`)."""
    h, n = period, constraints.n
    p = np.zeros(n) if declared.position is None else np.broadcast_to(declared.position, (n,))
    v = np.zeros(n) if declared.velocity is None else np.broadcast_to(declared.velocity, (n,))
    reach = slopes if slopes is not None else MarginSlopes.at(constraints, state)
    return reach.losses(p + h * v, p + 0.5 * h * v, v)


class InertiaError:
    """The acceleration error of a declared error in the links' inertial parameters and of
    unmodelled joint terms (``simulation.model_error``: ``inertia``, ``armature``,
    ``damping``, ``friction``), at a state and a model acceleration.

    **The bound.** The dynamics are linear in each link's inertial parameters: link k's mass
    m_k (its centre of mass fixed, so its first moment m_k c_k scales with it) and its
    rotational inertia about the centre of mass I_k, each scaled by its own factor 1 + δ,
    |δ| ≤ e. Split link k's parameters into those two pieces p (Pinocchio's joint torque
    regressor Y(q, q̇, a) times the piece's ten parameters): w_p = Y(q, q̇, â) π_p = D_p â + b_p,
    D_p = J_kᵀ I_p J_k ⪰ 0. The plant may add, per joint, rotor inertia α_j ∈ [0, A_j],
    viscous damping up to c_j and dry friction up to F_j. Its D = D̂ + ΔD, b = b̂ + Δb with

        u = ΔD â + Δb = Σ_p δ_p w_p + α ⊙ â + f,     |f_j| ≤ c_j |q̇_j| + F_j,

    and with the same torque the accelerations differ by

        y = a − â = −D⁻¹ u = r − D̂⁻¹ ΔD y,     r = −D̂⁻¹ u,

    so |r| ≤ r̄ = e Σ_p |D̂⁻¹ w_p| + |D̂⁻¹| (A ⊙ |â| + c ⊙ |q̇| + F) and |y| ≤ r̄ + G|y| with
    G = e Σ_p |D̂⁻¹ D_p| + |D̂⁻¹| diag(A) ≥ |D̂⁻¹ΔD| entry by entry (|·| of each entry). When
    G's spectral radius is below 1, |y| ≤ (I − G)⁻¹ r̄ (the series Σ Gᵏ r̄, every term ≥ 0).
    Always, since D ⪰ (1 − e) D̂ (ΔD is the pieces' ±e share of D̂ plus α ≥ 0),
    |y_j| ≤ √(D⁻¹)_jj √(uᵀD⁻¹u) ≤ √(D̂⁻¹)_jj √(ūᵀ|D̂⁻¹|ū) / (1 − e) with ū ≥ |u| the same
    bound in torque; without added rotor inertia also −eD̂ ⪯ ΔD ⪯ eD̂, so in the norm
    ‖y‖ = √(yᵀD̂y): ‖y‖ ≤ ‖r‖/(1 − e) and |(D̂⁻¹ΔD y)_j| ≤ e √(D̂⁻¹)_jj ‖y‖, whence
    |y_j| ≤ r̄_j + e/(1 − e) √(D̂⁻¹)_jj √(r̄ᵀ|D̂|r̄). The smallest of these is ā. Computed in
    joint coordinates and carried to controller coordinates by |T|.

    It holds for the given model acceleration â: the guard takes the law's (the torque it
    keeps unless it must act); a brake's own inertia error only scales its deceleration
    (within ±e in the D̂ norm), which the braking set's share θ absorbs. The model's own
    smooth Coulomb friction is :func:`friction_error`'s; anything else the user bounds is
    ``acceleration``.

    Args:
        model: the controller's model.
        relative: e ∈ [0, 1).
        armature, damping, friction: A [kg·m²], c [N·m·s/rad], F [N·m] per joint (joint
            coordinates), or None.
    """

    def __init__(self, model: RobotModel, relative: float, armature: Array | None = None,
                 damping: Array | None = None, friction: Array | None = None) -> None:
        if not (math.isfinite(relative) and 0.0 <= relative < 1.0):
            raise ValueError(f"inertia error must be in [0, 1), got {relative}")
        self.model, self.relative = model, float(relative)
        n = model.n
        self._joint = [np.zeros(n) if v is None else np.broadcast_to(
            np.asarray(v, dtype=float), (n,)) for v in (armature, damping, friction)]
        pin_model = model.model
        self._data = pin_model.createData()
        bodies = len(pin_model.inertias) - 1
        pieces = np.zeros((10 * bodies, 2 * bodies))  # each link's mass and rotation pieces
        spatial = np.zeros((2 * bodies, 6, 6))  # each piece's spatial inertia, joint frame
        for k in range(bodies):
            link = pin_model.inertias[k + 1]
            mass = pin.Inertia(link.mass, link.lever, np.zeros((3, 3)))
            rotation = pin.Inertia(0.0, link.lever, link.inertia)
            pieces[10 * k:10 * k + 10, 2 * k] = mass.toDynamicParameters()
            pieces[10 * k:10 * k + 10, 2 * k + 1] = rotation.toDynamicParameters()
            spatial[2 * k], spatial[2 * k + 1] = mass.matrix(), rotation.matrix()
        self._pieces = pieces
        self._spatial = spatial
        self._jacobians = np.zeros((2 * bodies, 6, n))  # each piece's link's, joint frame

    def bound(self, state: ArmState, accel: Array, inverse: Array | None = None) -> Array:
        """ā of the class docstring at ``state`` for the model acceleration ``accel``
        (controller coordinates), per coordinate; ``inverse``: D⁻¹ when the caller has it."""
        e = self.relative
        coords = self.model.coordinates
        if coords.is_identity:
            q, dq, ddq, inertia = state.x, state.dx, accel, state.inertia
        else:
            t, t_inv = coords.matrix, coords.inverse
            q, dq, ddq = t_inv @ state.x, t_inv @ state.dx, t_inv @ accel
            inertia = t.T @ state.inertia @ t
        pin_model, data = self.model.model, self._data
        inv = _joint_inverse(self.model, state.inertia, inverse)[1]  # (Tᵀ D T)⁻¹
        armature, damping, friction = self._joint
        joint_force = armature * np.abs(ddq) + damping * np.abs(dq) + friction  # ≥ |α â + f|
        first = np.abs(inv) @ joint_force
        spread = np.abs(inv) * armature  # |D̂⁻¹| diag(A)
        force = joint_force.copy()
        if e > 0.0:
            per_piece = pin.computeJointTorqueRegressor(pin_model, data, q, dq, ddq) @ (
                self._pieces)
            first += e * np.abs(inv @ per_piece).sum(axis=1)
            force += e * np.abs(per_piece).sum(axis=1)
            pin.computeJointJacobians(pin_model, data, q)
            jac = self._jacobians
            for k in range(len(jac) // 2):
                jac[2 * k] = jac[2 * k + 1] = pin.getJointJacobian(
                    pin_model, data, k + 1, pin.ReferenceFrame.LOCAL)
            # e Σ_p |D̂⁻¹ D_p|, D_p = J_kᵀ I_p J_k
            pieces = np.transpose(jac, (0, 2, 1)) @ (self._spatial @ jac)
            spread += e * np.abs(np.matmul(inv, pieces)).sum(axis=0)
        diag = np.sqrt(np.diag(inv))
        out = diag * math.sqrt(float(force @ np.abs(inv) @ force)) / (1 - e)
        if not np.any(armature):  # −eD̂ ⪯ ΔD ⪯ eD̂: |(D̂⁻¹ΔD y)_j| ≤ e √(D̂⁻¹)_jj ‖y‖_D̂
            out = np.minimum(out, first + e / (1 - e) * diag * math.sqrt(
                float(first @ np.abs(inertia) @ first)))
        if _contracts(spread):
            out = np.minimum(out, np.linalg.solve(np.eye(len(first)) - spread, first))
        return out if coords.is_identity else np.abs(coords.matrix) @ out
