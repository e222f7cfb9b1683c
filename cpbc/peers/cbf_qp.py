"""A torque-level CBF-QP safety filter around PD + gravity or an operational-space nominal:
the baseline users pick today.

At each sample it solves, with DAQP (a dense active-set solver),

    min_τ ½‖τ − τ_nom‖²,   τ_nom = g − K_P x̃ − K_D ẋ          (PD + gravity, eq. 6.10)

or, toward a task-space goal or reference (``nominal: osc``), τ_nom the operational-space
nominal of cpbc.peers.osc (OSCBF's: Jᵀ Λ a_task + Nᵀ D a_null + C ẋ + g),

subject to one row per barrier (cpbc.peers.cbf_rows: the rows, their two variants and their
equations) and the actuators' box |Tᵀτ| ≤ L when the scenario has torque limits.

**Tuning, as its users would tune it** (``variant: braking``, the default): a braking-aware
high-order CBF for every configuration constraint with the curvature term, one row per sphere
pair within the clearance's influence distance (per-link minima switch spheres and are not
smooth), k = 20 /s, β = 0.5 of the box's deceleration along each row, γ = 1/(2h) (half the
largest first-order gain a held period tolerates), and a cushion on rate rows that grows with
the period: c(h) = 2e-3 · (h / 1 ms)^1.7 rad/s, through the two cushions a practitioner
calibrates at 1 kHz (2e-3, the drift's change over 1 ms) and 100 Hz (0.1). The box is kept
hard. **Infeasible steps** (the box and the rows cannot all hold) are counted
(``infeasible``) and solved again with one free slack per configuration row, weighted 1e6
against the torque change (rows are scaled to unit norm, so the slack is in N·m), the rate
rows and the box kept hard; only if that too fails does every row get a slack. A slack spread
over every row would let a least-squares compromise spin a light wrist past its rate bound.

``variant: exponential`` is the earlier in-project filter: exponential CBFs with both poles at
−k on the reported constraints (a clearance's per-link minimum), no cushion, and on an
infeasible step the box dropped (the actuators then clip).

Only this module imports a QP solver, and only when a ``cbf_qp`` controller is built.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.rate_limit import RateLimit
from cpbc.controllers.controller import Controller, Evaluation, SafetyFilter, positive_vector
from cpbc.controllers.law_kind import LINEAR, LawInputs, LawKind
from cpbc.controllers.law_specs import ConstrainedLawSpec, PostureGainsSpec, TaskGainsSpec
from cpbc.errors import CpbcError, ParameterError, ScenarioError
from cpbc.model.input_bounds import InputBounds
from cpbc.model.robot_model import ArmState, RobotModel
from cpbc.peers.cbf_rows import Rows, Tuning, barrier_rows
from cpbc.peers.osc import OperationalSpace, OSCGains, TaskTarget
from cpbc.spec.fields import Positive

EXTRA = "pip install 'cpbc[peers]'"


class PeerUnavailable(CpbcError):
    """The optional solver a peer needs is not installed."""


def _daqp() -> Callable[..., Any]:
    try:
        import daqp  # the optional extra cpbc[peers]
    except ImportError:
        raise PeerUnavailable(
            f"the cbf_qp controller needs the DAQP solver, which is not installed: {EXTRA}"
        ) from None
    return daqp.solve


VARIANTS = ("braking", "exponential")
SLACK_WEIGHT = 1e6  # per unit row (N·m) of slack, against the torque change


DEFAULT_BOUNDS = InputBounds(1e-3)  # 1 kHz, no torque box


def default_cushion(period: float) -> float:
    """c(h) = 2e-3 · (h / 1 ms)^1.7 [rad/s]: the module docstring's calibrated cushions."""
    return 2e-3 * (period / 1e-3) ** 1.7


class CBFQP(SafetyFilter):
    """The CBF-QP filter of the module docstring.

    Args:
        model: the controller's robot model (D, C ẋ, g, f).
        target: x_d, (n,).
        constraints: the constraints to enforce — configuration constraints of any kind,
            rate limits and at most one kinetic-energy limit.
        kp, kd: gains of the PD + gravity nominal.
        gain: k [1/s] (cpbc.peers.cbf_rows).
        rate_gain: γ of the first-order rows [1/s]; 1/(2·period) when omitted.
        bounds: the control period h and the torque box L per joint (joint coordinates;
            none: no box) (cpbc.model.input_bounds); a torque-rate limit there is not
            kept by the filter (its QP has no rate rows): the plant clips to it.
        variant: ``braking`` (default) or ``exponential``.
        braking_share: β, the share of the box's deceleration a braking row counts on.
        rate_cushion: c on rate rows; default_cushion(period) when omitted (braking only).
        osc: an operational-space nominal (cpbc.peers.osc) in place of PD + gravity; the
            filter's value is then its closed-loop energy, and kp the posture spring's.
    """

    type_name = "cbf_qp"

    def __init__(
        self, model: RobotModel, target: Array, constraints: ConstraintSet, kp: object,
        kd: object, gain: float = 20.0, rate_gain: float | None = None,
        bounds: InputBounds = DEFAULT_BOUNDS, variant: str = "braking",
        braking_share: float = 0.5, rate_cushion: float | None = None,
        osc: OperationalSpace | None = None,
    ) -> None:
        super().__init__(model, target, constraints)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        if variant not in VARIANTS:
            raise ParameterError("variant", f"one of {VARIANTS}, not {variant!r}")
        if not 0 < braking_share <= 1:
            raise ParameterError("braking_share", f"must be in (0, 1], got {braking_share}")
        if rate_cushion is not None and not rate_cushion >= 0:
            raise ParameterError("rate_cushion", f"must be ≥ 0, got {rate_cushion}")
        for v in constraints.velocity:
            if not isinstance(v, RateLimit | KineticEnergyLimit):
                raise ParameterError("constraints", f"cbf_qp keeps rate and kinetic-energy "
                                     f"limits only, not {type(v).__name__} {v.names}")
        self.variant = variant
        self._given = (rate_gain, rate_cushion)
        limit = None if bounds.torque is None else np.broadcast_to(bounds.torque, (model.n,))
        self.torque_limit = limit
        self.tuning = Tuning(variant, float(positive_vector(gain, 1, "gain")[0]), 0.0,
                             float(braking_share), 0.0, limit)
        self._set_period(bounds.period)
        coords = model.coordinates
        self._box_rows = None if coords.is_identity else np.ascontiguousarray(coords.matrix.T)
        self._solve = _daqp()
        self.osc = osc
        self.acted = 0
        self.infeasible = 0
        self.rows_active = 0

    @property
    def row_active_steps(self) -> int:
        """Steps at which the barrier rows changed the torque: the solution differs from the
        nominal projected on the torque box alone (or the step was infeasible). ``acted``
        counts the box's clip of the nominal too."""
        return self.rows_active

    def _set_period(self, period: float) -> None:
        rate_gain, cushion = self._given
        rate = 0.5 / period if rate_gain is None else rate_gain
        if self.variant == "exponential":
            cushion = 0.0 if cushion is None else cushion
        elif cushion is None:
            cushion = default_cushion(period)
        gamma = float(positive_vector(rate, 1, "rate_gain")[0])
        self.tuning = replace(self.tuning, rate_gain=gamma, rate_cushion=float(cushion))

    @property
    def gain(self) -> float:
        return self.tuning.gain

    @property
    def rate_gain(self) -> float:
        return self.tuning.rate_gain

    def restarted(self) -> CBFQP:
        out = copy.copy(self)
        out.acted = out.infeasible = out.rows_active = 0
        return out

    def at_period(self, period: float) -> CBFQP:
        """The same filter at another control period (its default γ and cushion follow)."""
        out = self.restarted()
        out._set_period(period)
        return out

    @property
    def frames(self) -> tuple[int, ...]:
        return () if self.osc is None else self.osc.frames

    @property
    def reads_motion(self) -> bool:
        """Its rows read φ, ∇φ and ẋᵀ∇²φ ẋ (cpbc.peers.cbf_rows) from the per-step state."""
        return True

    def follow(self, target: TaskTarget) -> None:
        """Steer the operational-space nominal to a moving reference's target (written in
        place each step by cpbc.reference); a PD + gravity nominal has no task to steer."""
        if self.osc is None:
            raise CpbcError("cbf_qp: a moving reference needs the operational-space nominal "
                            "(nominal: osc)")
        self.osc.follow(target)

    def nominal(self, state: ArmState) -> Array:
        """τ_nom = g − K_P x̃ − K_D ẋ, or the operational-space nominal."""
        return self._nominal(state)[0]

    def _nominal(self, state: ArmState) -> tuple[Array, float]:
        """τ_nom and the nominal's value: ½ẋᵀDẋ + ½x̃ᵀK_Px̃ for PD + g."""
        if self.osc is not None:
            return self.osc.evaluate(state)
        err = state.x - self.target
        value = 0.5 * float(state.dx @ state.inertia @ state.dx) + 0.5 * float(
            err @ (self.kp * err))
        return state.gravity - self.kp * err - self.kd * state.dx, value

    def rows(self, state: ArmState) -> tuple[Array, Array, Array]:
        """The barrier rows: A (m, n), lower (m,), upper (m,) with lower ≤ A τ ≤ upper."""
        r = barrier_rows(self.tuning, self.constraints, state)
        return r.a, r.lower, r.upper

    def _bounded(self, a: Array, lower: Array, upper: Array, slack: NDArray[np.bool_] | None
                 ) -> tuple[Array, Array, Array]:
        """The rows with the box first (DAQP's simple bounds when T = I), and with ``slack``
        (a mask of rows) one free slack variable per masked row: lower ≤ a τ + s ≤ upper."""
        n = self.model.n
        if slack is not None:
            a = np.hstack([a, np.eye(len(lower))[:, slack]])
        if self.torque_limit is None:
            return a, lower, upper
        lim = self.torque_limit * (1 - 1e-9)  # the solver's tolerance inside the box
        lower, upper = np.concatenate([-lim, lower]), np.concatenate([lim, upper])
        if self._box_rows is not None:
            pad = np.zeros((n, a.shape[1] - n))
            a = np.vstack([np.hstack([self._box_rows, pad]), a])
        return a, lower, upper

    def _qp(self, nominal: Array, a: Array, lower: Array, upper: Array, box: bool,
            slack: NDArray[np.bool_] | None = None) -> tuple[Array, int]:
        n = self.model.n
        if box:
            a, lower, upper = self._bounded(a, lower, upper, slack)
        weights = np.ones(a.shape[1])
        weights[n:] = SLACK_WEIGHT
        linear = np.zeros(len(weights))
        linear[:n] = -nominal
        z, _, flag, _ = self._solve(np.diag(weights), linear, np.ascontiguousarray(a),
                                    upper, lower, np.zeros(len(upper), dtype=np.int32))
        return np.asarray(z)[:n], int(flag)

    def _box_only(self, nominal: Array) -> Array:
        """The nominal projected on the torque box alone (no barrier rows): what the filter
        would apply if no row were there."""
        if self.torque_limit is None:
            return nominal
        if self._box_rows is None:
            lim = self.torque_limit * (1 - 1e-9)
            return np.clip(nominal, -lim, lim)
        empty = np.zeros((0, self.model.n))
        tau, flag = self._qp(nominal, empty, np.zeros(0), np.zeros(0), box=True)
        return tau if flag == 1 else nominal

    def _fallback(self, nominal: Array, rows: Rows) -> Array:
        """An infeasible step: braking keeps the box and relaxes the configuration rows
        (then every row, if the rate rows alone contradict the box); exponential drops the
        box; τ_nom (clipped to a simple box) if even that fails."""
        a, lower, upper = rows.a, rows.lower, rows.upper
        if self.variant == "braking":
            tau, flag = self._qp(nominal, a, lower, upper, box=True, slack=rows.soft)
            if flag != 1:
                everything = np.ones(len(lower), dtype=bool)
                tau, flag = self._qp(nominal, a, lower, upper, box=True, slack=everything)
        else:
            tau, flag = self._qp(nominal, a, lower, upper, box=False)
        if flag == 1:
            return tau
        if self.torque_limit is None or self._box_rows is not None:
            return nominal
        return np.clip(nominal, -self.torque_limit, self.torque_limit)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        nominal, value = self._nominal(state)
        rows = barrier_rows(self.tuning, self.constraints, state)
        tau, flag = self._qp(nominal, rows.a, rows.lower, rows.upper, box=True)
        feasible = flag == 1
        if not feasible:  # counted as a step it acted on, of which it could not meet all
            self.infeasible += 1
            tau = self._fallback(nominal, rows)
        tol = 1e-9 * (1 + np.max(np.abs(nominal)))
        if not feasible or np.max(np.abs(tau - nominal)) > tol:
            self.acted += 1
            if not feasible or np.max(np.abs(tau - self._box_only(nominal))) > tol:
                self.rows_active += 1
        found = self.constraints.margins(state.x, state.dx, state) if margins else None
        return Evaluation(tau, value, found)


# -- the scenario's ``type: cbf_qp`` (cpbc.controllers.law_kind): PD + gravity — or, toward a
# goal or reference, an operational-space nominal (cpbc.peers.osc) — filtered by the QP on the
# same constraint objects as the laws. The solver is imported when one is built. ----------
class CBFQPSpec(ConstrainedLawSpec):
    """The CBF-QP peer (cpbc.peers.cbf_qp): PD + gravity, or an operational-space nominal
    toward a goal or reference, filtered by a QP."""

    type: Literal["cbf_qp"] = Field(
        description=(
            "the torque-level CBF-QP safety filter around PD + gravity (needs the peers "
            "extra)"))
    nominal: Literal["pd_gravity", "osc"] = Field(
        default="pd_gravity", description=(
            "the torque it filters: pd_gravity (g − K_P x̃ − K_D ẋ toward target:) or osc "
            "(operational-space control toward goal: or reference:, with task: and posture: "
            "gains; cpbc.peers.osc)"))
    # cpbc.peers.cbf_rows
    variant: Literal["braking", "exponential"] = Field(
        default="braking", description=(
            "braking (default) or exponential: the earlier filter"))
    # k [1/s]: α'(0) of the braking rows, or the exponential poles
    gain: Positive = Field(
        default=20.0, description=(
            "k [1/s]: α'(0) of the braking rows, or the exponential variant's double pole"))
    # γ of the first-order rows [1/s]; 1/(2h) when omitted
    rate_gain: Positive | None = Field(
        default=None, description=(
            "γ of the first-order rows [1/s]; 1/(2h) when omitted"))
    # β: share of the box's deceleration
    braking_share: float = Field(
        default=0.5, gt=0, le=1, description=(
            "β ∈ (0, 1]: the share of the torque box's deceleration a braking row counts on"))
    # c on rate rows; 2e-3 (h/1 ms)^1.7
    rate_cushion: float | None = Field(
        default=None, ge=0, description=(
            "c on rate rows [rad/s]; 2e-3 (h / 1 ms)^1.7 when omitted"))


def _nominal(spec: CBFQPSpec, given: LawInputs) -> OperationalSpace | None:
    """The operational-space nominal (``nominal: osc``) toward the goal with the law's task
    and posture gains, or None for PD + gravity."""
    field = f"{given.field}.nominal"
    if spec.nominal == "pd_gravity":
        if given.goal is not None:
            raise ScenarioError(field, "with goal: or reference:, cbf_qp filters an "
                                "operational-space nominal: set nominal: osc")
        return None
    if given.goal is None:
        raise ScenarioError(field, "osc steers a frame: give goal: or reference: in place "
                            "of target:, or nominal: pd_gravity")
    task, posture = spec.task or TaskGainsSpec(), spec.posture or PostureGainsSpec()
    return OperationalSpace(given.model, given.goal, given.target, OSCGains(
        task.omega_n, task.zeta, task.rotation_omega_n or task.omega_n, posture.omega_n,
        posture.zeta))


def build_cbf_qp(spec: CBFQPSpec, given: LawInputs) -> Controller:
    osc = _nominal(spec, given)
    cons = given.constraint_set(spec.constraints)
    try:
        return CBFQP(given.model, given.target, cons, given.gains["kp"], given.gains["kd"],
                     spec.gain, spec.rate_gain, given.bounds, spec.variant,
                     spec.braking_share, spec.rate_cushion, osc)
    except PeerUnavailable as exc:
        raise ScenarioError(f"{given.field}.type", str(exc)) from None


KINDS = (LawKind(CBFQPSpec, build_cbf_qp, slopes=LINEAR,
                 examples={"cbf_qp": {"constraints": ["limits", "rates"]}},
                 goal_types=("cbf_qp",)),)
