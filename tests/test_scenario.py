"""Scenario layer: every shipped scenario loads and builds; bad input is a ScenarioError (or an
InadmissibleStateError) that names the offending field, never a traceback from deep inside."""

from __future__ import annotations

import copy
import math
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from cpbc.constraints import KineticEnergyLimit, LinearLimit, PointOutsideSphere, RateLimit
from cpbc.errors import CpbcError, InadmissibleStateError, ScenarioError
from cpbc.resources import models_dir, scenarios_dir
from cpbc.scenario import Scenario, build, load_scenario
from cpbc.scenario.schema.kinds import KINDS
from cpbc.spec.expressions import parse_number

# the arm scenarios; the Part I ones (a system: block) are tested in test_scenario_systems.py
SHIPPED = sorted(p for p in scenarios_dir().glob("*.yaml")
                 if "system" not in yaml.safe_load(p.read_text()))
T = np.array([[1.0, 0.0], [1.0, 1.0]])
REL = 17 * math.pi / 18

# A small valid scenario: the thesis's Chapter 6 setting with a target away from the obstacle.
MINIMAL: dict = {
    "name": "minimal",
    "robot": {"model": "planar_2link", "coordinates": "absolute"},
    "simulation": {"duration": 0.05, "timestep": 0.001},
    "target": [1.0, 1.5],
    "cases": [{"name": "rest", "position": [0, 0]}],
    "constraints": [
        {
            "type": "point_outside_sphere",
            "name": "obstacle",
            "frame": "end_point",
            "centre": [0, 2],
            "radius": 0.5,
        },
        {
            "type": "linear_limit",
            "name": "relative_angle",
            "coefficients": [[-1, 1]],
            "lower": ["-17*pi/18"],
            "upper": ["17*pi/18"],
        },
        {"type": "joint_rate_limit", "name": "link_rates", "bounds": [0.3, 0.2]},
    ],
    "controllers": [
        {"type": "pd", "name": "PD", "kp": 4, "kd": 20},
        {
            "type": "cpbc",
            "name": "CPBC",
            "kp": 4,
            "kd": 20,
            "shaping": {"type": "power", "alpha": 0.2},
        },
    ],
}


@pytest.fixture
def minimal() -> dict:
    """A fresh deep copy of the minimal valid scenario, to be edited by each test."""
    return copy.deepcopy(MINIMAL)


def edit(data: dict, path: str, value: object) -> dict:
    """Set data[a][b][i]… = value for path 'a.b.i' (integers index lists)."""
    keys = [int(k) if k.isdigit() else k for k in path.split(".")]
    node = data
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    return data


def expect_error(load_dict, data: dict, field: str, *words: str) -> ScenarioError:
    """Loading must fail with a ScenarioError whose field and message name ``field``."""
    with pytest.raises(ScenarioError) as info:
        load_dict(data)
    err = info.value
    assert isinstance(err, CpbcError)
    assert field in err.field, f"field {err.field!r} does not name {field!r}"
    assert field.split(".")[-1].split("[")[0] in str(err)
    for w in words:
        assert w in str(err), f"{w!r} not in message {str(err)!r}"
    return err


@pytest.mark.parametrize("value", [True, "yes"])
def test_boolean_is_not_a_number(load_dict, minimal, value):
    data = yaml.safe_load(yaml.safe_dump(edit(minimal, "simulation.duration", value)))
    expect_error(load_dict, data, "simulation.duration")


# == shipped scenarios ===========================================================================
def test_there_are_shipped_scenarios():
    names = {p.stem for p in SHIPPED}
    assert {"thesis_ch6", "thesis_ch7"} <= names


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_scenario_loads_and_builds(path):
    scenario, file = load_scenario(path)
    assert isinstance(scenario, Scenario)
    assert file == path
    assert scenario.name == path.stem  # the output folder is named after it
    setup = build(scenario, file)
    n = setup.model.n
    assert setup.target.shape == (n,)
    assert len(setup.controllers) == len(scenario.controllers) >= 1
    assert len(setup.cases) == len(scenario.cases) >= 1
    for entry in setup.controllers:
        assert entry.controller.type_name in KINDS.law_types
        assert entry.controller.target.shape == (n,)
        # every law can be evaluated at every initial state: each is inside its admissible set
        for case in setup.cases:
            entry.controller.check_admissible(case.position, case.velocity, case.name)
            tau, v = entry.controller.evaluate(case.position, case.velocity)
            assert tau.shape == (n,) and np.all(np.isfinite(tau))
            assert math.isfinite(v)
    for case in setup.cases:
        assert np.all(setup.monitor.margins(case.position, case.velocity) > 0)
    assert np.all(setup.monitor.margins(setup.target, np.zeros(n)) > 0)
    assert setup.make_plant().n == n


def test_shipped_scenario_can_be_named_without_path():
    scenario, file = load_scenario("thesis_ch7")
    assert file == scenarios_dir() / "thesis_ch7.yaml"
    assert scenario.name == "thesis_ch7"


def test_thesis_ch6_is_the_thesis_experiment():
    """Section 6.4: target (π, 2π/3) from rest at 0, φ₁, φ₂, |θ̇| < (0.3, 0.2), K_P = 4, K_D = 20."""
    setup = build(*load_scenario("thesis_ch6"))
    np.testing.assert_allclose(setup.target, [math.pi, 2 * math.pi / 3], rtol=1e-15)
    np.testing.assert_array_equal(setup.model.coordinates.matrix, T)
    assert [c.name for c in setup.cases] == ["rest"]
    np.testing.assert_array_equal(setup.cases[0].position, [0, 0])
    np.testing.assert_array_equal(setup.cases[0].velocity, [0, 0])
    by_type = {type(c): c for c in (*setup.monitor.configuration, *setup.monitor.velocity)}
    obs = by_type[PointOutsideSphere]
    np.testing.assert_array_equal(obs.centre, [0, 2, 0])
    assert obs.radius == 0.5
    rel = by_type[LinearLimit]
    np.testing.assert_array_equal(rel.rows, [[-1, 1]])
    np.testing.assert_allclose([rel.lower[0], rel.upper[0]], [-REL, REL], rtol=1e-15)
    np.testing.assert_array_equal(by_type[RateLimit].bounds, [0.3, 0.2])
    assert setup.rate_bounds == [0.3, 0.2]
    types = {e.controller.type_name: e.controller for e in setup.controllers}
    assert {"pd", "cpbc"} <= set(types)
    for ctrl in (types["pd"], types["cpbc"]):
        np.testing.assert_array_equal(ctrl.kp, [4, 4])
        np.testing.assert_array_equal(ctrl.kd, [20, 20])
    assert len(types["cpbc"].constraints) == 4


def test_thesis_ch7_is_the_thesis_experiment():
    """Section 7.3: target (π, π), two initial rates, K_P = diag(2, 10), K_D = diag(4, 20)."""
    setup = build(*load_scenario("thesis_ch7"))
    np.testing.assert_allclose(setup.target, [math.pi, math.pi], rtol=1e-15)
    np.testing.assert_array_equal(setup.model.coordinates.matrix, T)
    velocities = sorted(tuple(c.velocity) for c in setup.cases)
    assert velocities == [(-0.2, -0.1), (0.0, 0.0)]
    assert setup.rate_bounds == [0.3, 0.2]
    types = {e.controller.type_name: e.controller for e in setup.controllers}
    assert {"pd", "bpbc"} <= set(types)
    for ctrl in (types["pd"], types["bpbc"]):
        np.testing.assert_array_equal(ctrl.kp, [2, 10])
        np.testing.assert_array_equal(ctrl.kd, [4, 20])
    # (7.32) with ζ_g = 0 (horizontal), ζ_c = m₂l₁l_c₂ = 0.5, ζ_f = 0: 0.5·0.13 + 10 + 20
    assert types["bpbc"].torque_bound == pytest.approx(30.065, abs=1e-3)


# == the minimal scenario and what build makes of it =============================================
def test_minimal_scenario_builds(load_dict, minimal):
    setup = load_dict(minimal)
    assert setup.coordinate_names == ("theta1", "theta2")
    assert setup.monitor.names == ("obstacle", "relative_angle", "rate[theta1]", "rate[theta2]")
    np.testing.assert_allclose(setup.target, [1.0, 1.5])
    np.testing.assert_array_equal(setup.cases[0].velocity, [0.0, 0.0])  # default
    assert [e.name for e in setup.controllers] == ["PD", "CPBC"]
    assert setup.loop_settings.bounds.period == 0.001  # defaults to the timestep
    assert setup.loop_settings.duration == 0.05
    assert setup.loop_settings.bounds.torque is None
    assert [o.name for o in setup.obstacles] == ["obstacle"]
    assert not setup.obstacles[0].collides


def test_expressions_of_pi_parse(load_dict, minimal):
    edit(minimal, "target", ["pi", "2*pi/3"])
    edit(minimal, "cases.0.position", ["-pi/4", "(1 + 2) * pi / 12"])
    setup = load_dict(minimal)
    np.testing.assert_allclose(setup.target, [math.pi, 2 * math.pi / 3], rtol=1e-15)
    np.testing.assert_allclose(setup.cases[0].position, [-math.pi / 4, math.pi / 4], rtol=1e-15)
    rel = setup.monitor.configuration[1]
    assert rel.lower[0] == -17 * math.pi / 18
    assert rel.upper[0] == 17 * math.pi / 18


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("2*pi/3", 2 * math.pi / 3),
        ("-17*pi/18", -17 * math.pi / 18),
        (" pi ", math.pi),
        ("2**-1", 0.5),
        ("+3", 3.0),
        ("1e-3", 1e-3),
    ],
)
def test_parse_number(text, value):
    assert parse_number(text) == value


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os')",
        "__import__('os').system('true')",
        "pi.__class__",
        "open('x')",
        "(lambda: 1)()",
        "[1][0]",
        "1 if pi else 2",
        "e",
        "nan",
        "1/0",
        "",
    ],
)
def test_parse_number_rejects_anything_but_arithmetic(text):
    with pytest.raises(ValueError, match="cannot read"):
        parse_number(text)


def test_parse_number_passes_non_strings_through():
    assert parse_number(1.5) == 1.5
    assert parse_number([1]) == [1]


def test_malicious_expression_is_a_scenario_error(load_dict, minimal):
    edit(minimal, "target", ["__import__('os').system('touch pwned')", 1.0])
    expect_error(load_dict, minimal, "target[0]", "cannot read")


def test_overflowing_expression_is_a_scenario_error(load_dict, minimal):
    edit(minimal, "simulation.duration", "10.0**400")
    expect_error(load_dict, minimal, "simulation.duration")


def test_model_by_relative_path_and_custom_coordinates(tmp_path, load_dict, minimal):
    (tmp_path / "robots").mkdir()
    shutil.copy(models_dir() / "planar_2link.xml", tmp_path / "robots" / "arm.xml")
    edit(minimal, "robot", {"model": "robots/arm.xml", "coordinates": [[1, 0], [1, 1]]})
    setup = load_dict(minimal)
    assert setup.model_path == tmp_path / "robots" / "arm.xml"
    np.testing.assert_array_equal(setup.model.coordinates.matrix, T)
    assert setup.coordinate_names == ("x1", "x2")


def test_joint_coordinates_and_selected_joints(load_dict, minimal):
    minimal["robot"]["coordinates"] = "joint"
    minimal["constraints"] = [
        {"type": "joint_rate_limit", "name": "r", "joints": ["joint2"], "bounds": [0.4]},
        {
            "type": "joint_position_limit",
            "name": "p",
            "joints": ["joint1"],
            "lower": [-1],
            "upper": [2],
        },
    ]
    setup = load_dict(minimal)
    assert setup.coordinate_names == ("joint1", "joint2")
    assert setup.monitor.names == ("position[joint1]", "rate[joint2]")
    assert setup.rate_bounds == [None, 0.4]


def test_friction_reaches_model_and_plant(load_dict, minimal):
    edit(minimal, "robot.viscous_friction", [0.4, 1.3])
    setup = load_dict(minimal)
    t_inv = np.linalg.inv(T)
    np.testing.assert_allclose(
        setup.model.viscous_friction, t_inv.T @ np.diag([0.4, 1.3]) @ t_inv, atol=1e-15
    )
    np.testing.assert_allclose(setup.make_plant().model.dof_damping, [0.4, 1.3], atol=1e-15)


def test_obstacle_is_placed_in_the_plant(load_dict, minimal):
    plant = load_dict(minimal).make_plant()
    gid = mujoco.mj_name2id(plant.model, mujoco.mjtObj.mjOBJ_GEOM, "obstacle")
    assert gid >= 0
    np.testing.assert_allclose(plant.model.geom_pos[gid], [0, 2, 0])
    assert plant.model.geom_size[gid, 0] == 0.5
    assert plant.model.geom_contype[gid] == 0


def test_controller_constraint_subset(load_dict, minimal):
    minimal["controllers"][1]["constraints"] = ["link_rates"]
    setup = load_dict(minimal)
    assert setup.controllers[1].controller.constraints.names == ("rate[theta1]", "rate[theta2]")
    assert setup.controllers[0].controller.constraints.empty  # PD enforces nothing


def test_kinetic_energy_scenario_builds(load_dict, minimal):
    minimal["constraints"] = [{"type": "kinetic_energy_limit", "name": "ke", "limit": 0.05}]
    minimal["controllers"] = [
        {"type": "cpbc_ke", "kp": 4, "kd": 6},
        {"type": "bpbc_ke", "kp": [2, 10], "kd": [4, 20]},
    ]
    setup = load_dict(minimal)
    assert [e.name for e in setup.controllers] == ["cpbc_ke", "bpbc_ke"]  # named by type
    assert isinstance(setup.monitor.velocity[0], KineticEnergyLimit)


# == bad input: each names its field ==============================================================
@pytest.mark.parametrize(
    ("path", "value", "field", "words"),
    [
        ("colour", "red", "colour", ("unknown key",)),
        ("controllers.1.kpp", 1, "kpp", ("unknown key",)),
        ("constraints.0.colour", "red", "colour", ("unknown key",)),
        ("simulation.dt", 0.01, "dt", ("unknown key",)),
        ("target", [1, 2, 3], "target", ("2 entries",)),
        ("target", "pi", "target", ()),
        ("cases.0.position", [1], "cases[0].position", ("2 entries",)),
        ("cases.0.velocity", [0, 0, 0], "cases[0].velocity", ("2 entries",)),
        ("controllers.1.kp", [1, 2, 3], "controllers[1]", ("kp",)),
        ("controllers.1.kd", 0, "kd", ("greater than 0",)),
        ("controllers.0.kp", -4, "kp", ("greater than 0",)),
        ("controllers.1.kp", [4, 0], "kp", ("greater than 0",)),
        ("controllers.1.shaping", {"type": "power", "alpha": 0}, "alpha", ()),
        ("constraints.2.bounds", [0.3, 0], "bounds", ("greater than 0",)),
        ("constraints.2.bounds", [0.3, -0.2], "bounds", ("greater than 0",)),
        ("constraints.2.bounds", [0.3], "constraints[2].bounds", ("2 entries",)),
        ("constraints.0.radius", 0, "radius", ("greater than 0",)),
        ("constraints.0.radius", -0.5, "radius", ("greater than 0",)),
        ("constraints.0.centre", [0], "constraints[0].centre", ()),
        ("constraints.1.lower", ["17*pi/18"], "constraints[1]", ("lower < upper",)),
        ("constraints.1.lower", [-1, -2], "constraints[1].lower", ()),
        ("constraints.1.coefficients", [[1, 2, 3]], "constraints[1].coefficients", ()),
        ("simulation.duration", 0, "simulation.duration", ("greater than 0",)),
        ("simulation.duration", -1.0, "simulation.duration", ("greater than 0",)),
        ("simulation.timestep", 0, "simulation.timestep", ("greater than 0",)),
        ("simulation.timestep", float("nan"), "simulation.timestep", ("finite",)),
        ("target", [float("nan"), 1.0], "target[0]", ("finite",)),
        ("target", [float("inf"), 1.0], "target[0]", ("finite",)),
        ("cases.0.velocity", [0.0, "nan"], "cases[0].velocity[1]", ("cannot read",)),
        ("simulation.duration", "1/0", "simulation.duration", ("cannot read",)),
        ("simulation.control_period", 0.0015, "simulation.control_period", ("multiple",)),
        ("simulation.control_period", 0.0005, "simulation.control_period", ("multiple",)),
        ("simulation.log_every", 0, "simulation.log_every", ()),
        ("simulation.torque_limit", [1, 2, 3], "simulation.torque_limit", ()),
        ("simulation.integrator", "leapfrog", "simulation.integrator", ()),
        ("robot.model", "no_such_robot", "robot.model", ("planar_2link",)),
        ("robot.coordinates", [[1, 2], [2, 4]], "robot.coordinates", ("invertible",)),
        ("robot.viscous_friction", [1, 2, 3], "robot.viscous_friction", ()),
        ("constraints.0.frame", "tool", "constraints[0]", ("tool", "end_point")),
        ("constraints.2.joints", ["joint1"], "constraints[2].joints", ("theta1",)),
        ("constraints.2.joints", ["theta1", "theta1"], "constraints[2]", ("twice",)),
        ("constraints.1.name", "obstacle", "constraints[1].name", ("duplicate",)),
        ("controllers.1.name", "PD", "controllers", ("unique",)),
        ("name", "has space", "name", ()),
        ("cases", [], "cases", ()),
        ("controllers", [], "controllers", ()),
    ],
)
def test_bad_value_names_its_field(load_dict, minimal, path, value, field, words):
    expect_error(load_dict, edit(minimal, path, value), field, *words)


def test_missing_required_key(load_dict, minimal):
    del minimal["simulation"]
    expect_error(load_dict, minimal, "simulation", "missing")


def test_duplicate_case_names(load_dict, minimal):
    minimal["cases"].append(copy.deepcopy(minimal["cases"][0]))
    expect_error(load_dict, minimal, "cases", "unique")


def test_unknown_controller_type_lists_registered_types(load_dict, minimal):
    edit(minimal, "controllers.1.type", "lqr")
    err = expect_error(load_dict, minimal, "controllers[1]", "lqr")
    for name in KINDS.law_types:
        assert repr(name) in str(err)


def test_unknown_type_message_quotes_the_type_only(load_dict, minimal):
    edit(minimal, "controllers.1.type", "lqr")
    with pytest.raises(ScenarioError) as info:
        load_dict(minimal)
    assert "unknown type 'lqr'" in str(info.value)


def test_unknown_constraint_type_lists_registered_types(load_dict, minimal):
    edit(minimal, "constraints.0.type", "box")
    err = expect_error(load_dict, minimal, "constraints[0]", "box")
    for name in ("joint_position_limit", "linear_limit", "point_outside_sphere",
                 "joint_rate_limit", "rate_limit", "kinetic_energy_limit"):
        assert repr(name) in str(err)


def test_constraint_without_type(load_dict, minimal):
    del minimal["constraints"][0]["type"]
    expect_error(load_dict, minimal, "constraints[0]", "type")


def test_unknown_constraint_name_in_a_controller(load_dict, minimal):
    minimal["controllers"][1]["constraints"] = ["obstacle", "walls"]
    expect_error(load_dict, minimal, "controllers[1].constraints", "walls", "link_rates")


def test_bpbc_refuses_an_obstacle(load_dict, minimal):
    edit(minimal, "controllers.1.type", "bpbc")
    expect_error(load_dict, minimal, "controllers[1]", "bpbc", "rate limits only")


def test_bpbc_needs_a_rate_limit_on_every_joint(load_dict, minimal):
    minimal["constraints"][2]["joints"] = ["theta1"]
    minimal["constraints"][2]["bounds"] = [0.3]
    minimal["controllers"][1].update(type="bpbc", constraints=["link_rates"])
    expect_error(load_dict, minimal, "controllers[1]", "every joint")


def test_cpbc_ke_needs_a_kinetic_energy_limit(load_dict, minimal):
    edit(minimal, "controllers.1.type", "cpbc_ke")
    expect_error(load_dict, minimal, "controllers[1]", "kinetic_energy_limit")


def test_recentred_needs_joint_limits(load_dict, minimal):
    minimal["controllers"][1] = {"type": "recentred", "kp": 1, "kd": 1}
    with pytest.raises(ScenarioError) as info:
        load_dict(minimal)
    assert info.value.field == "controllers[1]"


@pytest.mark.parametrize(
    ("path", "value", "what", "constraint"),
    [
        ("cases.0.velocity", [0.35, 0.0], "cases[0]", "rate[theta1]"),
        ("cases.0.velocity", [0.0, -0.2], "cases[0]", "rate[theta2]"),  # on the bound
        ("target", ["pi/2", "pi/2"], "target", "obstacle"),  # end point at the centre
        ("target", ["2*pi/3", "-17*pi/18"], "target", "relative_angle"),
        ("cases.0.position", [0.0, 3.0], "cases[0]", "relative_angle"),
    ],
)
def test_state_outside_the_admissible_set(load_dict, minimal, path, value, what, constraint):
    with pytest.raises(InadmissibleStateError) as info:
        load_dict(edit(minimal, path, value))
    err = info.value
    assert isinstance(err, CpbcError)
    assert err.constraint == constraint
    assert err.margin <= 0
    assert what in err.what
    assert constraint in str(err)


def test_constraints_not_enforced_by_any_controller_still_define_s(load_dict, minimal):
    """The monitor holds every scenario constraint, so the initial state is checked against it
    even when only PD runs."""
    minimal["controllers"] = [minimal["controllers"][0]]
    with pytest.raises(InadmissibleStateError, match="obstacle"):
        load_dict(edit(minimal, "target", ["pi/2", "pi/2"]))


def test_missing_scenario_file_lists_shipped_ones(tmp_path):
    with pytest.raises(ScenarioError, match="thesis_ch7"):
        load_scenario(tmp_path / "nothing_here.yaml")


@pytest.mark.parametrize(
    ("text", "match"),
    [("name: [unclosed\n", "not valid YAML"), ("- 1\n- 2\n", "mapping"), ("", "mapping")],
)
def test_file_that_is_not_a_scenario_mapping(tmp_path, text, match):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=match):
        load_scenario(path)


# -- input that was once mishandled: files, keys and numbers --------------------------------
def test_duplicate_key_names_the_key_and_both_lines(tmp_path: Path) -> None:
    path = tmp_path / "dup.yaml"
    path.write_text("name: d\nsimulation: {duration: 1}\ntarget: [1, 1]\n"
                    "cases: [{name: a, position: [0, 0]}]\n"
                    "controllers: [{type: pd, kp: 1, kd: 1}]\ntarget: [2, 2]\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.field == "target"
    assert "line 6" in str(info.value) and "line 3" in str(info.value)


def test_yaml_anchors_and_merge_keys_still_work(tmp_path: Path) -> None:
    path = tmp_path / "merge.yaml"
    path.write_text("name: m\nsimulation: {duration: 0.01}\ntarget: [1, 1]\n"
                    "cases: [{name: a, position: [0, 0]}]\ncontrollers:\n"
                    "  - &pd {type: pd, name: PD, kp: 4, kd: 20}\n"
                    "  - {<<: *pd, name: PD2, kd: 10}\n")  # overriding a merged key is fine
    scenario, _ = load_scenario(path)
    assert [c.name for c in scenario.controllers] == ["PD", "PD2"]
    assert scenario.controllers[1].kd == 10 and scenario.controllers[1].kp == 4


def test_a_file_that_is_not_utf8_is_named(tmp_path: Path) -> None:
    path = tmp_path / "latin.yaml"
    path.write_bytes("name: t\ndescription: caf\xe9\n".encode("latin-1"))
    with pytest.raises(ScenarioError, match=r"not UTF-8 text: byte 0xe9 on line 2"):
        load_scenario(path)


def test_a_directory_named_yaml_is_called_a_directory(tmp_path: Path) -> None:
    folder = tmp_path / "run.yaml"
    folder.mkdir()
    (folder / "inner.yaml").write_text("name: x\n")
    with pytest.raises(ScenarioError, match=r"is a directory.*inner\.yaml"):
        load_scenario(folder)


def test_a_byte_order_mark_is_fine(tmp_path: Path, minimal) -> None:
    path = tmp_path / "bom.yaml"
    path.write_bytes(b"\xef\xbb\xbf" + yaml.safe_dump(minimal).encode())
    assert load_scenario(path)[0].name == minimal["name"]


def test_duration_shorter_than_a_period(load_dict, minimal) -> None:
    edit(minimal, "simulation.duration", 0.0005)
    expect_error(load_dict, minimal, "simulation.duration", "shorter than one control period",
                 "simulation.timestep")


def test_absurd_step_count_needs_max_steps(load_dict, minimal) -> None:
    edit(minimal, "simulation.duration", 1e7)
    err = expect_error(load_dict, minimal, "simulation.duration", "1e+10", "max_steps")
    assert "shorten the duration" in str(err)
    edit(minimal, "simulation.duration", 20.0)
    edit(minimal, "simulation.max_steps", 10_000)
    expect_error(load_dict, minimal, "simulation.duration", "2e+04")
    edit(minimal, "simulation.max_steps", 20_000)
    assert load_dict(minimal).loop_settings.duration == 20.0


def _ur5(target: list[float], start: list[float]) -> dict:
    return {"name": "ur", "robot": {"model": "ur5"}, "simulation": {"duration": 0.01},
            "target": target, "cases": [{"name": "s", "position": start}],
            "controllers": [{"type": "pd_gravity", "kp": 50, "kd": 10}]}


def test_target_outside_the_joint_range_without_a_declared_limit(load_dict) -> None:
    err = expect_error(load_dict, _ur5([0, -1, 4.0, 0, 0, 0], [0, -1, 1, 0, 0, 0]), "target",
                       "elbow_joint", "= 4", "[-3.14159, 3.14159]")
    assert "move it inside the range" in str(err)
    expect_error(load_dict, _ur5([0, -1, 1, 0, 0, 0], [0, -1, 1, 0, 7, 0]),
                 "cases[0].position", "wrist_2_joint", "= 7", "[-6.28319, 6.28319]")
    assert load_dict(_ur5([0, -1, 1, 0, 0, 0], [0, -1, 1.2, 0, 6, 0])).model.n == 6


def test_continuous_joints_take_any_angle(load_dict) -> None:
    data = _ur5([10.0, 3.0, 2.0, 0, 3.0, -9.0], [10.2, 3.0, 2.0, 0, 3.0, -9.0])
    data["robot"]["model"] = "kinova"  # joints 1, 4, 6 are continuous
    data["controllers"] = [{"type": "pd_gravity", "omega_n": 5, "zeta": 1}]  # light wrist
    setup = load_dict(data)
    assert setup.arm is not None and setup.arm.continuous_joints[0] == "j2s6s200_joint_1"


def test_locking_a_continuous_joint(load_dict) -> None:
    data = _ur5([3.0, 2.0, 0, 3.0, 0.5], [3.0, 2.0, 0, 3.0, 0.4])
    data["robot"].update(model="kinova", locked_joints={"j2s6s200_joint_1": 0.3})
    data["controllers"] = [{"type": "pd_gravity", "omega_n": 5, "zeta": 1}]
    assert load_dict(data).model.n == 5


def test_from_model_position_limits_name_the_unbounded_joints(load_dict) -> None:
    data = _ur5([0, 3.0, 2.0, 0, 3.0, 0], [0, 3.0, 2.1, 0, 3.0, 0])
    data["robot"]["model"] = "kinova"
    data["constraints"] = [{"type": "joint_position_limit", "lower": "from_model",
                            "upper": "from_model"}]
    expect_error(load_dict, data, "constraints[0].lower", "j2s6s200_joint_1",
                 "'joints': ['j2s6s200_joint_2', 'j2s6s200_joint_3', 'j2s6s200_joint_5']")


def test_physical_gains_and_their_errors(load_dict, minimal) -> None:
    minimal["controllers"] = [{"type": "pd", "omega_n": [1, 2], "zeta": 1}]
    setup = load_dict(minimal)
    d = np.diag(setup.model.inertia(setup.target))
    np.testing.assert_allclose(setup.controllers[0].controller.kp, d * [1, 4])
    minimal["controllers"] = [{"type": "pd", "omega_n": 1, "zeta": 1, "kd": 1}]
    expect_error(load_dict, minimal, "controllers[0]", "not both")
    minimal["controllers"] = [{"type": "cpbc", "kp": 1}]
    expect_error(load_dict, minimal, "controllers[0]", "omega_n")


def test_unstable_gains_name_the_coordinate_and_check_gains_overrides(load_dict,
                                                                      minimal) -> None:
    minimal["controllers"] = [{"type": "pd", "kp": 4, "kd": 5000}]
    err = expect_error(load_dict, minimal, "controllers[0]", "zero-order hold", "lower kd",
                       "control_period")
    assert "coordinate '" in str(err)
    minimal["simulation"]["check_gains"] = False
    assert load_dict(minimal).controllers[0].controller.kd[0] == 5000
    minimal["simulation"].update(check_gains=True, backend="reference")  # continuous control
    assert load_dict(minimal).controllers[0].controller.kd[0] == 5000


def test_locked_joint_errors_carry_their_field(load_dict) -> None:
    data = _ur5([0] * 5, [0] * 5)
    data["robot"]["locked_joints"] = {"wrist_9_joint": 0.0}
    expect_error(load_dict, data, "robot.locked_joints", "wrist_9_joint")


def test_an_inadmissible_state_carries_its_field(load_dict, minimal) -> None:
    edit(minimal, "cases.0.position", ["pi/2", "pi/2"])  # the end point in the obstacle
    with pytest.raises(InadmissibleStateError) as info:
        load_dict(minimal)
    assert info.value.field == "cases[0]" and info.value.constraint == "obstacle"


def test_a_urdf_arm_gets_its_motors_torque_limits_unless_told_otherwise(tmp_path) -> None:
    """Left out, simulation.torque_limit is the URDF's effort limits (the Panda's 87 / 12
    N·m), scaled by torque_limit_scale; `none` switches it off; the built-in MJCF arm,
    which declares no efforts, has none."""
    from cpbc.resources import scenarios_dir

    text = (scenarios_dir() / "panda_cpbc_sphere.yaml").read_text()
    line = "  torque_limit: from_model     # the URDF's effort limits (87 and 12 N m)\n"
    assert line in text
    limits = {}
    for name, replacement in [("absent", ""), ("none", "  torque_limit: none\n"),
                              ("half", "  torque_limit_scale: 0.5\n")]:
        path = tmp_path / f"{name}.yaml"
        path.write_text(text.replace(line, replacement))
        spec, file = load_scenario(path)
        limits[name] = build(spec, file).loop_settings.bounds.torque
    np.testing.assert_array_equal(limits["absent"], [87, 87, 87, 87, 12, 12, 12])
    np.testing.assert_array_equal(limits["half"], [43.5, 43.5, 43.5, 43.5, 6, 6, 6])
    assert limits["none"] is None
    spec, file = load_scenario("thesis_ch7")
    assert build(spec, file).loop_settings.bounds.torque is None
