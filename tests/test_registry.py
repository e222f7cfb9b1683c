"""The kind registry (cpbc.scenario.schema.kinds): one contract over every registered constraint and
law kind (each built from the example entry it declares), the refusals of a kind that does
not declare what it must, and a constraint kind added as one module — its class and its
``KINDS``, written into a package of its own and found by the same walk that finds the
shipped ones — reaching the schema, the build, the results, the figures and the docs without
touching the default registry."""

from __future__ import annotations

import copy
import importlib
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any, Literal

import numpy as np
import pytest
from pydantic import Field, ValidationError

import cpbc.constraints
from cpbc.arrays import Array
from cpbc.constraints import ConfigurationConstraint
from cpbc.constraints.margins import BY_KEY, OTHER, TYPES
from cpbc.controllers.law_kind import Slopes
from cpbc.controllers.packed_law import python_path_notes
from cpbc.controllers.pd import PDSpec, build_pd
from cpbc.errors import ScenarioError
from cpbc.json_schema import scenario_schema
from cpbc.results.io import write_summaries
from cpbc.results.margin_types import grouped, types_of
from cpbc.results.plots import margins_figure
from cpbc.results.saved_run import load_run
from cpbc.run import write_logs
from cpbc.scenario import Scenario, build
from cpbc.scenario.runner import run_all
from cpbc.scenario.schema import ConstraintEntrySpec, scenario_model
from cpbc.scenario.schema.kinds import (
    KINDS,
    PACKAGES,
    ConstraintKind,
    KindError,
    Kinds,
    LawKind,
    declared_kinds,
)
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

def _built(tmp_path: Path, data: dict[str, Any], kinds: Kinds = KINDS) -> Any:
    scenario = scenario_model(kinds).model_validate(data)
    return build(scenario, tmp_path / "kinds.yaml", kinds)


def _json_mapping(schema: dict[str, Any], key: str) -> dict[str, str]:
    """The discriminator mapping (type → $ref) of the arm scenario's ``key`` items."""
    arm = schema["$defs"]["Scenario"] if "Scenario" in schema.get("$defs", {}) else schema
    return arm["properties"][key]["items"]["discriminator"]["mapping"]


def test_the_registry_is_what_the_packages_declare() -> None:
    """Every constraint and law module's ``KINDS`` (cpbc.constraints, cpbc.controllers,
    cpbc.peers), in the order of their module names (the walk is deterministic), and nothing
    else."""
    declared = [*cpbc.constraints.linear_limit.KINDS, *cpbc.constraints.rate_limit.KINDS]
    assert all(k in KINDS.constraints for k in declared)
    assert KINDS == Kinds.of(declared_kinds(*PACKAGES))
    assert KINDS.constraint_types == (
        "clearance", "kinetic_energy_limit", "joint_position_limit", "linear_limit",
        "point_outside_sphere", "joint_rate_limit", "rate_limit")
    assert KINDS.law_types == ("bpbc", "bpbc_ke", "cpbc", "cpbc_ke", "pd", "pd_gravity",
                               "recentred", "cbf_qp")
    assert KINDS.law("pd").spec.__module__ == "cpbc.controllers.pd"


@pytest.mark.parametrize("type_name", KINDS.constraint_types)
def test_constraint_kind_contract(type_name: str, tmp_path: Path) -> None:
    kind = KINDS.constraint(type_name)
    data = copy.deepcopy(BASE)
    data["constraints"] = [{"type": type_name, "name": "c", **kind.examples[type_name]}]
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
    data["controllers"] = [{"type": type_name, "kp": 4, "kd": 2, **kind.examples[type_name]}]
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
    quiet = LawKind(PDSpec, build_pd, slopes=None,  # type: ignore[arg-type]
                    examples={"pd": {}, "pd_gravity": {}})
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

    kind = ConstraintKind(UnlabelledSpec, lambda spec, given: Unlabelled(), Unlabelled,
                          {"unlabelled": {}})
    with pytest.raises(KindError, match="declares no margin type"):
        KINDS.with_kinds(kind)


def test_a_kind_without_an_example_for_each_type_is_refused() -> None:
    """The contract test builds every type from the example its kind declares: a kind that
    gives none for one of its types is refused when a registry is built."""
    pd = KINDS.law("pd")
    with pytest.raises(KindError, match=r"no example entry for \['pd_gravity'\]"):
        Kinds((), (LawKind(PDSpec, build_pd, pd.slopes, {"pd": {}}),))
    (rates,) = (k for k in KINDS.constraints if "rate_limit" in k.names)
    with pytest.raises(KindError, match="no example entry"):
        Kinds((ConstraintKind(rates.spec, rates.build, rates.constraint, {}),), ())


def test_a_type_declared_twice_is_refused() -> None:
    with pytest.raises(KindError, match="declared twice"):
        KINDS.with_kinds(KINDS.laws[0])


# -- a constraint kind added as one module --------------------------------------------------
# The whole of a new constraint kind: its class (φ and its gradient, its margin type) and its
# declaration (spec, factory, example), in one module.
POINT_BELOW = textwrap.dedent('''
    """φ(x) = h − p_y(x) > 0: a frame's origin stays below the height h [m]."""

    from typing import Literal

    import numpy as np
    from pydantic import Field

    from cpbc.constraints.constraint_kind import ConstraintEntrySpec, ConstraintKind
    from cpbc.constraints.constraint_types import ConfigurationConstraint
    from cpbc.constraints.margins import CLEARANCE


    class PointBelow(ConfigurationConstraint):
        margin_type = CLEARANCE  # φ is a distance in m already

        def __init__(self, model, frame, height, name):
            self.model, self.frame_id, self.height = model, model.frame_id(frame), height
            self.names = (name,)

        def value(self, x):
            return np.array([self.height - self.model.point_position(self.frame_id, x)[1]])

        def gradient(self, x):
            self.model.point_position(self.frame_id, x)
            return -self.model.point_jacobian(self.frame_id, x)[1:2]


    class PointBelowSpec(ConstraintEntrySpec):
        type: Literal["point_below"] = Field(description="a frame's origin below a height")
        name: str = Field(default="below", description="unique name")
        frame: str = Field(description="the frame")
        height: float = Field(description="the height [m]")


    def build(spec, given):
        return PointBelow(given.model, spec.frame, spec.height, spec.name)


    KINDS = (ConstraintKind(PointBelowSpec, build, PointBelow,
                            {"point_below": {"frame": "end_point", "height": 1.9}}),)
''')


@pytest.fixture(scope="module")
def extra_package(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    """A package ``extra_kinds`` holding the one module ``point_below.py``, importable for the
    tests of this module and forgotten after them."""
    root = tmp_path_factory.mktemp("extra")
    (root / "extra_kinds").mkdir()
    (root / "extra_kinds" / "__init__.py").write_text("", encoding="utf-8")
    (root / "extra_kinds" / "point_below.py").write_text(POINT_BELOW, encoding="utf-8")
    sys.path.insert(0, str(root))
    try:
        yield importlib.import_module("extra_kinds")
    finally:
        sys.path.remove(str(root))
        for name in [m for m in sys.modules if m.split(".")[0] == "extra_kinds"]:
            del sys.modules[name]


def _with_point_below(extra: ModuleType) -> Kinds:
    """The shipped kinds and the extra package's, found by the walk that finds the shipped
    ones."""
    return Kinds.of(declared_kinds(cpbc.constraints, extra, *PACKAGES[1:]))


def test_a_new_constraint_kind_reaches_schema_build_results_figures_and_docs(
        tmp_path: Path, extra_package: ModuleType) -> None:
    kinds = _with_point_below(extra_package)
    kind = kinds.constraint("point_below")
    assert kind.constraint.__module__ == "extra_kinds.point_below"
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
    # it has no kernel: it alone runs in Python, and cpbc.run says so once, at build
    (note,) = python_path_notes(law)
    assert "'below' (PointBelow) has no kernel" in note and "µs a step" in note
    assert python_path_notes(law) == []
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


def test_a_registry_of_its_own_leaves_the_default_as_it_was(extra_package: ModuleType) -> None:
    before = (KINDS.constraint_types, KINDS.law_types)
    mine = _with_point_below(extra_package)
    module = importlib.import_module("extra_kinds.point_below")
    assert (KINDS.constraint_types, KINDS.law_types) == before
    assert mine.constraint("point_below") is module.KINDS[0]
    # a module given by itself: appended to the shipped kinds
    assert KINDS.with_modules(module).constraint_types == (*before[0], "point_below")
    assert scenario_model(KINDS) is Scenario
    with pytest.raises(KeyError, match="point_below"):
        KINDS.constraint("point_below")


def test_inputs_name_the_entry_field(tmp_path: Path) -> None:
    data = copy.deepcopy(BASE)
    data["constraints"] = [{"type": "joint_rate_limit", "name": "r", "joints": ["elbow"],
                            "bounds": [1]}]
    with pytest.raises(ScenarioError, match=r"constraints\[0\]\.joints.*elbow"):
        _built(tmp_path, data)
