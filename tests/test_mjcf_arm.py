"""MJCF files whose arm Pinocchio would not see (cpbc.model.mjcf_arm): refused by
``cpbc.robot`` and ``cpbc.run`` with exit 2 and one line naming what to change in the file,
nothing printed or written; a model without a joint refused by the API too."""

from __future__ import annotations

from pathlib import Path

import pinocchio as pin
import pytest
import yaml

from cpbc import robot, run
from cpbc.errors import ModelError
from cpbc.model import RobotModel

ARM = ("<body name='l1'><joint name='j1' type='hinge' axis='0 0 1'/><geom type='capsule' "
       "size='0.05' fromto='0 0 0 0.3 0 0' mass='1'/></body>")
# gymnasium-robotics' Fetch (reach.xml) in miniature: a mocap handle before the arm
MOCAP_FIRST = ("<mujoco><worldbody><body mocap='true' name='handle'><geom type='box' "
               "size='0.01 0.01 0.01' contype='0' conaffinity='0'/></body>" + ARM +
               "</worldbody></mujoco>")
NO_JOINT = ("<mujoco><worldbody><body name='b'><geom type='sphere' size='0.1' mass='1'/></body>"
            "</worldbody></mujoco>")


def _robot_refuses(path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert robot.main([str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


def test_an_arm_after_a_mocap_body_is_refused_naming_both(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "reach.xml"
    path.write_text(MOCAP_FIRST)
    assert pin.buildModelFromMJCF(str(path)).nq == 0  # what the check foresees
    err = _robot_refuses(path, capsys)
    assert "'handle', has no joint" in err and "move the arm's body 'l1' first" in err


def test_an_mjcf_without_a_joint_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "empty.xml"
    path.write_text(NO_JOINT)
    assert "has no joint" in _robot_refuses(path, capsys)


@pytest.mark.parametrize(("text", "named"), [(MOCAP_FIRST, "move the arm's body 'l1' first"),
                                             (NO_JOINT, "has no joint")])
def test_the_run_refuses_them_naming_the_model(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, named: str) -> None:
    (tmp_path / "arm.xml").write_text(text)
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump({
        "name": "s", "robot": {"model": "arm.xml"}, "simulation": {"duration": 0.01},
        "target": [0.1], "cases": [{"name": "a", "position": [0.0]}],
        "controllers": [{"type": "pd", "name": "PD", "kp": 4, "kd": 2}]}))
    assert run.main([str(scenario), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "robot.model" in err and named in err and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.xml", "s.yaml"]


def test_a_model_without_a_joint_is_refused_by_the_api() -> None:
    with pytest.raises(ModelError, match="no joint to drive"):
        RobotModel(pin.Model(), name="nothing")
