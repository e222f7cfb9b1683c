"""Building a Part I scenario (a ``system:`` block) into a
:class:`~cpbc.scenario.system_setup.SystemSetup`: the plant of each case, the laws, and what
the results layer shows of them (panels, the phase portrait, the a-priori bounds); the
Aerosonde's in cpbc.scenario.aerosonde_build.

Every check that refuses the scenario raises :class:`~cpbc.errors.ScenarioError` naming the
YAML field, before anything runs.
"""

from __future__ import annotations

from pathlib import Path

from cpbc.backstepping import (
    ChainGains,
    DesignError,
    IntegratorChainController,
    LogBarrier,
    OutsideDomainError,
    QuadraticTerm,
    ReactionWheelController,
    SuspensionController,
    SuspensionGains,
    WheelPendulumGains,
)
from cpbc.backstepping.parameter_constraints import worst_case
from cpbc.errors import ScenarioError
from cpbc.results.system_metrics import Panel, SystemView
from cpbc.scenario.aerosonde_build import build_aerosonde
from cpbc.scenario.schema import (
    AerosondeSpec,
    IntegratorChainSpec,
    QuarterCarSpec,
    ReactionWheelSpec,
    SystemCaseSpec,
    SystemScenario,
)
from cpbc.scenario.system_setup import (
    SystemCase,
    SystemLaw,
    SystemSetup,
    check_backend,
    check_length,
    gain_error,
)
from cpbc.systems import (
    HaversineBump,
    IntegratorChain,
    QuarterCar,
    ReactionWheelPendulum,
)
from cpbc.systems.ode_plant import OdePlant


def _suspension(spec: QuarterCarSpec) -> tuple[list[SystemLaw], SystemView]:
    laws: list[SystemLaw] = []
    for i, law in enumerate(spec.laws):
        try:
            gains = SuspensionGains(**law.gains.model_dump())
            barrier = LogBarrier(gains.k2, gains.k3) if law.barrier else QuadraticTerm(gains.k3)
            ctrl = SuspensionController(gains, barrier=barrier)
        except DesignError as exc:
            raise gain_error(f"system.laws[{i}]", exc) from None
        if law.barrier and ctrl.travel_bound > spec.travel_limit * (1 + 1e-12):
            raise ScenarioError(
                f"system.laws[{i}].gains",
                f"k2 + c1 = {ctrl.travel_bound:.6g} m exceeds travel_limit "
                f"{spec.travel_limit:.6g} m: the law (3.84) keeps |x3| < k2 + c1 only",
            )
        laws.append(SystemLaw(law.name, ctrl, law.barrier))
    first = next((la for la in spec.laws if la.barrier), spec.laws[0]).gains
    view = SystemView(
        panels=(
            Panel("suspension travel x3 [mm]", 2, 1e3, spec.travel_limit),
            Panel("body acceleration ẋ4 = −u [m/s²]", None, -1.0),
            Panel("tire deflection x1 [mm]", 0, 1e3),
        ),
        phase=None, judged=(0, 1, 2, 3), angles=(),
        design_bounds={"(3.84) k2 + c1 on |x3| [m]": first.k2 + first.c1},
    )
    return laws, view


def _reaction_wheel(spec: ReactionWheelSpec) -> tuple[list[SystemLaw], SystemView]:
    laws: list[SystemLaw] = []
    bounds: dict[str, float] = {}
    for i, law in enumerate(spec.laws):
        try:
            ctrl = ReactionWheelController(WheelPendulumGains(**law.gains.model_dump()))
        except DesignError as exc:
            raise gain_error(f"system.laws[{i}]", exc) from None
        b = ctrl.bounds()
        torque = max(b.torque)  # (3.159) printed and corrected
        if torque > spec.torque_limit * (1 + 1e-12):
            raise ScenarioError(
                f"system.laws[{i}].gains",
                f"(3.159) bounds |τ| by {torque:.6g} N m for these gains, above torque_limit "
                f"{spec.torque_limit:.6g} N m: the law cannot promise the actuator's limit "
                "(lower c2, k4 or k2/k3, or raise torque_limit)",
            )
        laws.append(SystemLaw(law.name, ctrl, True))
        if not bounds:
            bounds = {"(3.148) sup|α1| printed": b.alpha1[0],
                      "(3.148) sup|α1| corrected": b.alpha1[1],
                      "(3.157) |q̇1| printed [rad/s]": b.rate[0],
                      "(3.157) |q̇1| corrected [rad/s]": b.rate[1],
                      "(3.159) |τ| printed [N m]": b.torque[0],
                      "(3.159) |τ| corrected [N m]": b.torque[1]}
    view = SystemView(
        panels=(
            Panel("pendulum angle q1 [rad]", 0),
            Panel("pendulum rate q̇1 [rad/s]", 1, 1.0, spec.rate_limit),
            Panel("torque τ [N m]", None, 1.0, spec.torque_limit),
            Panel("wheel speed q̇2 [rad/s]", 2),
        ),
        phase=(0, 1, "q1 [rad]", "q̇1 [rad/s]"), judged=(0, 1), angles=(0,),
        design_bounds=bounds,
    )
    return laws, view


def _integrator_chain(spec: IntegratorChainSpec) -> tuple[list[SystemLaw], SystemView]:
    """The §4.4 law under reading H1 per law; refused unless its worst-case state bounds X_i
    (4.88) are within the limits (4.89), the one guarantee manual tuning (§4.3.6) keeps."""
    laws: list[SystemLaw] = []
    bounds: dict[str, float] = {}
    for i, law in enumerate(spec.laws):
        try:
            ctrl = IntegratorChainController(ChainGains(**law.gains.model_dump()))
        except DesignError as exc:
            raise gain_error(f"system.laws[{i}]", exc) from None
        worst = worst_case(ctrl.law)
        for j, (x, lim) in enumerate(zip(worst.state_bounds, spec.limits, strict=True)):
            if x > lim:
                raise ScenarioError(
                    f"system.laws[{i}].gains",
                    f"the worst-case bound X{j + 2} = k{2 * j + 2} + sup_D |α{j + 1}| = {x:.6g} "
                    f"(4.88) exceeds limits[{j}] = Ξ{j + 2} = {lim:.6g} (4.89): the law keeps "
                    f"|ξ{j + 2}| < X{j + 2} only",
                )
        laws.append(SystemLaw(law.name, ctrl, True))
        if not bounds:
            for j, (x, a) in enumerate(zip(worst.state_bounds, worst.alpha, strict=True)):
                bounds[f"(4.88) sup_D |α{j + 1}|"] = a.value
                bounds[f"(4.88) X{j + 2} on |ξ{j + 2}|"] = x
    view = SystemView(
        panels=(
            Panel("position ξ1", 0),
            Panel("velocity ξ2", 1, 1.0, spec.limits[0]),
            Panel("acceleration ξ3", 2, 1.0, spec.limits[1]),
            Panel("jerk ξ4", 3, 1.0, spec.limits[2]),
            Panel("input u", None),
        ),
        phase=(0, 1, "ξ1", "ξ2"), judged=(0, 1, 2, 3), angles=(), design_bounds=bounds,
    )
    return laws, view


SpecOf = QuarterCarSpec | ReactionWheelSpec | IntegratorChainSpec


def _plant(spec: SpecOf, case: SystemCaseSpec, i: int) -> OdePlant:
    if case.commands is not None:
        raise ScenarioError(f"cases[{i}].commands",
                            "only the aerosonde system takes altitude commands; remove the key")
    if isinstance(spec, IntegratorChainSpec):
        if case.bump_height is not None:
            raise ScenarioError(f"cases[{i}].bump_height",
                                "the integrator chain has no road; remove the key")
        return IntegratorChain((None, *spec.limits))
    if isinstance(spec, ReactionWheelSpec):
        if case.bump_height is not None:
            raise ScenarioError(f"cases[{i}].bump_height",
                                "the reaction wheel pendulum has no road; remove the key")
        return ReactionWheelPendulum(rate_limit=spec.rate_limit, torque_limit=spec.torque_limit)
    if case.bump_height is None:
        raise ScenarioError(f"cases[{i}].bump_height",
                            "required key is missing: the bump height A [m] (0 for a flat road)")
    road = HaversineBump(case.bump_height, spec.bump_length, spec.speed)
    return QuarterCar(road, travel_limit=spec.travel_limit)


def _check_start(case: SystemCase, laws: list[SystemLaw], plant: OdePlant, i: int) -> None:
    """Refuse a start outside a barrier law's domain, or outside a constrained state's
    bounds (the law's input is not known before the run)."""
    field = f"cases[{i}].state"
    if len(case.state) != len(plant.state_names):
        raise ScenarioError(field, f"needs {len(plant.state_names)} values "
                            f"({', '.join(plant.state_names)}), got {len(case.state)}")
    for q in plant.constrained:
        if q.source == "state" and not q.lower < case.state[q.index] < q.upper:
            raise ScenarioError(field, f"{q.name} = {case.state[q.index]:.6g} is outside its "
                                f"bounds ({q.lower:.6g}, {q.upper:.6g})")
    for law in laws:
        try:
            law.law(case.state, 0.0)
        except OutsideDomainError as exc:
            raise ScenarioError(field, f"law '{law.name}': {exc}; the barrier law is not "
                                "defined there, so no run can start from it") from None


def build_system(scenario: SystemScenario, source: Path) -> SystemSetup:
    """The plants, laws and view of a Part I scenario; ScenarioError naming the field."""
    spec, sim = scenario.system, scenario.simulation
    if isinstance(spec, AerosondeSpec):
        return build_aerosonde(scenario, spec, source)
    laws, view = (_reaction_wheel(spec) if isinstance(spec, ReactionWheelSpec)
                  else _integrator_chain(spec) if isinstance(spec, IntegratorChainSpec)
                  else _suspension(spec))
    names = [law.name for law in laws]
    if len(set(names)) != len(names):
        raise ScenarioError("system.laws", f"law names repeat: {names}")
    period = sim.period
    check_length(scenario, period)
    cases: list[SystemCase] = []
    for i, c in enumerate(scenario.cases):
        plant = _plant(spec, c, i)
        case = SystemCase(c.name, tuple(c.state), plant)
        _check_start(case, laws, plant, i)
        cases.append(case)
    if len({c.name for c in cases}) != len(cases):
        raise ScenarioError("cases", "case names repeat")
    plant = cases[0].plant
    setup = SystemSetup(scenario, source, tuple(cases), tuple(laws), view, period,
                        plant.state_names, plant.input_name)
    check_backend(setup, sim.backend, "simulation.backend")
    return setup
