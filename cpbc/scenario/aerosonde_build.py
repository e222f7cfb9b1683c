"""Building a Chapter 5 scenario (``system: {type: aerosonde}``): per case the plant trimmed at
its start altitude, the altitude command, and both laws tracking it, each checked before
anything runs (:class:`~cpbc.errors.ScenarioError` naming the YAML field)."""

from __future__ import annotations

import math
from pathlib import Path

from cpbc.backstepping import DesignError, OutsideDomainError
from cpbc.backstepping.altitude_backstepping import (
    TraditionalAltitudeGains,
    TraditionalAltitudeLaw,
)
from cpbc.backstepping.altitude_command import AltitudeCommand, TrackingLaw
from cpbc.backstepping.altitude_law import AltitudeLaw
from cpbc.backstepping.altitude_model import AltitudeModel
from cpbc.backstepping.constrained_altitude import (
    ConstrainedAltitudeGains,
    ConstrainedAltitudeLaw,
)
from cpbc.errors import CpbcError, ScenarioError
from cpbc.results.system_metrics import Panel, SystemView
from cpbc.scenario.schema import (
    AerosondeSpec,
    ConstrainedAltitudeLawSpec,
    SystemCaseSpec,
    SystemScenario,
    TraditionalAltitudeLawSpec,
)
from cpbc.scenario.system_setup import (
    Law,
    SystemCase,
    SystemLaw,
    SystemSetup,
    check_backend,
    check_length,
    gain_error,
)
from cpbc.systems.aerosim import AerosondeParameters
from cpbc.systems.aerosonde import AerosondePlant

DEG = 180.0 / math.pi


def _law(spec: TraditionalAltitudeLawSpec | ConstrainedAltitudeLawSpec, model: AltitudeModel,
         limit: float, j: int) -> AltitudeLaw:
    try:
        if isinstance(spec, TraditionalAltitudeLawSpec):
            return TraditionalAltitudeLaw(
                model, TraditionalAltitudeGains(**spec.gains.model_dump()))
        gains = ConstrainedAltitudeGains(**spec.gains.model_dump())
    except DesignError as exc:
        raise gain_error(f"system.laws[{j}]", exc) from None
    if gains.climb_rate_bound > limit * (1 + 1e-12):
        raise ScenarioError(
            f"system.laws[{j}].gains",
            f"k2 + c1 = {gains.climb_rate_bound:.6g} m/s exceeds climb_rate_limit "
            f"{limit:.6g} m/s: the law (5.61) keeps |v_z| < k2 + c1 only (5.68)")
    return ConstrainedAltitudeLaw(model, gains)


def _command(case: SystemCaseSpec, altitude: float, duration: float, i: int) -> AltitudeCommand:
    steps = [(c.time, c.altitude) for c in case.commands or []]
    for j, (t, _) in enumerate(steps):
        if j and t <= steps[j - 1][0]:
            raise ScenarioError(f"cases[{i}].commands[{j}].time",
                                f"{t:g} s does not come after the previous command's time")
        if t >= duration:
            raise ScenarioError(f"cases[{i}].commands[{j}].time",
                                f"{t:g} s is not before the end of the run ({duration:g} s)")
    return AltitudeCommand(altitude, tuple(steps))


def _plant(spec: AerosondeSpec, case: SystemCaseSpec, command: AltitudeCommand,
           i: int) -> AerosondePlant:
    if case.bump_height is not None:
        raise ScenarioError(f"cases[{i}].bump_height", "the Aerosonde has no road; remove the key")
    field = f"cases[{i}].state"
    if len(case.state) != 2:
        raise ScenarioError(field, "needs 2 values for the Aerosonde: altitude [m] and climb "
                            f"rate [m/s] (level trim at the airspeed), got {len(case.state)}")
    altitude, climb = case.state
    if not 0.0 <= altitude < 11_000.0:
        raise ScenarioError(field, f"altitude {altitude:g} m is outside the ISA troposphere "
                            "model (0 to 11 km)")
    if not abs(climb) < spec.climb_rate_limit:
        raise ScenarioError(field, f"climb rate {climb:g} m/s is outside its bounds "
                            f"(±{spec.climb_rate_limit:g} m/s)")
    try:
        return AerosondePlant(AerosondeParameters(mass=spec.mass), spec.airspeed, altitude,
                              spec.climb_rate_limit, spec.elevator_limit,
                              command_times=command.times)
    except CpbcError as exc:
        raise ScenarioError("system", str(exc)) from None


def _check_start(law: SystemLaw, case: SystemCase, command: AltitudeCommand, i: int) -> None:
    """The law must be defined at the start for the command active then."""
    field = f"cases[{i}].commands[0]" if command.index(0.0) else f"cases[{i}].state"
    try:
        law.for_case(case.name)(case.state, 0.0)
    except OutsideDomainError as exc:
        raise ScenarioError(field, f"law '{law.name}': {exc}; no run can start from it") from None


def _view(spec: AerosondeSpec, laws: list[TraditionalAltitudeLawSpec | ConstrainedAltitudeLawSpec]
          ) -> SystemView:
    lo, hi = AerosondeParameters().alpha_bounds
    bounds = {f"(5.68) k2 + c1 on |v_z|, law '{law.name}' [m/s]": law.gains.k2 + law.gains.c1
              for law in laws if isinstance(law, ConstrainedAltitudeLawSpec)}
    return SystemView(
        panels=(
            Panel("altitude h [m]", 0),
            Panel("climb rate v_z [m/s]", 1, 1.0, spec.climb_rate_limit),
            Panel("angle of attack α [deg]\n(AeroSim stall bounds)", 2, DEG, hi, lower=lo),
            Panel("elevator δ_E demanded [deg]\n(actuator range dashed)", None, DEG,
                  spec.elevator_limit),
        ),
        phase=None, judged=(1, 3), angles=(), design_bounds=bounds, path=(4, 0))


def build_aerosonde(scenario: SystemScenario, spec: AerosondeSpec, source: Path) -> SystemSetup:
    """The plants, laws and view of a Chapter 5 scenario; ScenarioError naming the field."""
    sim = scenario.simulation
    names = [law.name for law in spec.laws]
    if len(set(names)) != len(names):
        raise ScenarioError("system.laws", f"law names repeat: {names}")
    period = sim.period
    check_length(scenario, period)
    cases: list[SystemCase] = []
    commands: list[AltitudeCommand] = []
    per_law: list[dict[str, Law]] = [{} for _ in spec.laws]
    for i, c in enumerate(scenario.cases):
        command = _command(c, c.state[0] if c.state else 0.0, sim.duration, i)
        commands.append(command)
        plant = _plant(spec, c, command, i)
        model = plant.design_model(rho=spec.air_density, mass=spec.mass)
        case = SystemCase(c.name, plant.initial_state(c.state[0], c.state[1]), plant)
        for j, law_spec in enumerate(spec.laws):
            ctrl = _law(law_spec, model, spec.climb_rate_limit, j)
            per_law[j][c.name] = TrackingLaw(ctrl, command)
        cases.append(case)
    if len({c.name for c in cases}) != len(cases):
        raise ScenarioError("cases", "case names repeat")
    laws = [SystemLaw(s.name, per_law[j][cases[0].name], isinstance(s, ConstrainedAltitudeLawSpec),
                      per_law[j]) for j, s in enumerate(spec.laws)]
    for i, (built, command) in enumerate(zip(cases, commands, strict=True)):
        for system_law in laws:
            _check_start(system_law, built, command, i)
    first = cases[0].plant
    setup = SystemSetup(scenario, source, tuple(cases), tuple(laws), _view(spec, spec.laws),
                        period, first.state_names, first.input_name)
    check_backend(setup, sim.backend, "simulation.backend")
    return setup
