"""Every arm cpbc knows by name: its skeleton scenario (``python -m cpbc.robot``) builds and runs
PD + gravity and CPBC in MuJoCo and in the continuous-time reference (Pinocchio), and the two
engines tell the same story over a short run."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest
import yaml

from cpbc.model.arms import available_arms
from cpbc.robot import describe, main, scenario_for
from cpbc.scenario import Scenario, build, load_scenario
from cpbc.scenario.runner import run_one

DURATION = 0.05  # s: 50 control steps, enough to see both engines move the arm alike


def test_the_arms_of_issue_14_are_known() -> None:
    assert {"panda", "ur3", "ur5", "ur10", "xarm7", "z1", "kinova", "so100", "so101",
            "talos_arm", "baxter_left", "baxter_right", "ur5_limited", "ur5_gripper"} <= set(
        available_arms())


@pytest.mark.parametrize("name", available_arms())
def test_skeleton_runs_in_both_engines(name: str, tmp_path: Path) -> None:
    data = scenario_for(describe(name), DURATION)
    # The engines are compared on the laws themselves. With the URDF's effort limits (the
    # default) the reference backend, which has no safeguard, clips the torque: the Talos
    # arm's skeleton target needs 21.7 of joint 1's 22.3 N·m for gravity alone, and the
    # clipped CPBC breaks joint 2's range there (MuJoCo's guarded run keeps it).
    data["simulation"]["torque_limit"] = "none"
    # Dry friction differs between the engines by design (MuJoCo's frictionloss is a
    # constraint, the reference's F_c tanh(q̇/ε)); over 50 ms an arm with it (the fr3's own,
    # by default) hardly moves, and that difference is all the comparison would see.
    data["robot"]["friction"] = "none"
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    setup = build(*load_scenario(path))
    assert [c.name for c in setup.controllers] == ["PD_gravity", "CPBC"]
    case = setup.cases[0]
    for entry in setup.controllers:
        runs = {b: run_one(setup, case, entry, b) for b in ("mujoco", "reference")}
        for backend, r in runs.items():
            assert r.summary.status not in ("diverged", "constraint_violated"), (backend, r)
            v = r.trajectory.lyapunov  # V̇ ≤ 0 for both laws: the arm is heading home
            assert np.all(np.isfinite(v)) and v[-1] < v[0], (backend, entry.name, v[0], v[-1])
            assert np.all(np.isfinite(r.margins))
            if entry.name == "CPBC":  # it enforces the ranges and rates; PD + g only watches
                assert np.min(r.margins) > 0, (backend, np.min(r.margins))
        a, b = runs["mujoco"].trajectory, runs["reference"].trajectory
        ref = np.column_stack([np.interp(a.time, b.time, b.position[:, i])
                               for i in range(setup.model.n)])
        moved = np.max(np.abs(a.position[-1] - a.position[0]))
        # the loop holds the torque for 1 ms, the reference does not: a few % of the motion
        assert np.max(np.abs(a.position - ref)) < 0.05 * moved, (entry.name, moved)


def _cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def test_robot_cli_prints_joints_and_a_valid_scenario() -> None:
    code, out, err = _cli("kinova")
    assert code == 0 and err == ""
    for joint in ("j2s6s200_joint_1", "j2s6s200_joint_6"):
        assert joint in out
    assert "(continuous)" in out and "unbounded" in out
    assert "j2s6s200_end_effector" in out  # a frame
    data = yaml.safe_load(out)  # the whole output is YAML: the description is comments
    scenario = Scenario.model_validate(data)
    assert scenario.robot.model == "kinova"
    limits = scenario.constraints[0]
    assert limits.joints == ["j2s6s200_joint_2", "j2s6s200_joint_3", "j2s6s200_joint_5"]


def test_robot_cli_output_runs(tmp_path: Path) -> None:
    code, out, _ = _cli("ur5", "--duration", "0.02")
    assert code == 0
    path = tmp_path / "ur5.yaml"
    path.write_text(out)
    setup = build(*load_scenario(path))
    assert setup.model.n == 6


def test_robot_cli_builtin_mjcf() -> None:
    code, out, _ = _cli("planar_2link")
    assert code == 0 and "joint1" in out and "end_point" in out
    Scenario.model_validate(yaml.safe_load(out))


@pytest.mark.parametrize(("arg", "words"), [
    ("nao", "unknown robot 'nao'"),
    (".", "is a directory"),
    ("missing.urdf", "URDF file not found"),
    ("missing.xml", "model file not found"),
    ("arm.urdf.xacro", "xacro source"),
])
def test_robot_cli_bad_names_exit_2(arg: str, words: str) -> None:
    code, out, err = _cli(arg)
    assert code == 2 and out == ""
    assert words in err and "Traceback" not in err


def test_a_urdf_saved_as_xml_is_read_as_urdf(tmp_path: Path) -> None:
    from cpbc.model.arms import arm_urdf

    path = tmp_path / "ur5.xml"
    path.write_text(arm_urdf("ur5").read_text())
    code, out, _ = _cli(str(path), "--duration", "0.02")
    assert code == 0 and "shoulder_pan_joint" in out
    (tmp_path / "s.yaml").write_text(out)
    assert build(*load_scenario(tmp_path / "s.yaml")).arm is not None


_MOTORS = """<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="l1"><joint name="j1" axis="0 1 0" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
      <body name="l2" pos="0.5 0 0"><joint name="j2" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
        <body name="l3" pos="0.4 0 0"><joint name="j3" axis="0 1 0"/>
          <geom type="sphere" size="0.05"/></body></body></body>
  </worldbody>
  <actuator>
    <motor joint="j1" ctrlrange="-40 50" gear="2"/>
    <motor joint="j2" forcerange="-7 7" forcelimited="true"/>
    <motor joint="j3"/>
  </actuator>
</mujoco>
"""


def test_robot_cli_shows_the_effort_limits_of_mjcf_actuators(tmp_path: Path) -> None:
    path = tmp_path / "motors.xml"
    path.write_text(_MOTORS)
    np.testing.assert_allclose(describe(str(path)).limits.effort, [80.0, 7.0, np.inf])
    code, out, _ = _cli(str(path))
    assert code == 0
    rows = {line.split()[1]: line.split()[-1] for line in out.splitlines()
            if line.startswith("#   j") and "effort" not in line and " of " not in line}
    assert rows == {"j1": "80", "j2": "7", "j3": "-"}


def test_package_dirs_that_do_not_exist_name_the_field(tmp_path: Path) -> None:
    from cpbc import run
    from cpbc.errors import ScenarioError
    from cpbc.scenario.robots import load_scenario_arm
    from cpbc.scenario.schema import RobotSpec

    with pytest.raises(ScenarioError, match=r"^robot\.package_dirs: .*nope"):
        load_scenario_arm(RobotSpec(model="ur5", package_dirs=["nope"]), tmp_path)
    data = scenario_for(describe("ur5"), 0.01)
    data["robot"]["package_dirs"] = ["nope"]
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = run.main([str(tmp_path / "s.yaml"), "--quiet", "--no-plots"])
    assert code == 2 and "robot.package_dirs" in err.getvalue() + out.getvalue()
    assert "Traceback" not in err.getvalue()
