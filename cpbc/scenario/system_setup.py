"""A built Part I scenario (a ``system:`` block): its cases, laws and view
(:class:`SystemSetup`), and the checks every Part I system's build shares (the gains, the
run's length, the backend). Built by cpbc.scenario.system_build (and, for the Aerosonde,
cpbc.scenario.aerosonde_build)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from cpbc.errors import ScenarioError
from cpbc.results.system_metrics import SystemView
from cpbc.scenario.schema import SystemScenario

if TYPE_CHECKING:  # the systems and their laws load with a Part I scenario, not an arm's
    from cpbc.backstepping.design_errors import DesignError
    from cpbc.systems.ode_plant import OdePlant

Law = Callable[[tuple[float, ...], float], float]  # u = k(x, t), x a State


@dataclass(frozen=True)
class SystemLaw:
    name: str
    law: Law
    barrier: bool  # False: the comparison without barrier, which guarantees nothing
    #: the law of each case where it differs from ``law`` (one tracking the case's command)
    cases: Mapping[str, Law] = field(default_factory=dict)

    def for_case(self, case: str) -> Law:
        return self.cases.get(case, self.law)


@dataclass(frozen=True)
class SystemCase:
    name: str
    state: tuple[float, ...]  # the initial state x (cpbc.systems.ode_plant.State)
    plant: OdePlant  # a Plant (with its MJCF) unless the system is only its ODE


@dataclass(frozen=True)
class SystemSetup:
    """A built Part I scenario."""

    scenario: SystemScenario
    source: Path
    cases: tuple[SystemCase, ...]
    laws: tuple[SystemLaw, ...]
    view: SystemView
    control_period: float
    state_names: tuple[str, ...]
    input_name: str


def gain_error(field: str, exc: DesignError) -> ScenarioError:
    return ScenarioError(f"{field}.gains.{exc.parameter}", f"{exc.reason} (got {exc.value!r})")


def check_backend(setup: SystemSetup, backend: str, field: str) -> None:
    """:class:`ScenarioError` naming ``field`` when ``backend`` is MuJoCo and the system is
    only its ODE: a plant with no MuJoCo model (the integrator chain: nothing for a physics
    engine to add), or one whose MJCF only replays the path (the Aerosonde, whose forces
    depend on α̇)."""
    from cpbc.systems.ode_plant import Plant  # with a Part I scenario only

    plant = next((c.plant for c in setup.cases if not c.plant.physics), None)
    if backend != "mujoco" or plant is None:
        return
    why = ("its MJCF only replays the path" if isinstance(plant, Plant)
           else "it has no MuJoCo model")
    raise ScenarioError(field, f"this system is only its ODE ({why}); MuJoCo cannot simulate "
                        "it: use the continuous-time reference (backend: reference)")


def check_length(scenario: SystemScenario, period: float) -> None:
    sim = scenario.simulation
    ratio = period / sim.timestep
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
        raise ScenarioError("simulation.control_period",
                            f"{period:g} s is not a whole multiple of the timestep "
                            f"{sim.timestep:g} s")
    if period > sim.duration:
        raise ScenarioError("simulation.duration",
                            f"{sim.duration:g} s is shorter than one control period ({period:g} s)")
    steps = math.ceil(sim.duration / sim.timestep)
    if steps > sim.max_steps:
        raise ScenarioError("simulation.max_steps",
                            f"{steps} physics steps exceed max_steps {sim.max_steps}; raise it "
                            "or shorten the duration")
