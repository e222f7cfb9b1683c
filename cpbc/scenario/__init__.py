"""Scenario layer: YAML format (pydantic), loading with field-named errors, and building."""

from cpbc.scenario.build import ScenarioSetup, build
from cpbc.scenario.load import load_scenario
from cpbc.scenario.schema import Scenario

__all__ = ["Scenario", "ScenarioSetup", "build", "load_scenario"]
