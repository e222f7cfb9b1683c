"""Re-centred barrier PBC for joint position limits (Cases 2–3 of §6.3.1, eqs. 6.53–6.65).

The one law of Chapter 6 with a unique minimum (f is strictly convex, Lemma 6.10) and hence
guaranteed asymptotic stability — in continuous time, with the whole of τ applied.
Generalised from symmetric limits |x_i| < X_i to lower_i < x_i < upper_i by centring:
z = x − c, w = (upper − lower)/2, and each factor normalised to 1 at the centre,

    Φ(z) = Π (1 − z_i²/w_i²),   f(x) = zᵀK_P z / (2Φ)                          (6.54)
    ∇f  = [K_P z + (zᵀK_P z) z / (w² − z²)] / Φ      (elementwise division)      (6.55)

The thesis's factors ½(X_i² − z_i²) differ only by the constants X_i²/2, which rescale
K_P; normalising keeps K_P's meaning of a PD gain at the centre of the range (without
velocity constraints: Ψ below rescales it again).

    V = ½ẋᵀDẋ / Ψ + f(x) − f(x_d) − ∇f(x_d)ᵀ(x − x_d)                          (6.61)
    τ = g + c + D (D + KΠ)⁻¹ (a − c),  K = ½ẋᵀDẋ,  c = Cẋ + f,
    a = −K_D ẋ + K b_ψ − Ψ (∇f(x) − ∇f(x_d))                                   (6.63)

which reduces to τ = g − K_D ẋ − ∇f(x) + ∇f(x_d) (6.57) without velocity constraints.
V̇ = −ẋᵀ(K_D ẋ + f)/Ψ ≤ 0 (eq. 6.64).

**What the product barrier does on a 6- or 7-joint arm.** (6.55) splits joint i's force as

    ∇f_i = K_P,i z_i / Φ  +  E z_i / ((w_i² − z_i²) Φ),     E = zᵀK_P z = Σ_j K_P,j z_j²

the first a P-action on joint i's own distance to the *centre* of its range, the second a
share of every joint's error energy E, independent of joint i's own gain; and 1/Φ
multiplies both by a factor of every joint. At rest (6.57) commands τ − g = ∇f(x_d) − ∇f(x),
the difference of two such forces, which is K_P x̃ only when x and x_d are both near the
centre. With K_P = D_ii ω_n² the shoulder gains are 10²–10⁴ times the wrist gains, so the
shoulders' energy, divided by a wrist's w_i², outweighs the wrist's own term by that ratio:
on the UR3 (ranges ±2π, ±π) with ω_n = 10, ζ = 1 and the target at the centre, a start 1 rad
off on every joint gives the wrists 5.0–5.9 N·m where K_P x̃ is 0.09–0.76 N·m, and 1.5 rad
off gives the elbow 145 N·m (K_P x̃: 18) and 1.01 × its 150 N·m effort limit; on the xArm7,
0.5 rad off already needs 2.1 × its effort limits. Near x_d the law's stiffness is ∇²f(x_d),
not K_P: 34 × K_P on a UR3 joint with x_d 1 rad from the centre, 913 × on the xArm7. The
wrists (inertia ~10⁻³ kg·m²) then reach their rate bounds within one control period.
With velocity constraints (6.63) multiplies the potential force by Ψ = Π ψ_j, the thesis's
unnormalised ψ_j = ½(B_j² − ẋ_j²) for a rate bound: at rest τ − g = Ψ(x, 0)(∇f(x_d) − ∇f(x)),
so the stiffness near the target is Ψ(x_d, 0)∇²f(x_d) while K_D is not scaled — Π ½B_j² is
0.0324 in ``planar_recentred`` (bounds 0.6 rad/s), 0.885 on the UR3 at half its rate limits,
4.3 on the xArm7 at half its, 7 × 10⁴ at its full 3.14 rad/s.
This is the law, not a slip in the code: the gradient matches a finite difference of f to
10⁻⁹ (tests/test_recentred_arms.py). :meth:`RecentredBarrier.start_problem` states, from a
start state, when the law cannot be run: it commands more than the torque limit, or (the bare
law, without the safeguard) its first held torque breaks one of its velocity constraints.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from pydantic import Field

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import BarrierTerms, ConstraintSet
from cpbc.constraints.linear_limit import LinearLimit
from cpbc.controllers.controller import Controller, Evaluation, positive_vector
from cpbc.controllers.law_kind import LINEAR, LawInputs, LawKind
from cpbc.controllers.law_specs import ConstrainedLawSpec
from cpbc.controllers.linalg import solve_spd
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model.robot_model import ArmState, RobotModel


class RecentredBarrier(Controller):
    """Re-centred barrier law for joint limits, optionally with velocity constraints."""

    type_name = "recentred"

    def __init__(
        self,
        model: RobotModel,
        target: Array,
        constraints: ConstraintSet,
        kp: object,
        kd: object,
    ) -> None:
        super().__init__(model, target, constraints)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        limits = constraints.configuration
        joint_limits = [
            c for c in limits
            if isinstance(c, LinearLimit)
            and np.all(np.count_nonzero(c.rows, axis=1) == 1)
            and np.allclose(np.abs(c.rows).sum(axis=1), 1.0)
        ]
        if not limits or len(joint_limits) != len(limits):
            raise CpbcError(
                "recentred (Cases 2–3) enforces joint position limits (joint_position_limit) "
                "and optionally velocity constraints; obstacle and combination limits need cpbc"
            )
        self.joints = np.concatenate([np.argmax(np.abs(c.rows), axis=1) for c in joint_limits])
        if len(set(self.joints.tolist())) != len(self.joints):
            raise CpbcError("recentred: a joint has more than one position limit")
        self.centre = np.concatenate([c.centre for c in joint_limits])
        self.half_width = np.concatenate([c.half_width for c in joint_limits])
        self._limit_names = [name for c in limits for name in c.names]
        self._velocity = ConstraintSet(model.n, velocity=constraints.velocity)
        self._f_target, self._grad_target = self._barrier_potential(self.target)

    def _pieces(self, x: Array) -> tuple[Array, Array, float, Array, float]:
        """z, the gaps w² − z², 1/Φ, K_P z and the energy zᵀK_P z of (6.54)–(6.55) on the
        limited joints; ConstraintViolation outside a limit."""
        z = x[self.joints] - self.centre
        gap = self.half_width**2 - z * z
        if not np.all(gap > 0):
            i = int(np.argmin(gap))
            raise ConstraintViolation(self._limit_names[i], float(gap[i]))
        inv_phi = math.exp(-float(np.sum(np.log(gap / self.half_width**2))))
        kz_sel = self.kp[self.joints] * z
        return z, gap, inv_phi, kz_sel, float(z @ kz_sel)

    def _barrier_potential(self, x: Array) -> tuple[float, Array]:
        """f(x) and ∇f(x) of (6.54)–(6.55)."""
        z, gap, inv_phi, kz_sel, energy = self._pieces(x)
        kz = np.zeros_like(x)
        kz[self.joints] = kz_sel + energy * z / gap
        return 0.5 * energy * inv_phi, kz * inv_phi

    def force_parts(self, x: Array) -> tuple[Array, Array, float]:
        """The two parts of ∇f(x) = own + shared (module docstring, eq. 6.55) and Φ(x):
        own_i = K_P,i z_i / Φ and shared_i = (zᵀK_P z) z_i / ((w_i² − z_i²) Φ), shape (n,),
        zero on coordinates without a position limit."""
        z, gap, inv_phi, kz_sel, energy = self._pieces(x)
        own, shared = np.zeros_like(x), np.zeros_like(x)
        own[self.joints] = kz_sel * inv_phi
        shared[self.joints] = energy * z / gap * inv_phi
        return own, shared, 1.0 / inv_phi

    def start_problem(self, state: ArmState, names: Sequence[str],
                      torque_limit: Array | None = None, period: float | None = None
                      ) -> str | None:
        """Why the law cannot be run from ``state`` (a case's start), or None.

        1. With ``torque_limit`` (joint coordinates): some |τ_q,i| of the law at the start
           exceeds limit_i. The actuators would clip it, and V̇ ≤ 0 (6.58, 6.64) needs the
           whole of τ.
        2. With ``period`` h (the bare law, no safeguard): under the held τ the model
           predicts, with the dynamics frozen at the sample, ẋ(h) = ẋ + h D⁻¹(τ − Cẋ − g − f)
           outside one of the law's velocity constraints: the barrier of (6.63) has had no
           chance to act.

        ``names`` labels the coordinates (controller coordinates).
        """
        tau = self.evaluate_state(state).torque
        problem = None
        if torque_limit is not None:
            problem = self._over_limit(state, tau, names, np.asarray(torque_limit, float))
        if problem is None and period is not None and self._velocity.velocity:
            problem = self._first_period(state, tau, period)
        return problem

    def _over_limit(self, state: ArmState, tau: Array, names: Sequence[str], limit: Array
                    ) -> str | None:
        """Reason 1 of :meth:`start_problem`, with the parts of τ − g at the worst joint."""
        to_joint = self.model.coordinates.torque_to_joint
        tau_q, g_q = to_joint(tau), to_joint(state.gravity)
        ratio = np.abs(tau_q) / limit
        i = int(np.argmax(ratio))
        if not ratio[i] > 1.0:
            return None
        room = (limit - np.abs(g_q)) / np.maximum(np.abs(tau_q - g_q), 1e-300)
        scale = float(np.min(room))
        identity = self.model.coordinates.is_identity
        k = i if identity else int(np.argmax(np.abs(tau - state.gravity)))
        joint = f"'{names[i]}'" if identity else f"joint {i}"
        own, shared, phi = self.force_parts(state.x)
        psi = self._psi(state)
        fix = (f"kp at most {scale:.3g} × (omega_n {math.sqrt(scale):.3g} ×) its value"
               if scale > 0 else "any kp (gravity alone is over the limit)")
        return (
            f"the law commands {abs(tau_q[i]):.4g} N·m on {joint} at the start, "
            f"{ratio[i]:.3g} × its torque limit {limit[i]:.4g} N·m (τ = "
            f"{np.array2string(tau, precision=3, separator=', ')}); the actuators would clip it "
            "and (6.58)/(6.64) would not hold. At rest τ − g = Ψ(∇f(x_d) − ∇f(x)) (6.57, 6.63); "
            f"on '{names[k]}' the joint's own term −ΨK_P z/Φ is {-psi * own[k]:.4g}, the error "
            f"energy of all joints −Ψ(zᵀK_P z) z/((w² − z²)Φ) is {-psi * shared[k]:.4g} and the "
            f"target's Ψ∇f(x_d) is {psi * self._grad_target[k]:.4g} N·m, with Φ(x) = {phi:.3g}"
            f" and Ψ = {psi:.3g}: the product barrier (6.54) hands every joint the error energy "
            "of all of them, measured from the centres of the ranges. Bring the target and the "
            "cases nearer the centres of the ranges, use cpbc, or fit the torque at rest "
            f"(τ − g scales with K_P) with {fix}"
        )

    def _psi(self, state: ArmState) -> float:
        """Ψ at the state: Π ψ_j of the velocity constraints, 1 without them."""
        if not self._velocity.velocity:
            return 1.0
        return math.exp(self._velocity.barrier(state).log_psi)

    def _predicted(self, state: ArmState, tau: Array, h: float) -> Array:
        """The law's velocity margins after a held period h (frozen dynamics)."""
        bias = state.coriolis_force + state.gravity + state.dissipation
        acc = solve_spd(state.inertia, tau - bias)
        x1 = state.x + h * state.dx + 0.5 * h * h * acc
        dx1 = state.dx + h * acc
        later = self.model.state(x1, dx1) if self._velocity.needs_dynamics else None
        return self._velocity.velocity_margins(x1, dx1, later)

    def _first_period(self, state: ArmState, tau: Array, period: float) -> str | None:
        """Reason 2 of :meth:`start_problem`, with the longest period that would hold."""
        margins = self._predicted(state, tau, period)
        if np.all(margins > 0):
            return None
        j = int(np.argmin(margins))
        lo, hi = 0.0, period
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if np.all(self._predicted(state, tau, mid) > 0) else (lo, mid)
        return (
            f"the bare law (simulation.safeguard: false) breaks {self._velocity.names[j]} within "
            f"its first control period from the start: it commands τ = "
            f"{np.array2string(tau, precision=3, separator=', ')} N·m and the model predicts the "
            f"margin {margins[j]:.3g} after h = {period:g} s (below {lo:.2g} s it would hold). "
            "The product barrier (6.54) hands every joint the error energy of all of them, "
            "and the light wrist joints accelerate past their rate bounds before the velocity "
            "barrier of (6.63) can act. Turn the safeguard on, shorten simulation.control_period, "
            "bring the target and the cases nearer the centres of the ranges, or lower kp"
        )

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        f, grad = self._barrier_potential(state.x)  # raises outside the limits
        x, dx = state.x, state.dx
        bar = self._velocity.barrier(state) if self._velocity.velocity else None
        kinetic = 0.5 * float(dx @ state.inertia @ dx)
        tau = self._law(state, grad, kinetic, bar)
        shift = f - self._f_target - float(self._grad_target @ (x - self.target))
        psi = 1.0 if bar is None else math.exp(bar.log_psi)
        found = self.constraints.margins(x, dx, state) if margins else None
        return Evaluation(tau, kinetic / psi + shift, found)

    def _law(self, state: ArmState, grad: Array, kinetic: float, bar: BarrierTerms | None
             ) -> Array:
        """(6.57) without velocity constraints, (6.63) with them (module docstring)."""
        a = -self.kd * state.dx
        if bar is None:
            return state.gravity + a - grad + self._grad_target
        a = a - math.exp(bar.log_psi) * (grad - self._grad_target)
        if bar.gradient is not None:
            a += kinetic * bar.gradient
        c = state.coriolis_force + state.dissipation
        assert bar.weight is not None  # velocity constraints give Π
        y = solve_spd(state.inertia + kinetic * bar.weight, a - c)
        return state.gravity + c + state.inertia @ y


# -- the scenario's ``type: recentred`` (cpbc.controllers.law_kind) --------------------------
class RecentredSpec(ConstrainedLawSpec):
    type: Literal["recentred"] = Field(
        description=(
            "the re-centred barrier (Cases 2–3, eqs. 6.53–6.65): joint_position_limit and "
            "velocity constraints"))


def build_recentred(spec: RecentredSpec, given: LawInputs) -> Controller:
    gains: dict[str, Any] = dict(given.gains)
    return RecentredBarrier(given.model, given.target, given.constraint_set(spec.constraints),
                            **gains)


def start_problem_of(law: Controller, x: Array, dx: Array, names: tuple[str, ...],
                     torque_limit: Array | None, period: float | None) -> str | None:
    """RecentredBarrier.start_problem: the torque limit and, in a loop without the safeguard,
    the first held period against its velocity constraints."""
    assert isinstance(law, RecentredBarrier)
    return law.start_problem(law.state(x, dx), names, torque_limit, period)


KINDS = (LawKind(RecentredSpec, build_recentred, slopes=LINEAR,
                 examples={"recentred": {"constraints": ["limits", "rates"]}},
                 start_problem=start_problem_of),)
