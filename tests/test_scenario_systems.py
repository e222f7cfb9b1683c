"""The Part I scenario layer (cpbc/scenario/system_build.py): the shipped system scenarios load
and build, every law is defined at every case's start, and the literal thesis starts the
laws cannot take are refused with the reason."""

from __future__ import annotations

import pytest
import yaml

from cpbc.errors import ScenarioError
from cpbc.resources import scenarios_dir
from cpbc.scenario.load import load_any
from cpbc.scenario.schema import SystemScenario
from cpbc.scenario.system_build import build_system

SYSTEMS = sorted(p for p in scenarios_dir().glob("*.yaml")
                 if "system" in yaml.safe_load(p.read_text()))


def test_the_part_1_scenarios_are_shipped() -> None:
    assert {p.stem for p in SYSTEMS} == {"ch3_suspension", "ch3_rwp", "ch4_integrator_chain",
                                         "ch5_aerosonde"}


@pytest.mark.parametrize("path", SYSTEMS, ids=[p.stem for p in SYSTEMS])
def test_shipped_system_scenario_loads_and_builds(path) -> None:
    scenario, file = load_any(path)
    assert isinstance(scenario, SystemScenario) and scenario.name == path.stem
    setup = build_system(scenario, file)
    assert [c.name for c in setup.cases] == [c.name for c in scenario.cases]
    for case in setup.cases:
        for law in setup.laws:
            assert abs(law.law(case.state, 0.0)) < 1e6


def test_figure_cases_are_named_after_the_thesis() -> None:
    names = {p.stem: [c.name for c in load_any(p)[0].cases] for p in SYSTEMS}  # type: ignore[union-attr]
    assert names == {"ch3_suspension": ["fig3.4", "fig3.5", "fig3.6", "fig3.7"],
                     "ch3_rwp": ["fig3.9", "fig3.11"],
                     "ch4_integrator_chain": ["fig4.1", "fig4.2"],
                     "ch5_aerosonde": ["fig5.1", "fig5.3", "fig5.5", "fig5.7"]}


def test_literal_fig3_7_start_is_refused_naming_the_domain() -> None:
    scenario, file = load_any(scenarios_dir() / "ch3_suspension.yaml")
    data = scenario.model_dump()
    data["cases"][3]["state"] = [0.0, -20.0, -0.05, 0.0]  # as printed in the thesis
    with pytest.raises(ScenarioError) as err:
        build_system(SystemScenario.model_validate(data), file)
    assert err.value.field == "cases[3].state"
    assert "z1 = -0.0989997" in str(err.value) and "(-0.051, 0.051)" in str(err.value)


def test_rwp_gains_whose_torque_bound_exceeds_the_actuator_are_refused() -> None:
    """The law keeps |τ| below its a-priori bound (3.159) only: 0.3949 N m for the thesis's
    gains, so a 0.3 N m actuator is refused before the run (it ran, and crossed at t = 0)."""
    scenario, file = load_any(scenarios_dir() / "ch3_rwp.yaml")
    data = scenario.model_dump()
    data["system"]["torque_limit"] = 0.3
    with pytest.raises(ScenarioError) as err:
        build_system(SystemScenario.model_validate(data), file)
    assert err.value.field == "system.laws[0].gains"
    assert "(3.159)" in str(err.value) and "0.394922" in str(err.value)
    data["system"]["torque_limit"] = 0.395  # just above the bound: accepted
    build_system(SystemScenario.model_validate(data), file)
