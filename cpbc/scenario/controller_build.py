"""The controllers of an arm scenario: gains, the held-loop check, the laws and the
CBF-QP peer, built on the scenario's constraints."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import (
    ConfigurationConstraint,
    ConstraintSet,
    VelocityConstraint,
)
from cpbc.controllers import CONTROLLERS, Controller, Identity, Power, RecentredBarrier, Tanh
from cpbc.controllers.shaping import Shaping
from cpbc.errors import CpbcError, InadmissibleStateError, ScenarioError
from cpbc.model import RobotModel
from cpbc.model.bounds import ModelBounds, estimate_bounds
from cpbc.scenario import schema as s
from cpbc.scenario.arm_setup import CaseEntry, ControllerEntry
from cpbc.scenario.gains import physical_gains, unstable_loop
from cpbc.scenario.goal import GoalPlan, law_terms, linear_gains, peer_nominal
from cpbc.simulation import LoopSettings


def _shaping(spec: s.ShapingSpec | None) -> Shaping:
    if spec is None or isinstance(spec, s.IdentityShapingSpec):
        return Identity()
    if isinstance(spec, s.PowerShapingSpec):
        return Power(spec.alpha)
    return Tanh(spec.sigma)


def _gain_vector(value: float | list[float], n: int, field: str) -> Array:
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise ScenarioError(field, f"needs 1 or {n} entries (one per coordinate), got {a.size}")
    return a


@dataclass(frozen=True)
class _Gains:
    """K_P, K_D of a law, and its linear stiffness and damping near the target."""

    kp: Array
    kd: Array
    stiffness: Array
    damping: Array


def _gains(spec: s.ControllerSpec, model: RobotModel, target: Array, field: str) -> _Gains:
    """K_P, K_D as given, or from ω_n and ζ with D_ii at the target (cpbc.scenario.gains)."""
    n = model.n
    xi = gamma = np.ones(n)
    if isinstance(spec, s.BPBCSpec):  # K_P tanh(Ξx̃), K_D tanh(Γẋ): slopes K_P Ξ, K_D Γ
        xi = _gain_vector(spec.xi, n, f"{field}.xi")
        gamma = _gain_vector(spec.gamma, n, f"{field}.gamma")
    if spec.kp is not None and spec.kd is not None:
        kp, kd = _gain_vector(spec.kp, n, f"{field}.kp"), _gain_vector(spec.kd, n, f"{field}.kd")
    else:
        omega = _gain_vector(spec.omega_n, n, f"{field}.omega_n")  # type: ignore[arg-type]
        zeta = _gain_vector(spec.zeta, n, f"{field}.zeta")  # type: ignore[arg-type]
        kp, kd = physical_gains(omega, zeta, np.diag(model.inertia(target)))
        kp, kd = kp / xi, kd / gamma
    return _Gains(kp, kd, kp * xi, kd * gamma)


def _check_zoh(
    gains: _Gains, model: RobotModel, states: list[Array], sim: s.SimulationSpec,
    names: tuple[str, ...], field: str,
) -> None:
    """Refuse gains whose held loop is unstable at the control period (cpbc.scenario.gains)."""
    euler_step = 0.0 if sim.integrator == "RK4" else sim.timestep
    bad = unstable_loop(gains.stiffness, gains.damping, [model.inertia(x) for x in states],
                        sim.control_period or sim.timestep, names, euler_step)
    if bad is not None:
        raise ScenarioError(field, bad.advice() + "; simulation.check_gains: false runs it "
                            "anyway")


def _controller_constraints(
    spec: s.CPBCSpec | s.RecentredSpec | s.BPBCSpec | s.CBFQPSpec, n: int,
    constraints: dict[str, ConfigurationConstraint | VelocityConstraint], field: str,
) -> ConstraintSet:
    chosen = list(constraints) if spec.constraints is None else spec.constraints
    unknown = [c for c in chosen if c not in constraints]
    if unknown:
        raise ScenarioError(
            f"{field}.constraints",
            f"unknown constraint names {unknown}; the scenario defines {list(constraints)}",
        )
    objs = [constraints[c] for c in chosen]
    return ConstraintSet(
        n,
        [o for o in objs if isinstance(o, ConfigurationConstraint)],
        [o for o in objs if isinstance(o, VelocityConstraint)],
    )


def _build_controller(
    spec: s.PDSpec | s.CPBCSpec | s.RecentredSpec | s.BPBCSpec,
    model: RobotModel,
    target: Array,
    gains: _Gains,
    constraints: dict[str, ConfigurationConstraint | VelocityConstraint],
    model_bounds: Callable[[], ModelBounds],
    field: str,
    terms: dict[str, object] | None = None,
) -> Controller:
    cls = CONTROLLERS[spec.type]
    kwargs: dict[str, object] = terms or {"kp": gains.kp, "kd": gains.kd}
    if not isinstance(spec, s.PDSpec):
        kwargs["constraints"] = _controller_constraints(spec, model.n, constraints, field)
        if not isinstance(spec, s.RecentredSpec):
            kwargs["shaping"] = _shaping(spec.shaping)
    if isinstance(spec, s.BPBCSpec):
        kwargs.update(xi=spec.xi, gamma=spec.gamma, model_bounds=model_bounds())
    try:
        return cls(model, target, **kwargs)  # type: ignore[arg-type]
    except InadmissibleStateError:
        raise
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)  # set by a ParameterError
        where = f"{field}.{parameter}" if parameter in type(spec).model_fields else field
        raise ScenarioError(where, str(exc)) from None


def _build_peer(
    spec: s.CBFQPSpec, model: RobotModel, target: Array, gains: _Gains,
    constraints: dict[str, ConfigurationConstraint | VelocityConstraint], loop: LoopSettings,
    field: str, goal: GoalPlan | None = None,
) -> Controller:
    """The CBF-QP peer (cpbc.peers, imported only here, when a scenario asks for it) on the
    same constraint objects as the laws, the loop's control period and torque box; with a
    goal, around the operational-space nominal."""
    from cpbc.peers import CBFQP, PeerUnavailable

    cons = _controller_constraints(spec, model.n, constraints, field)
    osc = peer_nominal(spec, goal, field)
    try:
        return CBFQP(model, target, cons, gains.kp, gains.kd, spec.gain, spec.rate_gain,
                     loop.control_period, loop.torque_limit, spec.variant,
                     spec.braking_share, spec.rate_cushion, osc)
    except PeerUnavailable as exc:
        raise ScenarioError(f"{field}.type", str(exc)) from None
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)
        raise ScenarioError(f"{field}.{parameter}" if parameter else field, str(exc)) from None


def build_controllers(
    scenario: s.Scenario, model: RobotModel, target: Array, cases: list[CaseEntry],
    built: dict[str, ConfigurationConstraint | VelocityConstraint], names: tuple[str, ...],
    loop: LoopSettings, goal: GoalPlan | None = None,
) -> list[ControllerEntry]:
    bounds_cache: list[ModelBounds] = []

    def model_bounds() -> ModelBounds:
        if not bounds_cache:
            bounds_cache.append(estimate_bounds(model))
        return bounds_cache[0]

    sim = scenario.simulation
    check = sim.check_gains and sim.backend == "mujoco"  # the reference holds nothing
    states = [target] + [c.position for c in cases]
    controllers = []
    for i, cspec in enumerate(scenario.controllers):
        field = f"controllers[{i}]"
        terms = None
        if goal is not None:
            terms, task = law_terms(cspec, model, goal, field)
            stiffness, damping = linear_gains(model, goal, task)
            gains = _Gains(terms["kp"], terms["kd"], stiffness, damping)  # type: ignore[arg-type]
        elif cspec.task is not None or cspec.posture is not None:
            raise ScenarioError(f"{field}.task", "task and posture gains need a goal: give "
                                "goal: {frame, position, ...} in place of target:, or kp, kd")
        else:
            gains = _gains(cspec, model, target, field)
        if check:
            _check_zoh(gains, model, states, sim, names, field)
        if isinstance(cspec, s.CBFQPSpec):
            ctrl = _build_peer(cspec, model, target, gains, built, loop, field, goal)
        else:
            ctrl = _build_controller(cspec, model, target, gains, built, model_bounds, field,
                                     terms)
        controllers.append(ControllerEntry(cspec.name or cspec.type, ctrl))
    if len({c.name for c in controllers}) != len(controllers):
        raise ScenarioError("controllers", "controller names must be unique; set 'name' on each")
    return controllers


def check_recentred(controllers: list[ControllerEntry], cases: list[CaseEntry],
                     model: RobotModel, loop: LoopSettings, names: tuple[str, ...],
                     guarded_loop: bool) -> None:
    """Refuse a ``recentred`` law that cannot be run from a case's start
    (RecentredBarrier.start_problem: the torque limit; without the safeguard, the first
    held period against its velocity constraints)."""
    period = None if guarded_loop else loop.control_period
    for i, entry in enumerate(controllers):
        law = entry.controller
        if not isinstance(law, RecentredBarrier):
            continue
        for case in cases:
            state = law.state(case.position, case.velocity)
            problem = law.start_problem(state, names, loop.torque_limit, period)
            if problem is not None:
                raise ScenarioError(f"controllers[{i}]",
                                    f"'{entry.name}' (recentred), case '{case.name}': {problem}")
