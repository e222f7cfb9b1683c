"""An MJCF arm's effort limits from its actuators (cpbc.model.actuators): ``ctrlrange`` ×
``gear`` of a motor, ``forcerange`` × ``gear``, the joint's ``actuatorfrcrange``, read
into the controller's model, where ``simulation.torque_limit: from_model`` and ``auto``
apply them — as ``python -m cpbc.robot`` prints them. An MJCF written here; robosuite's
Panda too when robosuite is installed (it is no dependency)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yaml

from cpbc.model.actuators import actuator_efforts, apply_actuator_efforts
from cpbc.robot import describe
from cpbc.scenario import build, load_scenario

ARM = """<mujoco model="five">
  <compiler angle="radian"/>
  <worldbody>
    <body name="l1">
      <joint name="j1" type="hinge" axis="0 0 1" range="-2 2" actuatorfrcrange="-30 30"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
      <body name="l2" pos="0.3 0 0">
        <joint name="j2" type="hinge" axis="0 1 0" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
        <body name="l3" pos="0.3 0 0">
          <joint name="j3" type="hinge" axis="0 1 0" range="-2 2"/>
          <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03" mass="0.5"/>
          <body name="l4" pos="0.2 0 0">
            <joint name="j4" type="hinge" axis="1 0 0" range="-2 2"
                   actuatorfrcrange="-6 6"/>
            <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.02" mass="0.3"/>
            <body name="l5" pos="0.1 0 0">
              <joint name="j5" type="hinge" axis="0 1 0" range="-2 2"/>
              <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.02" mass="0.2"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="j2" gear="50" ctrlrange="-1 1" ctrllimited="true"/>
    <general joint="j3" gear="2" forcerange="-4 5" forcelimited="true"/>
    <motor joint="j4" gear="1" ctrlrange="-3 3" ctrllimited="true"/>
    <motor joint="j4" gear="1" ctrlrange="-3 3" ctrllimited="true"/>
    <position joint="j5" kp="100" ctrlrange="-1 1" ctrllimited="true"/>
  </actuator>
</mujoco>
"""
# j1: only its actuatorfrcrange (30); j2: gear × ctrlrange (50); j3: gear × min|forcerange|
# (8); j4: two motors of 3 add up to 6, and so does actuatorfrcrange (6); j5: a position
# servo, whose ctrlrange is a set point's (no bound)
EFFORTS = [30.0, 50.0, 8.0, 6.0, np.inf]


@pytest.fixture
def arm(tmp_path: Path) -> Path:
    path = tmp_path / "five.xml"
    path.write_text(ARM)
    return path


def test_each_joint_has_the_bound_of_what_drives_it(arm: Path) -> None:
    mj = mujoco.MjModel.from_xml_path(str(arm))
    np.testing.assert_array_equal(actuator_efforts(mj, list(range(5))), EFFORTS)
    model = pin.buildModelFromMJCF(str(arm))
    # Pinocchio reads the joints' actuatorfrcrange only
    np.testing.assert_array_equal(model.effortLimit, [30.0, np.inf, np.inf, 6.0, np.inf])
    written = apply_actuator_efforts(model, mj)
    np.testing.assert_array_equal(written, EFFORTS)
    np.testing.assert_array_equal(model.effortLimit, EFFORTS)


def test_a_joint_bound_tighter_than_its_motors_wins(tmp_path: Path) -> None:
    path = tmp_path / "tight.xml"
    path.write_text(ARM.replace('range="-2 2"/>\n        <geom type="capsule" fromto="0 0 0 '
                                '0.3 0 0" size="0.03" mass="1"/>\n        <body name="l3"',
                                'range="-2 2" actuatorfrcrange="-20 20"/>\n        <geom '
                                'type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>'
                                '\n        <body name="l3"'))
    mj = mujoco.MjModel.from_xml_path(str(path))
    assert actuator_efforts(mj, [1])[0] == 20.0  # j2: the motor's 50, the joint's 20


def _scenario(tmp_path: Path, model: Path, torque_limit: str, rest: list[float]) -> Path:
    scenario = {
        "name": "mjcf_efforts", "robot": {"model": str(model)},
        "simulation": {"duration": 0.01, "timestep": 0.001, "torque_limit": torque_limit},
        "target": [x + 0.1 for x in rest], "cases": [{"name": "rest", "position": rest}],
        "controllers": [{"type": "pd_gravity", "name": "PD+g", "kp": 1.0, "kd": 0.01}],
    }
    path = tmp_path / f"scenario_{torque_limit}.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    return path


def test_a_scenario_runs_with_the_actuators_limits(arm: Path, tmp_path: Path) -> None:
    # auto: where declared (j5 runs unlimited); from_model refuses the joint without one
    setup = build(*load_scenario(_scenario(tmp_path, arm, "auto", [0.0] * 5)))
    assert setup.loop_settings.bounds.torque is not None
    np.testing.assert_array_equal(setup.loop_settings.bounds.torque, EFFORTS)
    with pytest.raises(Exception, match=r"no effort limit for joints \['j5'\]"):
        build(*load_scenario(_scenario(tmp_path, arm, "from_model", [0.0] * 5)))


def test_the_printed_efforts_are_the_ones_that_run(arm: Path) -> None:
    np.testing.assert_array_equal(describe(str(arm)).limits.effort, EFFORTS)


ROBOSUITE = importlib.util.find_spec("robosuite")


@pytest.mark.skipif(ROBOSUITE is None, reason="robosuite is not installed")
def test_robosuites_panda_runs_with_its_printed_efforts(tmp_path: Path) -> None:
    assert ROBOSUITE is not None and ROBOSUITE.origin is not None
    panda = (Path(ROBOSUITE.origin).parent / "models" / "assets" / "robots" / "panda"
             / "robot.xml")
    setup = build(*load_scenario(_scenario(tmp_path, panda, "from_model",
                                           [0.0, 0.0, 0.0, -1.57, 0.0, 1.87, 0.0])))
    assert setup.loop_settings.bounds.torque is not None
    np.testing.assert_array_equal(setup.loop_settings.bounds.torque, [80] * 5 + [12] * 2)
    np.testing.assert_array_equal(describe(str(panda)).limits.effort, [80] * 5 + [12] * 2)
