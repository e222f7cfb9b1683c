"""Margins in the unit of the coordinates they bound: a prismatic joint's position and rate
limits in m and m/s, a revolute joint's in rad and rad/s."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from cpbc.constraints import ConstraintSet
from cpbc.constraints.linear_limit import LinearLimit
from cpbc.model import RobotModel
from cpbc.results.margin_types import types_of
from cpbc.run import main

# A cart on a rail (slide joint, m) carrying a link (hinge, rad), in the horizontal plane.
CART_ARM = """\
<mujoco model="cart_arm">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.001" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="cart">
      <joint name="rail" type="slide" axis="1 0 0" range="-1 1"/>
      <inertial pos="0 0 0" mass="2" diaginertia="0.1 0.1 0.1"/>
      <body name="link">
        <joint name="hinge" type="hinge" axis="0 0 1" range="-2 2"/>
        <inertial pos="0.5 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
        <site name="tip" pos="1 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="rail"/>
    <motor joint="hinge"/>
  </actuator>
</mujoco>
"""


def test_prismatic_margins_are_in_metres(tmp_path: Path) -> None:
    (tmp_path / "cart_arm.xml").write_text(CART_ARM)
    scenario = {
        "name": "cart_arm",
        "robot": {"model": "cart_arm.xml"},
        "simulation": {"duration": 0.05, "timestep": 0.001},
        "target": [0.2, 0.5],
        "cases": [{"name": "rest", "position": [0, 0]}],
        "constraints": [
            {"type": "joint_position_limit", "name": "stops", "lower": [-0.8, -1.5],
             "upper": [0.8, 1.5]},
            {"type": "joint_rate_limit", "name": "rates", "bounds": [0.5, 0.6]},
        ],
        "controllers": [{"type": "pd", "name": "PD", "kp": 2, "kd": 4}],
    }
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    out = tmp_path / "out"
    assert main([str(path), "--out", str(out), "--quiet", "--no-plots", "--workers", "1"]) == 0
    summary = json.loads((out / "summary.json").read_text())[0]
    units = {w["type"]: w["unit"] for w in summary["worst_margins"]}
    assert units == {"position": "rad", "rate": "rad/s", "travel": "m", "speed": "m/s"}
    assert summary["margin_types"] == {"position[rail]": "travel", "position[hinge]": "position",
                                       "rate[rail]": "speed", "rate[hinge]": "rate"}


def test_a_limit_mixing_prismatic_and_revolute_coordinates_has_no_unit(tmp_path: Path) -> None:
    (tmp_path / "cart_arm.xml").write_text(CART_ARM)
    model = RobotModel.from_mjcf(tmp_path / "cart_arm.xml")
    assert model.length_coordinates.tolist() == [True, False]
    limits = LinearLimit([[1, 0], [0, 1], [1, 1]], [-1, -1, -1], [1, 1, 1], ["a", "b", "c"])
    assert types_of(ConstraintSet(2, [limits]), model.length_coordinates) == (
        "travel", "position", "other")
    assert types_of(ConstraintSet(2, [limits])) == ("position",) * 3  # no model: angles
