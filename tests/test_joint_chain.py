"""The arm's chain as the compiled joint placements' tables (cpbc.model.joint_chain): the
placements at many configurations in one call are Pinocchio's static regressor at each, on real
URDF arms with joints about x, y, z and an unaligned axis, on MJCF arms (one with a slide), and
on a branched chain of prismatic joints; a joint of another kind leaves the placements to
Pinocchio."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from cpbc.model.joint_chain import JointChain
from cpbc.model.loading import load_arm
from cpbc.model.robot_model import RobotModel
from cpbc.resources import models_dir


def _pinocchio(model: pin.Model, rows: np.ndarray) -> np.ndarray:
    data = model.createData()
    return np.array([pin.computeStaticRegressor(model, data, q) for q in rows])


@pytest.mark.parametrize("arm", ["panda", "ur5", "pr2_left", "tiago_pro_left"])
def test_the_placements_are_pinocchio_s_on_real_arms(arm: str) -> None:
    """The Panda (about z), the UR5 (y and z), the PR2's arm (x, y and z) and TIAGo Pro's
    (an unaligned axis), at 50 configurations across and beyond their ranges: the static
    regressor's entries to 1e-14 (they are of the order of 1/mass)."""
    model = load_arm(arm).model
    chain = JointChain.of(model, RobotModel(model).regressor_scale())
    assert chain is not None
    rows = np.random.default_rng(7).uniform(-4.0, 4.0, (50, model.nq))
    expected = _pinocchio(model, rows)
    found = chain.placements(rows)
    assert found.shape == expected.shape
    np.testing.assert_allclose(found, expected, rtol=0.0, atol=1e-14)
    np.testing.assert_allclose(chain.placements(rows[3:4]), expected[3:4], rtol=0.0, atol=1e-14)
    assert chain.placements(rows[:0]).shape == (0, *expected.shape[1:])


@pytest.mark.parametrize("path", [models_dir() / "planar_2link.xml",
                                  Path(__file__).parent / "models" / "shapes_arm.xml"])
def test_the_placements_are_pinocchio_s_on_mjcf_arms(path: Path) -> None:
    """MJCF arms as Pinocchio reads them: the thesis's planar arm (two hinges about z) and
    tests/models/shapes_arm.xml (hinges about z and y, then a slide along x)."""
    robot = RobotModel.from_mjcf(path)
    chain = JointChain.of(robot.model, robot.regressor_scale())
    assert chain is not None
    rows = np.random.default_rng(2).uniform(-3.0, 3.0, (20, robot.n))
    np.testing.assert_allclose(chain.placements(rows), _pinocchio(robot.model, rows), rtol=0.0,
                               atol=1e-14)


def _branched_chain() -> pin.Model:
    """Prismatic joints along x, y, z and an unaligned axis, revolute ones about x and an
    unaligned axis, in two branches off one joint, each placed at random in its parent."""
    rng = np.random.default_rng(11)
    model = pin.Model()
    kinds = [pin.JointModelPX(), pin.JointModelRX(), pin.JointModelPY(),
             pin.JointModelRevoluteUnaligned(*(np.array([1.0, -2.0, 2.0]) / 3.0)),
             pin.JointModelPZ(), pin.JointModelPrismaticUnaligned(0.0, 0.6, 0.8)]
    parents = [0, 1, 2, 3, 2, 5]  # joints 4 and 5 both hang off joint 2
    for i, (kind, parent) in enumerate(zip(kinds, parents, strict=True)):
        joint = model.addJoint(parent, kind, pin.SE3.Random(), f"j{i}")
        inertia = pin.Inertia(float(rng.uniform(0.5, 2.0)), rng.normal(size=3) * 0.1,
                              np.diag(rng.uniform(0.01, 0.1, 3)))
        model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
    return model


def test_the_placements_are_pinocchio_s_on_a_branched_chain_of_prismatic_joints() -> None:
    pin.seed(3)
    model = _branched_chain()
    chain = JointChain.of(model, RobotModel(model).regressor_scale())
    assert chain is not None
    rows = np.random.default_rng(5).uniform(-2.0, 2.0, (30, model.nq))
    np.testing.assert_allclose(chain.placements(rows), _pinocchio(model, rows), rtol=0.0,
                               atol=1e-13)


def test_a_joint_of_another_kind_leaves_the_placements_to_pinocchio() -> None:
    model = pin.Model()
    first = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "a")
    model.addJoint(first, pin.JointModelSphericalZYX(), pin.SE3.Identity(), "b")
    assert JointChain.of(model, 1.0) is None
