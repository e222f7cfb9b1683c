"""What a run did, judged from its data: status, settle time, peaks, margins, V.

``RunSummary`` is the one record of a run, an arm's (``summarise``) or a Part I
system's (cpbc.results.system_metrics): the same status vocabulary and the same fields where
they apply, a Part I run's own quantities in its ``SystemOutcome`` (``system``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.constraint_types import Array
from cpbc.constraints.margins import BY_KEY
from cpbc.controllers.controller import Controller
from cpbc.results.margin_types import WorstMargin, physical_history, types_of, worst_by_type
from cpbc.simulation.trajectory import Trajectory

STATUSES = ("converged", "reached", "tracked", "blocked", "unreachable", "stalled", "held",
            "not_settled", "constraint_violated", "diverged")
#: The statuses of a run that ended where it was sent (a joint target, a task goal, the end
#: of a reference).
ARRIVED = ("converged", "reached", "tracked")


@dataclass(frozen=True)
class SettleCriteria:
    """When a run counts as settled.

    Attributes:
        position_tolerance: ‖x − x_d‖∞ below this counts as on target [rad].
        velocity_tolerance: ‖ẋ‖∞ below this counts as at rest [rad/s].
        stall_window: fraction of the run at its end in which a stalled arm stays at rest
            without its error shrinking by more than ``stall_progress``.
        stall_progress: relative error decrease that still counts as no progress.
    """

    position_tolerance: float = 0.01
    velocity_tolerance: float = 0.005
    stall_window: float = 0.2
    stall_progress: float = 0.02


@dataclass(frozen=True)
class SystemOutcome:
    """What a Part I system's run has beyond an arm's fields (cpbc.results.system_metrics).

    Attributes:
        peaks, bounds: per constrained quantity, max |value| and the bound on |value| (of the
            side of an asymmetric interval the run came nearer to, in proportion).
        peak_abs, final_state: max |value| and last value of every state component and the
            input (the wheel's speed among them).
        design_bounds: the thesis's a-priori bounds evaluated for the gains (name → value).
        limits_reached: the plant's limits (the stall, the elevator's travel) the run reached:
            reported, not violations.
        crossed_at: first sample at which a constrained quantity was at its bound [s].
    """

    peaks: dict[str, float]
    bounds: dict[str, float]
    peak_abs: dict[str, float]
    final_state: dict[str, float]
    design_bounds: dict[str, float]
    limits_reached: list[str]
    crossed_at: float | None


@dataclass(frozen=True)
class RunSummary:
    """One controller on one case.

    Rates and torques are in the controller's coordinates x = T q, except ``torque_limits``
    and ``peak_joint_torques``, which are per joint (motor); for arms controlled in joint
    coordinates (T = I) the two agree. ``peak_torques`` is the torque applied (after the
    plant's torque limit), ``peak_commanded_torques`` what the controller asked for, and
    ``peak_torque_norm`` the largest ‖τ‖ commanded (what a theoretical ``torque_bound``
    bounds). ``min_margins`` are distances to the bounds in each constraint type's unit
    (``margin_types``; see cpbc.results.margin_types), ``margin_units`` their units.

    A Part I system's run (``system`` set) fills the fields that apply: its input u as the
    torques (one column), its constrained quantities' margins (type "other", each in its own
    unit), ``final_error`` the largest judged component at the end; it has no joint rates
    (empty lists), no V (NaN, null in JSON), no safeguard, contacts or saturation counted
    (0), and ``steps_per_second`` None on the reference backend, whose samples are not steps.
    """

    controller: str
    controller_type: str
    case: str
    backend: str
    status: str
    end_time: float
    violated_constraint: str | None
    final_error: float
    settle_time: float | None
    peak_joint_rates: list[float]
    rate_bounds: list[float | None]
    peak_torques: list[float]
    peak_commanded_torques: list[float]
    peak_joint_torques: list[float]
    torque_limits: list[float | None] | None
    peak_torque_norm: float
    torque_bound: float | None
    min_margins: dict[str, float]
    margin_types: dict[str, str]
    crossed_constraints: list[str]
    enforced_constraints: list[str]
    max_lyapunov_increase: float
    initial_lyapunov: float
    max_contacts: int
    saturated_steps: int
    wall_time: float
    control_steps: int
    steps_per_second: float | None
    extra: dict[str, float] = field(default_factory=dict)
    safeguard_steps: int = 0
    safeguard_infeasible: int = 0
    # control steps at which the safeguard held its rescue's brake (cpbc.controllers.rescue)
    rescues: int = 0
    # control steps that spent the safeguard's budget of tests (its test_budget)
    out_of_tests: int = 0
    rejected_samples: int = 0
    # why a failed run likely failed, when something before the run foresaw it (gravity
    # beyond a motor on the way to the target: cpbc.scenario.preflight); None otherwise
    cause: str | None = None
    # a goal run's task-space outcome (cpbc.results.task_metrics): errors {position m,
    # angle rad}, the reach time, and why it rests away from the goal; None for joint runs
    stall_kind: str | None = None
    task_error_final: dict[str, float] | None = None
    task_error_rms: dict[str, float] | None = None
    # per joint, the largest change of the applied joint torque between control instants over
    # the period, the first from the torque held before the run [N·m/s] (None: not measured,
    # the reference backend); the motors' rate limits (None: none); the steps at which the
    # plant's rate limit clipped the command
    peak_torque_rate: list[float] | None = None
    torque_rate_limits: list[float] | None = None
    rate_limited_steps: int = 0
    # the controller's (law and safeguard) longest and mean call in the loop [µs]: against
    # a control deadline (None on the reference backend)
    controller_time_max_us: float | None = None
    controller_time_mean_us: float | None = None
    task_error_max: dict[str, float] | None = None
    reach_time: float | None = None
    # a reference run's (cpbc.results.reference_metrics): the error to the applied reference
    # [m], the path lag t − s_v [s], the governor's slowed and blocked time [s], and the
    # constraint that blocked it with {time, path_time}; None for other runs
    tracking_error_applied_rms: float | None = None
    path_lag_final: float | None = None
    path_lag_max: float | None = None
    governor: dict[str, float] | None = None
    blocked_by: str | None = None
    blocked_at: dict[str, float] | None = None
    # every margin's unit (the unit of its type for an arm's, the quantity's own for a
    # Part I system's)
    margin_units: dict[str, str] = field(default_factory=dict)
    # a Part I system's run: its own quantities; None for an arm's
    system: SystemOutcome | None = None
    # an arm's joints as the model and the plant had them (cpbc.model.joint_dynamics):
    # ``friction`` {coulomb, viscous (per joint), smoothing ε, compensation ε_c or None}
    # and the rotor inertia ``armature`` per joint; None for a Part I system's run
    friction: dict[str, object] | None = None
    armature: list[float] | None = None

    @property
    def safeguard_share(self) -> float:
        """Fraction of the control steps at which the safeguard changed the law's torque."""
        return self.safeguard_steps / self.control_steps if self.control_steps else 0.0

    @property
    def failed(self) -> bool:
        """Whether the run ended short of the target with the actuators out of room: a
        crossed constraint, a diverged state, or a stop away from the target with saturated
        torques or a safeguard that found no torque to keep S."""
        if self.status in ("constraint_violated", "diverged"):
            return True
        return self.status not in ARRIVED and bool(self.saturated_steps
                                                   or self.safeguard_infeasible)

    def worst_margins(self) -> list[WorstMargin]:
        """Per constraint type, the constraint that came nearest its bound; a Part I
        system's few quantities one by one (each with its own type and unit)."""
        if self.system is None:
            return worst_by_type(self.min_margins, self.margin_types)
        return [WorstMargin(self.margin_types[n], self.margin_units.get(n, ""), n, v)
                for n, v in self.min_margins.items()]

    def as_dict(self) -> dict[str, object]:
        out = {k: _plain(v) for k, v in self.__dict__.items() if k != "system"}
        out["system"] = None if self.system is None else _plain(dict(self.system.__dict__))
        out["safeguard_share"] = self.safeguard_share
        out["worst_margins"] = [_plain(dict(w.__dict__)) for w in self.worst_margins()]
        return out


def _plain(v: object) -> object:
    if isinstance(v, float):
        return v if math.isfinite(v) else None  # JSON has no NaN or infinity
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v


def margin_history(monitor: ConstraintSet, traj: Trajectory) -> Array:
    """Every monitored constraint's margin at every sample, shape (N, m), as a distance to
    its bound in its type's unit (cpbc.results.margin_types)."""
    return physical_history(monitor, monitor.margins_along(traj.position, traj.velocity))


def _guard_share(traj: Trajectory, fraction: float) -> float:
    """The share of the control steps in the last ``fraction`` of the run at which the
    safeguard replaced the law's torque."""
    steps = traj.guarded_steps
    if steps is None or not steps.size:
        return 0.0
    return float(steps[int(len(steps) * (1.0 - fraction)):].mean())


def judge_status(
    traj: Trajectory, target: Array, criteria: SettleCriteria
) -> tuple[str, float | None]:
    """Status and settle time from the data (not from what the theory promises)."""
    if traj.outcome in ("diverged", "constraint_violated"):
        return traj.outcome, None
    err = np.max(np.abs(traj.position - target), axis=1)
    speed = np.max(np.abs(traj.velocity), axis=1)
    inside = err < criteria.position_tolerance
    settle: float | None = None
    if inside[-1]:
        outside = np.nonzero(~inside)[0]
        settle = float(traj.time[outside[-1] + 1]) if outside.size else 0.0
    if inside[-1] and speed[-1] < criteria.velocity_tolerance:
        return "converged", settle
    window = max(2, int(len(err) * criteria.stall_window))
    at_rest = np.all(speed[-window:] < criteria.velocity_tolerance)
    progress = (err[-window] - err[-1]) / max(err[-window], 1e-12)
    if at_rest and progress < criteria.stall_progress:
        # at rest away from the target: the law's own equilibrium, or the safeguard's hold
        return ("held" if _guard_share(traj, criteria.stall_window) > 0.5 else "stalled"), None
    return "not_settled", settle


def summarise(
    name: str,
    case: str,
    controller: Controller,
    monitor: ConstraintSet,
    traj: Trajectory,
    criteria: SettleCriteria,
    rate_bounds: list[float | None],
    margins: Array | None = None,
    torque_limits: Array | None = None,
    coordinates: Array | None = None,
    lengths: Array | None = None,
    torque_rate_limits: Array | None = None,
) -> RunSummary:
    """Condense a trajectory into a RunSummary.

    Args:
        margins: ``margin_history`` of the run, when already computed.
        torque_limits: the plant's joint torque limits, shape (n,), or None.
        coordinates: T of x = T q (the identity when omitted).
        lengths: which coordinates are lengths (RobotModel.length_coordinates), for the
            margins' units; all angles when omitted.
        torque_rate_limits: the plant's joint torque-rate limits, shape (n,), or None.
    """
    margins = margin_history(monitor, traj) if margins is None else margins
    lyapunov = traj.lyapunov
    status, settle = judge_status(traj, controller.target, criteria)
    finite_tau = np.where(np.isfinite(traj.torque), traj.torque, 0.0)
    applied_q = np.where(np.isfinite(traj.joint_torque), traj.joint_torque, 0.0)
    # τ_q = Tᵀ τ_x, so the applied torque in the controller's coordinates is τ_q T⁻¹ per row.
    applied = applied_q if coordinates is None else np.linalg.solve(
        np.asarray(coordinates, dtype=float).T, applied_q.T).T
    limits = None if torque_limits is None else [
        float(v) if np.isfinite(v) else None  # JSON has no infinity: null, no limit there
        for v in np.broadcast_to(np.asarray(torque_limits, dtype=float),
                                 (traj.joint_torque.shape[1],))]
    min_margins = {
        n: float(np.nanmin(margins[:, i])) if np.any(np.isfinite(margins[:, i])) else float("nan")
        for i, n in enumerate(monitor.names)
    }
    dv = np.diff(lyapunov)
    dv = dv[np.isfinite(dv)]
    types = dict(zip(monitor.names, types_of(monitor, lengths), strict=True))
    return RunSummary(
        controller=name,
        controller_type=controller.type_name,
        case=case,
        backend=traj.backend,
        status=status,
        end_time=traj.end_time,
        violated_constraint=traj.violated,
        final_error=float(np.max(np.abs(traj.position[-1] - controller.target))),
        settle_time=settle,
        peak_joint_rates=np.max(np.abs(traj.velocity), axis=0).tolist(),
        rate_bounds=rate_bounds,
        peak_torques=_peaks(applied),
        peak_commanded_torques=_peaks(finite_tau),
        peak_joint_torques=_peaks(applied_q),
        torque_limits=limits,
        peak_torque_norm=float(np.max(np.linalg.norm(finite_tau, axis=1))),
        torque_bound=controller.torque_bound,
        min_margins=min_margins,
        margin_types=types,
        crossed_constraints=[n for n, v in min_margins.items() if v <= 0],
        enforced_constraints=list(controller.constraints.names),
        max_lyapunov_increase=float(max(dv.max(), 0.0)) if dv.size else 0.0,
        initial_lyapunov=float(lyapunov[0]) if lyapunov.size else float("nan"),
        max_contacts=traj.max_contacts,
        saturated_steps=traj.saturated_steps,
        wall_time=traj.wall_time,
        control_steps=traj.control_steps,
        steps_per_second=traj.steps_per_second,
        safeguard_steps=traj.safeguard_steps,
        safeguard_infeasible=traj.safeguard_infeasible,
        rescues=getattr(traj, "rescues", 0),
        out_of_tests=getattr(traj, "out_of_tests", 0),
        rejected_samples=traj.rejected_samples,
        margin_units={n: BY_KEY[t].unit for n, t in types.items()},
        peak_torque_rate=None if traj.peak_torque_rate is None else [
            float(v) for v in traj.peak_torque_rate],
        torque_rate_limits=None if torque_rate_limits is None else [
            float(v) for v in torque_rate_limits],
        rate_limited_steps=traj.rate_limited_steps,
        controller_time_max_us=_us(traj.controller_time_max),
        controller_time_mean_us=_us(traj.controller_time_mean),
    )


def _us(seconds: float | None) -> float | None:
    return None if seconds is None else 1e6 * seconds


def _peaks(values: Array) -> list[float]:
    """Largest magnitude of every column (0 for an empty log)."""
    return np.max(np.abs(values), axis=0).tolist() if len(values) else [0.0] * values.shape[1]
