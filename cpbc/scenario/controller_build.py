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
from cpbc.scenario.gain_check import UnstableLoop, physical_gains, unstable_loop
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
           field: str, scale: float = 1.0) -> _Gains:
    """K_P, K_D as given, or from ω_n (times ``scale``) and ζ with D_ii at the target
    (cpbc.scenario.gain_check), divided by the law's slopes; its stiffness and damping near
    the target are K_P and K_D times them."""
    n = model.n
    if spec.kp is not None and spec.kd is not None:
        kp, kd = gain_vector(spec.kp, n, f"{field}.kp"), gain_vector(spec.kd, n, f"{field}.kd")
    else:
        omega = gain_vector(spec.omega_n, n, f"{field}.omega_n")  # type: ignore[arg-type]
        zeta = gain_vector(spec.zeta, n, f"{field}.zeta")  # type: ignore[arg-type]
        kp, kd = physical_gains(scale * omega, zeta, model.inertia(target).diagonal())
        kp, kd = kp / slopes.spring, kd / slopes.damping
    stiffness, damping = kp * slopes.spring, kd * slopes.damping
    return _Gains(kp, kd, lambda x: (stiffness, damping))


def _unstable(gains: _Gains, model: RobotModel, states: list[Array], sim: s.SimulationSpec,
              names: tuple[str, ...]) -> UnstableLoop | None:
    """The first state at which the held loop is unstable at the control period, described
    (cpbc.scenario.gain_check); None when it is stable at every one."""
    euler_step = 0.0 if sim.integrator == "RK4" else sim.timestep
    period = sim.period
    for x in states:
        stiffness, damping = gains.linear(x)
        bad = unstable_loop(stiffness, damping, [model.inertia(x)], period, names, euler_step)
        if bad is not None:
            return bad
    return None


def _check_zoh(
    gains: _Gains, model: RobotModel, states: list[Array], sim: s.SimulationSpec,
    names: tuple[str, ...], field: str, frequencies: Sequence[Frequency] = (),
) -> None:
    """Refuse gains whose held loop is unstable at the control period. Gains written as
    natural frequencies are answered in those: for each, the largest value at which, the
    others kept, the loop is stable (a default the entry did not write among them)."""
    bad = _unstable(gains, model, states, sim, names)
    if bad is None:
        return
    fixes = []
    for f in frequencies:
        def stable(k: float, f: Frequency = f) -> bool:
            try:
                return _unstable(f.gains(k), model, states, sim, names) is None
            except ScenarioError:  # gains the law refuses (a task below its posture)
                return False

        scale = _stable_scale(stable)
        if scale is not None:
            default = "" if f.given else f" (default {_times(f.value, 1.0)})"
            fixes.append(f"lower {f.name}{default} to {_times(f.value, scale)} or less")
    raise ScenarioError(field, bad.advice(", or ".join(fixes) if fixes else None)
                        + "; simulation.check_gains: false runs it anyway")


def _times(values: Array, scale: float) -> str:
    """``values`` times ``scale``, as written: one number, or a list."""
    v = np.atleast_1d(np.asarray(values, dtype=float)) * scale
    return f"{v[0]:.4g}" if v.size == 1 else "[" + ", ".join(f"{x:.4g}" for x in v) + "]"


@dataclass(frozen=True)
class Frequency:
    """A natural frequency an entry's gains are made from: its name in the scenario, its
    value, whether the entry wrote it (else it is its default), and the entry's gains with
    it scaled by k (the others kept)."""

    name: str
    value: Array
    given: bool
    gains: Callable[[float], _Gains]


def natural_frequencies(spec: s.LawSpec, kind: LawKind[Any], model: RobotModel,
                        target: Array, goal: GoalPlan | None, field: str) -> list[Frequency]:
    """The natural frequencies of an entry whose gains are written as such (``omega_n``, or
    a goal's ``task`` and ``posture``); none for an entry written as K_P and K_D."""
    slopes = kind.slopes(spec, model.n, field)
    if goal is not None and (spec.task is not None or spec.posture is not None):
        task, posture = spec.task or s.TaskGainsSpec(), spec.posture or s.PostureGainsSpec()

        def scaled(part: str, key: str) -> Callable[[float], _Gains]:
            def gains(k: float) -> _Gains:
                given = task if part == "task" else posture
                value = getattr(given, key) if getattr(given, key) is not None else task.omega_n
                changed = spec.model_copy(update={
                    "task": task, "posture": posture,
                    part: given.model_copy(update={key: k * value})})
                terms, found = law_terms(changed, model, goal, field, slopes)
                return _Gains(terms["kp"], terms["kd"],  # type: ignore[arg-type]
                              lambda x: linear_gains(model, goal, found, x))
            return gains

        out = [Frequency("task.omega_n", np.array(task.omega_n), spec.task is not None,
                         scaled("task", "omega_n"))]
        if task.rotation_omega_n is not None:
            out.append(Frequency("task.rotation_omega_n", np.array(task.rotation_omega_n),
                                 True, scaled("task", "rotation_omega_n")))
        out.append(Frequency("posture.omega_n", np.array(posture.omega_n),
                             spec.posture is not None, scaled("posture", "omega_n")))
        return out
    if goal is None and spec.kp is None and spec.omega_n is not None:
        omega = gain_vector(spec.omega_n, model.n, f"{field}.omega_n")
        shown = omega[:1] if np.all(omega == omega[0]) else omega
        return [Frequency("omega_n", shown, True,
                          lambda k: _gains(spec, slopes, model, target, field, k))]
    return []


def _stable_scale(stable: Callable[[float], bool], smallest: float = 1e-3) -> float | None:
    """The largest k in [smallest, 1) with ``stable(k)`` (k = 1 is not), to 0.1 % by
    bisection after halving down to a stable one; None when even ``smallest`` is not."""
    hi, lo = 1.0, 0.5
    while not stable(lo):
        hi, lo = lo, lo / 2
        if lo < smallest:
            return None
    while hi - lo > 1e-3 * lo:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


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


def _with_term(frequency: Frequency, term: JointLogCoshSpring | None) -> Frequency:
    """A natural frequency whose scaled gains the held-loop check sees with ``term``."""
    if term is None:
        return frequency
    scaled = frequency.gains
    return replace(frequency, gains=lambda k: _with_gains(scaled(k), term))


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
                          model_bounds, loop.bounds, field,
                          None if goal is None else goal.goal)
        law = _build_controller(cspec, kind, given)
        compensated = _compensated(cspec, kind, given, law, term)
        if check:
            extra = term if compensated else None
            frequencies = [_with_term(f, extra) for f in
                           natural_frequencies(cspec, kind, model, target, goal, field)]
            _check_zoh(_with_gains(gains, extra), model, states, sim, names, field, frequencies)
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
    period = None if guarded_loop else loop.bounds.period
    for i, (entry, spec) in enumerate(zip(controllers, specs, strict=True)):
        problem_of = kinds.law(spec.type).start_problem
        if problem_of is None:
            continue
        for case in cases:
            problem = problem_of(entry.controller, case.position, case.velocity, names,
                                 loop.bounds.torque, period)
            if problem is not None:
                raise ScenarioError(f"controllers[{i}]",
                                    f"'{entry.name}' ({spec.type}), case '{case.name}': "
                                    f"{problem}")
