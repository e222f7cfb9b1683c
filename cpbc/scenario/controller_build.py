"""The controllers of an arm scenario, each built by its law kind (cpbc.scenario.schema.kinds): the
gains (given, or from ω_n and ζ through the slopes the kind declares), the held-loop check,
and the law on the scenario's constraints."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import ConfigurationConstraint, VelocityConstraint
from cpbc.controllers import Controller
from cpbc.controllers.law_kind import LawInputs, Slopes, gain_vector
from cpbc.controllers.potentials import JointLogCoshSpring, total
from cpbc.controllers.potentials.friction import friction_compensation
from cpbc.errors import CpbcError, InadmissibleStateError, ScenarioError
from cpbc.model import RobotModel
from cpbc.model.bounds import ModelBounds, estimate_bounds
from cpbc.scenario import schema as s
from cpbc.scenario.arm_setup import CaseEntry, ControllerEntry
from cpbc.scenario.gain_check import physical_gains, unstable_loop
from cpbc.scenario.goal_build import GoalPlan, law_terms, linear_gains
from cpbc.scenario.joint_dynamics_setup import friction_spec
from cpbc.scenario.schema.kinds import KINDS, Kinds, LawKind
from cpbc.simulation import LoopSettings


@dataclass(frozen=True)
class _Gains:
    """K_P, K_D of a law, and its linear stiffness and damping at a state: constant for a
    joint-space law, through J(x) for a goal law's task springs."""

    kp: Array
    kd: Array
    linear: Callable[[Array], tuple[Array, Array]]


def _gains(spec: s.LawSpec, slopes: Slopes, model: RobotModel, target: Array,
           field: str) -> _Gains:
    """K_P, K_D as given, or from ω_n and ζ with D_ii at the target (cpbc.scenario.gain_check),
    divided by the law's slopes; its stiffness and damping near the target are K_P and K_D
    times them."""
    n = model.n
    if spec.kp is not None and spec.kd is not None:
        kp, kd = gain_vector(spec.kp, n, f"{field}.kp"), gain_vector(spec.kd, n, f"{field}.kd")
    else:
        omega = gain_vector(spec.omega_n, n, f"{field}.omega_n")  # type: ignore[arg-type]
        zeta = gain_vector(spec.zeta, n, f"{field}.zeta")  # type: ignore[arg-type]
        kp, kd = physical_gains(omega, zeta, model.inertia(target).diagonal())
        kp, kd = kp / slopes.spring, kd / slopes.damping
    stiffness, damping = kp * slopes.spring, kd * slopes.damping
    return _Gains(kp, kd, lambda x: (stiffness, damping))


def _check_zoh(
    gains: _Gains, model: RobotModel, states: list[Array], sim: s.SimulationSpec,
    names: tuple[str, ...], field: str,
) -> None:
    """Refuse gains whose held loop is unstable at the control period (cpbc.scenario.gain_check)."""
    euler_step = 0.0 if sim.integrator == "RK4" else sim.timestep
    period = sim.control_period or sim.timestep
    for x in states:
        stiffness, damping = gains.linear(x)
        bad = unstable_loop(stiffness, damping, [model.inertia(x)], period, names, euler_step)
        if bad is not None:
            raise ScenarioError(field, bad.advice() + "; simulation.check_gains: false runs "
                                "it anyway")


def _compensation(scenario: s.Scenario, model: RobotModel, target: Array,
                  goal: GoalPlan | None) -> JointLogCoshSpring | None:
    """The potential that beats the joints' Coulomb friction toward ``target``
    (cpbc.controllers.potentials.friction), for a joint-target scenario whose model has
    Coulomb friction and does not turn it off; None otherwise. It is a term in the joints:
    the controller's coordinates must be the joints'."""
    spec = friction_spec(scenario.robot)
    if goal is not None or not spec.compensate or not np.any(model.coulomb_friction):
        return None
    if not model.coordinates.is_identity:
        raise ScenarioError("robot.friction.compensate", "the Coulomb friction's compensation "
                            "is a term in the joints: use robot.coordinates: joint, or set "
                            "compensate: false")
    return friction_compensation(target, model.coulomb_friction, spec.compensation_width)


def _with_gains(gains: _Gains, term: JointLogCoshSpring | None) -> _Gains:
    """The gains the held-loop check sees: with the compensation, its stiffness at the
    target F̂_c/ε_c added to the law's (its linearisation at x̃ = 0)."""
    if term is None:
        return gains
    extra = term.stiffness * term.xi
    linear = gains.linear
    return _Gains(gains.kp, gains.kd, lambda x: (linear(x)[0] + extra, linear(x)[1]))


def _compensated(spec: s.LawSpec, kind: LawKind[Any], given: LawInputs, law: Controller,
                 term: JointLogCoshSpring | None) -> Controller | None:
    """The law built again with the compensation added to its potential, when the law has
    a potential and its kind passes one on (cpbc.scenario.goal_build.law_terms gives one
    the same way); None for a law without (the re-centred barrier, the CBF-QP)."""
    potential = getattr(law, "potential", None)
    if term is None or potential is None:
        return None
    summed = total(potential, term)
    again = _build_controller(spec, kind, replace(given, gains={**given.gains,
                                                                "potential": summed}))
    return again if getattr(again, "potential", None) is summed else None


def _build_controller(spec: s.LawSpec, kind: LawKind[Any], given: LawInputs) -> Controller:
    """The kind's law of an entry; the law's own errors name the entry's key they come from."""
    try:
        return kind.build(spec, given)
    except (InadmissibleStateError, ScenarioError):
        raise
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)  # set by a ParameterError
        where = f"{given.field}.{parameter}" if parameter in type(spec).model_fields else (
            given.field)
        raise ScenarioError(where, str(exc)) from None


def _entry_gains(spec: s.LawSpec, kind: LawKind[Any], model: RobotModel, target: Array,
                 goal: GoalPlan | None, kinds: Kinds, field: str
                 ) -> tuple[_Gains, dict[str, object] | None]:
    """An entry's gains for the held-loop check and, with a goal, the law's task terms."""
    slopes = kind.slopes(spec, model.n, field)
    if goal is not None:
        if spec.type not in kind.goal_types:
            raise ScenarioError(f"{field}.type", f"'{spec.type}' takes no goal; with goal: "
                                f"use one of {', '.join(kinds.goal_types)}")
        terms, task = law_terms(spec, model, goal, field, slopes)
        return _Gains(terms["kp"], terms["kd"],  # type: ignore[arg-type]
                      lambda x: linear_gains(model, goal, task, x)), terms
    if spec.task is not None or spec.posture is not None:
        raise ScenarioError(f"{field}.task", "task and posture gains need a goal: give "
                            "goal: {frame, position, ...} in place of target:, or kp, kd")
    return _gains(spec, slopes, model, target, field), None


def build_controllers(
    scenario: s.Scenario, model: RobotModel, target: Array, cases: list[CaseEntry],
    built: dict[str, ConfigurationConstraint | VelocityConstraint], names: tuple[str, ...],
    loop: LoopSettings, goal: GoalPlan | None = None, kinds: Kinds = KINDS,
) -> list[ControllerEntry]:
    bounds_cache: list[ModelBounds] = []

    def model_bounds() -> ModelBounds:
        if not bounds_cache:
            bounds_cache.append(estimate_bounds(model))
        return bounds_cache[0]

    sim = scenario.simulation
    check = sim.check_gains and sim.backend == "mujoco"  # the reference holds nothing
    states = [target] + [c.position for c in cases]
    term = _compensation(scenario, model, target, goal)
    controllers = []
    for i, cspec in enumerate(scenario.controllers):
        field = f"controllers[{i}]"
        kind = kinds.law(cspec.type)
        gains, terms = _entry_gains(cspec, kind, model, target, goal, kinds, field)
        given = LawInputs(model, target, terms or {"kp": gains.kp, "kd": gains.kd}, built,
                          model_bounds, loop.control_period, loop.torque_limit, field,
                          None if goal is None else goal.goal)
        law = _build_controller(cspec, kind, given)
        compensated = _compensated(cspec, kind, given, law, term)
        if check:
            _check_zoh(_with_gains(gains, term if compensated else None), model, states, sim,
                       names, field)
        controllers.append(ControllerEntry(
            cspec.name or cspec.type, law if compensated is None else compensated,
            None if compensated is None else friction_spec(scenario.robot).compensation_width))
    if len({c.name for c in controllers}) != len(controllers):
        raise ScenarioError("controllers", "controller names must be unique; set 'name' on each")
    return controllers


def check_starts(controllers: list[ControllerEntry], specs: Sequence[s.LawSpec],
                 cases: list[CaseEntry], loop: LoopSettings, names: tuple[str, ...],
                 guarded_loop: bool, kinds: Kinds = KINDS) -> None:
    """Refuse a law that says it cannot be run from a case's start (its kind's
    ``start_problem``: the recentred law's torque limit and, without the safeguard, its
    first held period)."""
    period = None if guarded_loop else loop.control_period
    for i, (entry, spec) in enumerate(zip(controllers, specs, strict=True)):
        problem_of = kinds.law(spec.type).start_problem
        if problem_of is None:
            continue
        for case in cases:
            problem = problem_of(entry.controller, case.position, case.velocity, names,
                                 loop.torque_limit, period)
            if problem is not None:
                raise ScenarioError(f"controllers[{i}]",
                                    f"'{entry.name}' ({spec.type}), case '{case.name}': "
                                    f"{problem}")
