"""URDF arms in scenarios: limits from the model, obstacles in the scene, clearance, short
closed-loop runs of the Panda and UR5 scenarios, and bad input that exits 2 writing nothing."""

from __future__ import annotations

import io
import json
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yaml
from rich.console import Console

from cpbc.constraints.clearance import Clearance
from cpbc.errors import InadmissibleStateError, ScenarioError
from cpbc.resources import scenarios_dir
from cpbc.results.summary_table import summary_table
from cpbc.run import main
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import run_all

PANDA_HOME = [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]


def _shipped(name: str) -> dict:
    return yaml.safe_load((scenarios_dir() / f"{name}.yaml").read_text())


def _write(folder: Path, data: dict, name: str = "arm.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _build(folder: Path, data: dict):
    return build(*load_scenario(_write(folder, data)))


def _panda(**changes: object) -> dict:
    data: dict = {
        "name": "panda_small",
        "robot": {"model": "panda"},
        "simulation": {"duration": 0.05, "integrator": "implicitfast"},
        "target": PANDA_HOME,
        "cases": [{"name": "rest", "position": PANDA_HOME}],
        "obstacles": [{"type": "sphere", "name": "ball", "centre": [0.5, 0, 0.3],
                       "radius": 0.08}],
        "constraints": [{"type": "clearance", "margin": 0.01}],
        "controllers": [{"type": "cpbc", "name": "CPBC", "kp": 20, "kd": 5}],
    }
    data.update(changes)
    return data


def _clearance_summary(results, setup) -> dict[str, tuple[float, int]]:
    names = [n for c in setup.monitor.configuration if isinstance(c, Clearance)
             for n in c.names]
    return {r.controller: (min(r.summary.min_margins[n] for n in names), r.summary.max_contacts)
            for r in results}


# -- limits and scene ---------------------------------------------------------------------
def test_limits_come_from_the_urdf(tmp_path: Path) -> None:
    data = _shipped("panda_cpbc_sphere")
    setup = _build(tmp_path, data)
    limits, rates, clearance = setup.monitor.configuration[0], setup.monitor.velocity[0], \
        setup.monitor.configuration[1]
    np.testing.assert_allclose(limits.lower, setup.arm.position_lower)
    np.testing.assert_allclose(limits.upper, setup.arm.position_upper)
    np.testing.assert_allclose(rates.bounds, 0.5 * setup.arm.velocity_limit)
    np.testing.assert_allclose(setup.loop_settings.bounds.torque, setup.arm.effort_limit)
    assert isinstance(clearance, Clearance)
    assert setup.rate_bounds == pytest.approx((0.5 * setup.arm.velocity_limit).tolist())
    ur5 = _build(tmp_path, _shipped("ur5_bpbc"))
    np.testing.assert_allclose(ur5.loop_settings.bounds.torque, [75, 75, 75, 14, 14, 14])


def test_obstacles_are_bodies_in_the_mujoco_scene(tmp_path: Path) -> None:
    data = _panda(obstacles=[
        {"type": "sphere", "name": "ball", "centre": [0.5, 0, 0.3], "radius": 0.08},
        {"type": "cylinder", "name": "pole", "start": [0.3, 0.5, 0], "end": [0.3, 0.5, 1],
         "radius": 0.03},
        {"type": "capsule", "name": "bar", "start": [-0.5, -0.5, 0.8], "end": [-0.5, 0.5, 0.8],
         "radius": 0.03, "collides": False},
        {"type": "box", "name": "crate", "centre": [0.4, -0.4, 0.1],
         "half_extents": [0.1, 0.1, 0.1], "rpy": [0, 0, 0.5]},
        {"type": "plane", "name": "table", "point": [0, 0, 0]},
    ])
    setup = _build(tmp_path, data)
    model = setup.make_plant().model
    kinds = {"ball": mujoco.mjtGeom.mjGEOM_SPHERE, "pole": mujoco.mjtGeom.mjGEOM_CYLINDER,
             "bar": mujoco.mjtGeom.mjGEOM_CAPSULE, "crate": mujoco.mjtGeom.mjGEOM_BOX,
             "table": mujoco.mjtGeom.mjGEOM_PLANE}
    for name, kind in kinds.items():
        g = model.geom(name)
        assert g.type == kind and g.bodyid == 0
        assert (g.contype, g.conaffinity) == ((0, 0) if name == "bar" else (1, 1))
    np.testing.assert_allclose(model.geom("crate").size, [0.1, 0.1, 0.1])
    np.testing.assert_allclose(model.geom("pole").size[:2], [0.03, 0.5])
    assert model.nu == 7  # one motor per joint: the plant drives actuators
    clearance = setup.monitor.configuration[0]
    assert len(clearance.names) == 10 * 5  # every moving link against every obstacle


def test_declared_primitives_self_pairs_and_locked_joints(tmp_path: Path) -> None:
    data = _panda(
        robot={"model": "panda", "locked_joints": {"panda_joint7": 0.8}},
        target=PANDA_HOME[:6], cases=[{"name": "rest", "position": PANDA_HOME[:6]}],
        constraints=[{
            "type": "clearance", "links": ["panda_link5", "panda_link6"],
            "primitives": [{"link": "panda_hand", "name": "palm", "centre": [0, 0, 0.06],
                            "radius": 0.06},
                           {"link": "panda_link3", "start": [0, 0, -0.1], "end": [0, 0, 0],
                            "radius": 0.07}],
            "self_collision": [["panda_link3", "panda_hand"]],
        }],
        controllers=[{"type": "cpbc", "name": "CPBC", "kp": 20, "kd": 5}],
    )
    setup = _build(tmp_path, data)
    assert setup.model.n == 6
    clearance = setup.monitor.configuration[0]
    frames = {p.frame for p in clearance.primitives}
    assert frames == {"panda_hand", "panda_link3", "panda_link5", "panda_link6"}
    # spheres are reported per link, capsules per primitive (named after its link by default)
    assert "clearance[panda_link3|palm]" in clearance.names
    assert "clearance[panda_link3|ball]" in clearance.names
    assert "clearance[panda_hand|ball]" in clearance.names
    assert setup.make_plant().n == 6


# -- closed loop --------------------------------------------------------------------------
def test_panda_sphere_pd_hits_the_ball_cpbc_does_not(tmp_path: Path) -> None:
    data = _shipped("panda_cpbc_sphere")
    data["simulation"]["duration"] = 0.5  # PD + gravity reaches the ball at ~0.17 s
    setup = _build(tmp_path, data)
    results = run_all(setup)
    clearance = _clearance_summary(results, setup)
    assert clearance["PD+g"][0] < 0 and clearance["PD+g"][1] > 0
    assert clearance["CPBC"][0] > 0 and clearance["CPBC"][1] == 0
    cpbc = next(r for r in results if r.controller == "CPBC").summary
    assert cpbc.status != "constraint_violated" and not cpbc.crossed_constraints


def test_ur5_bpbc_keeps_its_rate_limits_under_gravity(tmp_path: Path) -> None:
    data = _shipped("ur5_bpbc")
    data["simulation"]["duration"] = 0.6
    setup = _build(tmp_path, data)
    results = {r.controller: r.summary for r in run_all(setup)}
    bounds = np.array(setup.rate_bounds, dtype=float)
    assert np.all(np.array(results["BPBC"].peak_joint_rates) < bounds)
    assert np.any(np.array(results["PD+g"].peak_joint_rates) > bounds)
    assert results["BPBC"].saturated_steps == 0
    assert results["PD+g"].saturated_steps > 0


def test_ur5_table_names_the_joint_nearest_its_rate_bound(tmp_path: Path) -> None:
    data = _shipped("ur5_bpbc")
    data["simulation"]["duration"] = 0.6
    setup = _build(tmp_path, data)
    results = run_all(setup)
    console = Console(width=400, record=True, file=io.StringIO())
    console.print(summary_table([r.summary for r in results], setup.coordinate_names))
    table = console.export_text()
    assert "peak |rate|, nearest its bound" in table
    for r in results:
        s = r.summary
        ratios = [p / b for p, b in zip(s.peak_joint_rates, s.rate_bounds, strict=True)]
        i = int(np.argmax(ratios))
        over = sum(x >= 1 for x in ratios)
        row = next(line for line in table.splitlines() if f" {r.controller} " in line)
        assert f"({setup.coordinate_names[i]})" in row
        assert (f"{over} of 6 over" if over else "all 6 within") in row
    assert {r.controller: sum(p >= b for p, b in zip(r.summary.peak_joint_rates,
                                                       r.summary.rate_bounds, strict=True))
            > 0 for r in results} == {"PD+g": True, "BPBC": False}


# -- bad input ----------------------------------------------------------------------------
def _exit_code(tmp_path: Path, data: dict) -> tuple[int, Path]:
    out = tmp_path / "out"
    return main([str(_write(tmp_path, data)), "--out", str(out), "--quiet"]), out


@pytest.mark.parametrize(
    ("robot", "words"),
    [
        ({"model": "nao"}, ["robot.model", "panda", "ur5"]),
        ({"model": "missing/arm.urdf"}, ["robot.model", "URDF file not found"]),
        ({"model": "panda", "locked_joints": {"gripper": 0.0}}, ["robot.locked_joints",
                                                                 "gripper"]),
    ],
)
def test_bad_robot_exits_2_and_writes_nothing(tmp_path, capsys, robot, words) -> None:
    code, out = _exit_code(tmp_path, _panda(robot=robot))
    assert code == 2 and not out.exists()
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for w in words:
        assert w in err


def test_missing_mesh_exits_2(tmp_path: Path, capsys) -> None:
    urdf = tmp_path / "one.urdf"
    urdf.write_text(
        '<robot name="one"><link name="base"/><link name="arm"><inertial><mass value="1"/>'
        '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
        '<collision><geometry><mesh filename="package://gone/arm.stl"/></geometry></collision>'
        '</link><joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>'
        "</robot>"
    )
    data = _panda(robot={"model": "one.urdf"}, target=[0.1], cases=[
        {"name": "rest", "position": [0.0]}], obstacles=[], constraints=[])
    code, out = _exit_code(tmp_path, data)
    assert code == 2 and not out.exists()
    assert "package://gone/arm.stl" in capsys.readouterr().err


def test_unknown_joint_and_link_names(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="wrist") as info:
        _build(tmp_path, _panda(constraints=[
            {"type": "joint_rate_limit", "joints": ["wrist"], "bounds": [1.0]}]))
    assert info.value.field == "constraints[0].joints"
    with pytest.raises(ScenarioError, match="panda_link9") as info:
        _build(tmp_path, _panda(constraints=[{"type": "clearance", "links": ["panda_link9"]}]))
    assert info.value.field == "constraints[0].links"
    with pytest.raises(ScenarioError, match="unknown obstacles") as info:
        _build(tmp_path, _panda(constraints=[{"type": "clearance", "obstacles": ["wall"]}]))
    with pytest.raises(ScenarioError, match="panda_link9"):
        _build(tmp_path, _panda(constraints=[
            {"type": "clearance", "self_collision": [["panda_link1", "panda_link9"]]}]))


def test_state_inside_an_obstacle_exits_2(tmp_path: Path, capsys) -> None:
    data = _panda(obstacles=[{"type": "sphere", "name": "ball", "centre": [0.55, 0, 0.45],
                              "radius": 0.1}])
    with pytest.raises(InadmissibleStateError, match=r"clearance\[panda_"):
        _build(tmp_path, data)
    code, out = _exit_code(tmp_path, data)
    assert code == 2 and not out.exists()
    assert "target is outside the admissible set" in capsys.readouterr().err
    low = [0, 0.9, 0, -0.8, 0, 1.5, 0.8]
    arm = _build(tmp_path, _panda()).arm
    pdata = arm.model.createData()
    pin.framesForwardKinematics(arm.model, pdata, np.array(low))
    hand = pdata.oMf[arm.model.getFrameId("panda_hand")].translation.tolist()
    moved = _panda(cases=[{"name": "low", "position": low}],
                   obstacles=[{"type": "sphere", "name": "ball", "centre": hand, "radius": 0.02}])
    with pytest.raises(InadmissibleStateError, match=r"initial state of case 'low'.*panda_hand"):
        _build(tmp_path, moved)


def test_effort_limits_declared_for_some_joints_only_are_named(tmp_path: Path, capsys) -> None:
    """A horizontal arm that declares an effort limit on j1 (1 N·m, less than PD + g asks) and
    none on j2: `torque_limit: auto` limits j1 alone, and says so, naming the joint without
    one."""
    link = ('<link name="{0}"><inertial><origin xyz="0.2 0 0"/><mass value="1"/><inertia '
            'ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
    joint = ('<joint name="{0}" type="revolute"><parent link="{1}"/><child link="{2}"/>'
             '<origin xyz="{3} 0 0"/><axis xyz="0 0 1"/>'
             '<limit lower="-2" upper="2" effort="{4}" velocity="2"/></joint>')
    (tmp_path / "two.urdf").write_text(
        '<robot name="two"><link name="base"/>' + link.format("a") + link.format("b")
        + joint.format("j1", "base", "a", 0, 1) + joint.format("j2", "a", "b", 0.4, 0)
        + "</robot>")
    data = _panda(robot={"model": "two.urdf"}, target=[0.1, 0.2], cases=[
        {"name": "rest", "position": [0.0, 0.0]}], obstacles=[], constraints=[],
        controllers=[{"type": "pd_gravity", "name": "PD", "kp": 20, "kd": 5}])
    code, out = _exit_code(tmp_path, data)
    assert code == 0
    err = capsys.readouterr().err
    assert "effort limits for 1 of its 2 joints (none for j2)" in err
    (run,) = json.loads((out / "summary.json").read_text())
    assert run["torque_limits"] == [1.0, None]
    assert run["peak_commanded_torques"][0] > 1.0 >= run["peak_joint_torques"][0]
    assert run["saturated_steps"] > 0
