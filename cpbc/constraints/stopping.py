"""Can the actuators stop in time? A first-order stopping test for configuration constraints
under bounded torque (viability is part of the admissible set: what no torque can stop is
already lost).

With |τ_q| ≤ L the arm can only decelerate so fast, so a state close to a boundary φ_i = 0
and approaching it fast is lost whatever any controller does. For one constraint, with the
dynamics frozen at the state (D, b = C ẋ + g + f) and τ = T⁻ᵀ τ_q in controller coordinates,

    φ̈_i = ∇φ_i · D⁻¹ (τ − b) + ẋᵀ ∇²φ_i ẋ,

and the largest φ̈_i any torque in the box gives is

    a_i = Σ_j |w_j| L_j − ∇φ_i · D⁻¹ b + κ_i,     w = T⁻¹ D⁻¹ ∇φ_iᵀ,

with κ_i = ẋᵀ∇²φ_i ẋ (``ConfigurationConstraint.curvature``; 0 where not given). Approaching
at v_i = −∇φ_i · ẋ > 0 under the largest constant φ̈_i, φ_i falls by v_i² / (2 a_i) before
φ̇_i = 0, so a state with

    s_i = φ_i − v_i² / (2 a_i) ≤ 0      (or a_i ≤ 0 and v_i > 0)

cannot be kept inside φ_i > 0 by any held torque in the box, to first order. This is a
necessary condition for viability, not a sufficient one: it treats each constraint alone
(one torque must stop all of them), freezes D and b over the stop, and leaves out the
curvature of constraints that do not give it (clearance). States that fail it are refused
as initial states; states that pass it may still be lost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.kernels.braking_path import brake_ramp, uniform_deceleration
from cpbc.kernels.stopping_test import stopping_rows
from cpbc.model.robot_model import ArmState, RobotModel


def stopping_margins(
    constraints: ConstraintSet, model: RobotModel, x: Array, dx: Array, torque_limit: Array
) -> tuple[Array, Array, Array]:
    """s_i of the module docstring for every configuration constraint (in the order of
    their names), with the approach speeds v_i and the largest decelerations a_i.

    Args:
        constraints: the constraints (their configuration part is tested).
        model: the controller's model (D, b at the state).
        x, dx: the state, controller coordinates.
        torque_limit: L, joint coordinates, shape (n,) [N·m].
    """
    if not constraints.configuration:
        empty = np.zeros(0)
        return empty, empty, empty
    state = model.state(x, dx)
    bias = state.coriolis_force + state.gravity + state.dissipation
    margins, speed, decel, _ = stopping_terms(constraints, model, state, bias, torque_limit)
    return margins, speed, decel


_NO_MAP = np.zeros((0, 0))  # T⁻¹ as the kernel reads it in joint coordinates (unread)


def stopping_terms(constraints: ConstraintSet, model: RobotModel, state: ArmState,
                   bias: Array, torque_limit: Array) -> tuple[Array, Array, Array, Array]:
    """:func:`stopping_margins` at a per-step state whose bias b is known, with the
    gradients ∇φ_i as well (rows): φ, ∇φ and ẋᵀ∇²φ ẋ from each constraint's
    ``motion_terms`` (:func:`motion_rows`); the rest in one compiled call
    (cpbc.kernels.stopping_test.stopping_rows)."""
    phi, grads, curvature, state = motion_rows(constraints, model, state)
    margins, speed, decel = np.empty(len(phi)), np.empty(len(phi)), np.empty(len(phi))
    stopping_rows(phi, grads, curvature, state.inertia, bias, state.dx,
                  *stopping_map(model, torque_limit), margins, speed, decel)
    return margins, speed, decel, grads


def motion_rows(constraints: ConstraintSet, model: RobotModel, state: ArmState
                ) -> tuple[Array, Array, Array, ArmState]:
    """φ, ∇φ (rows) and ẋᵀ∇²φ ẋ of every configuration constraint from its
    ``motion_terms`` (the state's kinematics, no Pinocchio pass of their own; a state
    built without what they read is built again, by ``ConstraintSet.state``, and
    returned): what cpbc.kernels.stopping_test reads at a state."""
    lacks_frames = any(f not in state.frames for f in constraints.frames)
    if lacks_frames or (constraints.motion_kinematics and state.joint_jacobians is None):
        state = constraints.state(model, state.x, state.dx, motion=True)
    terms = [c.motion_terms(state) for c in constraints.configuration]
    phi = np.concatenate([t[0] for t in terms])
    grads = np.ascontiguousarray(np.concatenate([t[1] for t in terms]), dtype=float)
    curvature = np.concatenate([t[2] for t in terms])
    return phi, grads, curvature, state


def stopping_map(model: RobotModel, torque_limit: Array | float) -> tuple[Array, bool, Array]:
    """T⁻¹ (writable; unread in joint coordinates), whether the coordinates map, and the
    joints' torque limits L, one per joint: what cpbc.kernels.stopping_test reads of the
    model and the box."""
    coords = model.coordinates
    inverse = _NO_MAP if coords.is_identity else np.array(coords.inverse)
    limit = np.asarray(torque_limit, dtype=float)
    if limit.shape != (model.n,):  # one limit for every joint
        limit = np.full(model.n, float(torque_limit))
    return inverse, not coords.is_identity, limit


# -- the braking set: what the safeguard keeps invariant under bounded torque ----------------
@dataclass(frozen=True, eq=False)
class Braking:
    """The uniform brake within the torque box, and the point where it stops the arm.

    The test above is necessary, not sufficient: it lends every constraint the whole box at
    once. The safeguard brakes with one torque for all of them, the *uniform brake*

        τ = b − a D ẋ/|ẋ|,   b = C ẋ + g + f,   so that   ẍ = −a ẋ/|ẋ|,

    which slows every coordinate in proportion to its speed: it never spins a joint up
    through D, it keeps every rate and kinetic-energy margin growing, and with the dynamics
    frozen it moves the arm along the straight segment ahead of ẋ. The largest deceleration
    the box |Tᵀτ| ≤ L allows it is, with u = Tᵀ D ẋ/|ẋ| and β = Tᵀ b,

        A(x, ẋ) = min_j (L_j + sign(u_j) β_j) / |u_j|,

    (≤ 0 where b alone does not fit: nothing holds the arm). Braking with a share θ of it,
    the arm stops at

        x_s = x + ẋ |ẋ| / (2θA),

    and the *braking margins* σ_i = φ_i(x_s) are the configuration margins there. The set
    V = {(x, ẋ) ∈ S : σ_i > 0 for every i} is the one the safeguard keeps invariant: it
    holds σ as it holds every margin (its condition (S1)), and the uniform brake at full
    deceleration A > θA moves x_s back along ẋ, by (1/θ − 1) h (|ẋ| − ½hA) per period
    (frozen dynamics), so σ can always be kept from shrinking by braking. θ < 1 absorbs
    what freezing D, b and A over the stop gets wrong. A state outside V is refused as an
    initial state: the uniform brake cannot stop it in time (another brake within the box may:
    :mod:`cpbc.constraints.brakes`, which the safeguard's rescue holds there).

    Under a torque-rate limit |τ̇_q| ≤ ρ the brake is not there at once: from the torque τ_h
    the actuators hold it takes T = max_j |τ_b,j − τ_h,j| / ρ_j to build (:meth:`ramp`; 87 ms
    for 87 N·m at 1000 N·m/s), and the stopping point moves ahead by what the arm travels
    meanwhile (cpbc.kernels.braking_path.configuration_rows), so V shrinks with τ_max/ρ.

    Attributes:
        limit: L, the joint torque limits, shape (n,) [N·m].
        to_joint: Tᵀ of τ_q = Tᵀ τ, or None for joint coordinates.
        share: θ ∈ (0, 1].
        rate: ρ, the joint torque-rate limits, shape (n,) [N·m/s], or None.
        disturbance: ā, a bound on the model's acceleration error per coordinate (a
            declared model error), or None: the deceleration along the motion is lowered by
            its share Σ_j |ẋ_j| ā_j / |ẋ| (the error's most against the brake).
    """

    limit: Array
    to_joint: Array | None = None
    share: float = 0.8
    rate: Array | None = None
    disturbance: Array | None = None
    # L and Tᵀ as the kernel reads them (writable float copies; 0 × 0 for joint coordinates)
    _packed: tuple[Array, Array] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not 0.0 < self.share <= 1.0:
            raise ValueError(f"braking share must be in (0, 1], got {self.share}")
        object.__setattr__(self, "_packed", (
            np.array(self.limit, dtype=float),
            np.zeros((0, 0)) if self.to_joint is None else np.array(self.to_joint, dtype=float)))

    @classmethod
    def of(cls, model: RobotModel, limit: Array | float, share: float = 0.8,
           rate: Array | None = None, disturbance: Array | None = None) -> Braking:
        """The brake of ``model`` (its coordinates) within joint torque limits ``limit`` (and
        torque-rate limits ``rate``, and a model error ``disturbance``)."""
        coords = model.coordinates
        full = np.broadcast_to(np.asarray(limit, dtype=float), (model.n,)).copy()
        return cls(full, None if coords.is_identity else coords.matrix.T.copy(), share,
                   None if rate is None else np.broadcast_to(
                       np.asarray(rate, dtype=float), (model.n,)).copy(),
                   None if disturbance is None else np.broadcast_to(
                       np.asarray(disturbance, dtype=float), (model.n,)).copy())

    def ramp(self, inertia: Array, bias: Array, dx: Array, held: Array,
             per_speed: float) -> float:
        """T: the time the uniform brake b − θA D ẋ/|ẋ| takes to build from the torque
        ``held`` (controller coordinates) at the rate limit, 0 without one (``per_speed`` =
        1/(2θA), from :meth:`per_speed`; cpbc.kernels.braking_path.brake_ramp)."""
        if self.rate is None:
            return 0.0
        return brake_ramp(inertia, bias, dx, held, per_speed, self._packed[1],
                          self.to_joint is not None, self.rate)

    def deceleration(self, inertia: Array, bias: Array, dx: Array) -> float:
        """A: the largest deceleration along ẋ of the uniform brake (inf at rest;
        cpbc.kernels.braking_path.uniform_deceleration), less a model error's share along
        the motion (``disturbance``)."""
        a = uniform_deceleration(inertia, bias, dx, *self._packed, self.to_joint is not None)
        if self.disturbance is None or a == math.inf:
            return a
        speed = math.sqrt(float(dx.dot(dx)))
        return a - float(np.abs(dx).dot(self.disturbance)) / speed

    def per_speed(self, inertia: Array, bias: Array, dx: Array) -> float:
        """1/(2θA), so that x_s = x + (|ẋ|/(2θA)) ẋ; 0 at rest, inf where the box leaves
        no deceleration."""
        a = self.deceleration(inertia, bias, dx)
        if a == math.inf:
            return 0.0
        if not a > 0.0:
            return math.inf
        return 1.0 / (2.0 * self.share * a)

    def margins(self, constraints: ConstraintSet, model: RobotModel, x: Array,
                dx: Array, held: Array | None = None,
                period: float = 0.0) -> tuple[Array, float]:
        """σ_i for every configuration constraint (in the order of their names), and the
        distance |x_s − x| the brake travels [controller units]. Under a torque-rate limit
        the brake first ramps from the torque ``held`` (the gravity torque when omitted)
        for :meth:`ramp` plus one ``period``, the arm coasting meanwhile."""
        if not constraints.configuration:
            return np.zeros(0), 0.0
        state = model.state(x, dx)
        bias = state.coriolis_force + state.gravity + state.dissipation
        per_speed = self.per_speed(state.inertia, bias, dx)
        if per_speed == math.inf:
            return np.full(constraints.n_configuration, -math.inf), math.inf
        speed = math.sqrt(float(dx.dot(dx)))
        lead = 0.0 if self.rate is None or per_speed == 0.0 else period + self.ramp(
            state.inertia, bias, dx, state.gravity if held is None else held, per_speed)
        return constraints.configuration_margins(x + (lead + per_speed * speed) * dx), \
            (lead + per_speed * speed) * speed
