"""The kind registry (cpbc.scenario.schema.kinds): one contract over every registered constraint and
law kind, the refusals of a kind that does not declare what it must, and a constraint kind
added inside a test — one class and one declaration — reaching the schema, the build, the
results, the figures and the docs without touching the default registry."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest
from pydantic import Field, ValidationError

from cpbc.arrays import Array
from cpbc.constraints import ConfigurationConstraint
from cpbc.constraints.margins import BY_KEY, CLEARANCE, OTHER, TYPES
from cpbc.errors import ScenarioError
from cpbc.json_schema import scenario_schema
from cpbc.model import RobotModel
from cpbc.results.io import write_summaries
from cpbc.results.margin_types import grouped, types_of
from cpbc.results.plots import margins_figure
from cpbc.results.saved_run import load_run
from cpbc.run import write_logs
from cpbc.scenario import Scenario, build
from cpbc.scenario.runner import run_all
from cpbc.scenario.schema import ConstraintEntrySpec, scenario_model
from cpbc.scenario.schema.kinds import KINDS, ConstraintKind, KindError, Kinds, LawKind
from cpbc.scenario.schema.kinds.law_inputs import Slopes
from cpbc.scenario.schema.kinds.pd_kind import PDSpec
from cpbc.scenario.schema.kinds.pd_kind import build as build_pd
from cpbc.viewer.outputs import write_run_outputs
from tools import scenario_reference

REFERENCE = Path(__file__).resolve().parents[1] / "docs" / "scenario-reference.md"

# The thesis's planar arm at rest, three constraints every law below can take, one PD.
BASE: dict[str, Any] = {
    "name": "kinds",
    "robot": {"model": "planar_2link"},
    "simulation": {"duration": 0.02, "timestep": 0.001},
    "target": [0.5, 0.5],
    "cases": [{"name": "rest", "position": [0.2, 0.3]}],
    "obstacles": [{"type": "sphere", "name": "ball", "centre": [0.0, 2.0, 0.0],
                   "radius": 0.3}],
    "constraints": [
        {"type": "joint_position_limit", "name": "limits", "lower": [-3, -3],
         "upper": [3, 3]},
        {"type": "joint_rate_limit", "name": "rates", "bounds": [2, 2]},
        {"type": "kinetic_energy_limit", "name": "energy", "limit": 10},
    ],
    "controllers": [{"type": "pd", "kp": 4, "kd": 2}],
}

# A minimal entry of every registered constraint type (a new kind adds its line here).
CONSTRAINTS: dict[str, dict[str, Any]] = {
    "joint_position_limit": {"lower": [-3, -3], "upper": [3, 3]},
    "linear_limit": {"coefficients": [[-1, 1]], "lower": [-3], "upper": [3]},
    "point_outside_sphere": {"frame": "end_point", "centre": [0, 2], "radius": 0.5},
    "joint_rate_limit": {"bounds": [2, 2]},
    "rate_limit": {"coefficients": [[1, 1]], "bounds": [3]},
    "kinetic_energy_limit": {"limit": 10},
    "clearance": {"links": [], "primitives": [{"link": "link2", "centre": [1, 0, 0],
                                               "radius": 0.05}]},
}
# A minimal entry of every registered law type, on BASE's constraints.
LAWS: dict[str, dict[str, Any]] = {
    "pd": {},
    "pd_gravity": {},
    "cpbc": {"constraints": ["limits", "rates"]},
    "cpbc_ke": {"constraints": ["limits", "energy"]},
    "recentred": {"constraints": ["limits", "rates"]},
    "bpbc": {"constraints": ["rates"]},
    "bpbc_ke": {"constraints": ["energy"]},
    "cbf_qp": {"constraints": ["limits", "rates"]},
}


def _built(tmp_path: Path, data: dict[str, Any], kinds: Kinds = KINDS) -> Any:
    scenario = scenario_model(kinds).model_validate(data)
    return build(scenario, tmp_path / "kinds.yaml", kinds)


def _json_mapping(schema: dict[str, Any], key: str) -> dict[str, str]:
    """The discriminator mapping (type → $ref) of the arm scenario's ``key`` items."""
    arm = schema["$defs"]["Scenario"] if "Scenario" in schema.get("$defs", {}) else schema
    return arm["properties"][key]["items"]["discriminator"]["mapping"]


def test_every_registered_kind_is_in_this_contract() -> None:
    assert set(CONSTRAINTS) == set(KINDS.constraint_types)
    assert set(LAWS) == set(KINDS.law_types)


@pytest.mark.parametrize("type_name", KINDS.constraint_types)
def test_constraint_kind_contract(type_name: str, tmp_path: Path) -> None:
    kind = KINDS.constraint(type_name)
    data = copy.deepcopy(BASE)
    data["constraints"] = [{"type": type_name, "name": "c", **CONSTRAINTS[type_name]}]
    setup = _built(tmp_path, data)
    (c,) = (*setup.monitor.configuration, *setup.monitor.velocity)
    assert isinstance(c, kind.constraint)
    # the margins: a type the results know, in its unit, finite at the start and of the sign
    # of the constraint's own function (zero on the boundary of S, positive inside)
    assert c.margin_type in TYPES and c.margin_type is not OTHER and c.margin_type.unit
    x0 = setup.cases[0].position
    raw = setup.monitor.margins_along(x0[None, :], np.zeros((1, setup.model.n)))
    margins = c.margins(raw)
    assert np.all(np.isfinite(margins)) and np.array_equal(np.sign(margins), np.sign(raw))
    types = types_of(setup.monitor, setup.model.length_coordinates)
    assert set(types) == {c.margin_type.key}
    # figures and tables group every margin column under its type's label and unit
    (group, columns), = grouped(setup.monitor.names, types)
    assert group is BY_KEY[c.margin_type.key] and columns == list(range(len(types)))
    # the JSON schema and the generated reference name it
    assert _json_mapping(scenario_schema(), "constraints")[type_name].endswith(
        kind.spec.__name__)
    page = REFERENCE.read_text(encoding="utf-8")
    assert f"### {kind.spec.__name__}" in page and f'`"{type_name}"`' in page


@pytest.mark.parametrize("type_name", KINDS.law_types)
def test_law_kind_contract(type_name: str, tmp_path: Path) -> None:
    kind = KINDS.law(type_name)
    if type_name == "cbf_qp":
        pytest.importorskip("daqp", reason="the peers extra")
    data = copy.deepcopy(BASE)
    data["controllers"] = [{"type": type_name, "kp": 4, "kd": 2, **LAWS[type_name]}]
    setup = _built(tmp_path, data)
    (entry,) = setup.controllers
    assert entry.name == type_name and entry.controller.type_name == type_name
    tau, _ = entry.controller.evaluate(setup.cases[0].position, setup.cases[0].velocity)
    assert np.all(np.isfinite(tau))
    # what the gain check needs: the slopes per unit of K_P, K_D, one per coordinate
    spec = setup.scenario.controllers[0]
    slopes = kind.slopes(spec, setup.model.n, "controllers[0]")
    assert isinstance(slopes, Slopes)
    assert slopes.spring.shape == slopes.damping.shape == (setup.model.n,)
    assert np.all(slopes.spring > 0) and np.all(slopes.damping > 0)
    assert set(kind.goal_types) <= set(kind.names)
    assert _json_mapping(scenario_schema(), "controllers")[type_name].endswith(
        kind.spec.__name__)
    page = REFERENCE.read_text(encoding="utf-8")
    assert f"### {kind.spec.__name__}" in page and f'`"{type_name}"`' in page


def test_the_gain_check_reads_the_declared_slopes(tmp_path: Path) -> None:
    """bpbc declares its damping K_D tanh(Γẋ) (slope K_D Γ): gains the held loop takes
    for PD are refused for bpbc once Γ makes K_D Γ h exceed twice the inertia."""
    data = copy.deepcopy(BASE)
    data["simulation"]["control_period"] = 0.01
    data["controllers"] = [{"type": "pd", "kp": 1, "kd": 2}]
    _built(tmp_path, data)  # K_D h = 0.02, far inside
    data["controllers"] = [{"type": "bpbc", "kp": 1, "kd": 2, "gamma": 200,
                            "constraints": ["rates"]}]
    with pytest.raises(ScenarioError, match=r"controllers\[0\].*unstable under the zero-order"):
        _built(tmp_path, data)


def test_a_law_kind_without_the_gain_checks_declaration_is_refused() -> None:
    with pytest.raises(TypeError, match="slopes"):
        LawKind(PDSpec, build_pd)  # type: ignore[call-arg]
    quiet = LawKind(PDSpec, build_pd, slopes=None)  # type: ignore[arg-type]
    with pytest.raises(KindError, match="declares no slopes for the gain check"):
        Kinds((), (quiet,))


def test_a_constraint_class_without_a_margin_type_is_refused() -> None:
    class Unlabelled(ConfigurationConstraint):
        def value(self, x: Array) -> Array:
            return x

        def gradient(self, x: Array) -> Array:
            return np.eye(len(x))

    class UnlabelledSpec(ConstraintEntrySpec):
        type: Literal["unlabelled"] = Field(description="-")

    kind = ConstraintKind(UnlabelledSpec, lambda spec, given: Unlabelled(), Unlabelled)
    with pytest.raises(KindError, match="declares no margin type"):
        KINDS.with_kinds(kind)


def test_a_type_declared_twice_is_refused() -> None:
    with pytest.raises(KindError, match="declared twice"):
        KINDS.with_kinds(KINDS.laws[0])


# -- a constraint kind added in one place ---------------------------------------------------
class PointBelow(ConfigurationConstraint):
    """φ(x) = h − p_y(x) > 0: a frame's origin stays below the height h [m]."""

    margin_type = CLEARANCE  # φ is a distance in m already

    def __init__(self, model: RobotModel, frame: str, height: float, name: str) -> None:
        self.model, self.frame_id, self.height = model, model.frame_id(frame), height
        self.names = (name,)

    def value(self, x: Array) -> Array:
        return np.array([self.height - self.model.point_position(self.frame_id, x)[1]])

    def gradient(self, x: Array) -> Array:
        self.model.point_position(self.frame_id, x)
        return -self.model.point_jacobian(self.frame_id, x)[1:2]


class PointBelowSpec(ConstraintEntrySpec):
    type: Literal["point_below"] = Field(description="a frame's origin below a height")
    name: str = Field(default="below", description="unique name")
    frame: str = Field(description="the frame")
    height: float = Field(description="the height [m]")


POINT_BELOW = ConstraintKind(
    PointBelowSpec,
    lambda spec, given: PointBelow(given.model, spec.frame, spec.height, spec.name),
    PointBelow)


def test_a_new_constraint_kind_reaches_schema_build_results_figures_and_docs(
        tmp_path: Path) -> None:
    kinds = KINDS.with_kinds(POINT_BELOW)
    data = copy.deepcopy(BASE)
    data["constraints"].append({"type": "point_below", "frame": "end_point", "height": 1.9})
    data["controllers"] = [{"type": "cpbc", "kp": 4, "kd": 2, "name": "law"}]
    # the default registry is untouched: there the type is unknown, and the message lists
    # the known ones
    assert "point_below" not in KINDS.constraint_types
    with pytest.raises(ValidationError, match="point_below"):
        Scenario.model_validate(data)
    model = scenario_model(kinds)
    assert _json_mapping(model.model_json_schema(), "constraints")["point_below"].endswith(
        "PointBelowSpec")
    page = scenario_reference.render(model)
    assert "### PointBelowSpec" in page and '`"point_below"`' in page
    setup = _built(tmp_path, data, kinds)
    law = setup.controllers[0].controller
    assert "below" in law.constraints.names  # the law enforces it (all constraints)
    results = run_all(setup)
    summary = results[0].summary
    assert summary.margin_types["below"] == "clearance"
    assert 0 < summary.min_margins["below"] < 1.9  # the end point starts 0.47 m below
    folder = tmp_path / "out"
    folder.mkdir()
    write_logs(folder, setup, results)
    write_summaries(folder, [r.summary for r in results])
    written = write_run_outputs(folder, setup)  # the scene, the figures and the page
    assert folder / "rest" / "margins.png" in written
    fig = margins_figure(load_run(folder).cases[0])
    assert fig is not None
    labels = [ax.get_ylabel() for ax in fig.axes if ax.get_ylabel()]
    assert "clearance [m]" in labels


def test_a_registry_of_its_own_leaves_the_default_as_it_was() -> None:
    before = (KINDS.constraint_types, KINDS.law_types)
    mine = KINDS.with_kinds(POINT_BELOW)
    assert (KINDS.constraint_types, KINDS.law_types) == before
    assert mine.constraint("point_below") is POINT_BELOW
    assert scenario_model(KINDS) is Scenario
    with pytest.raises(KeyError, match="point_below"):
        KINDS.constraint("point_below")


def test_inputs_name_the_entry_field(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["constraints"] = [{"type": "joint_rate_limit", "name": "r", "joints": ["elbow"],
                            "bounds": [1]}]
    with pytest.raises(ScenarioError, match=r"constraints\[0\]\.joints.*elbow"):
        _built(tmp_path, data)
