"""The arm's reach (cpbc.taskspace.reach): a bound no configuration exceeds, exact for a
stretched planar arm, grown by a prismatic joint's travel."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from cpbc.model import RobotModel
from cpbc.model.loading import load_arm
from cpbc.resources import models_dir
from cpbc.taskspace.goal import FrameGoal
from cpbc.taskspace.reach import reach


@pytest.mark.parametrize(("arm", "frame"), [("panda", "panda_hand"), ("ur5", "tool0")])
def test_no_configuration_takes_the_point_beyond_the_reach(arm: str, frame: str) -> None:
    loaded = load_arm(arm)
    model = RobotModel(loaded.model, name=arm)
    fid = loaded.model.getFrameId(frame)
    found = reach(model, FrameGoal(fid, frame, np.zeros(3), offset=np.array([0, 0, 0.1])))
    data = loaded.model.createData()
    rng = np.random.default_rng(1)
    farthest = 0.0
    for _ in range(2000):
        q = rng.uniform(loaded.model.lowerPositionLimit, loaded.model.upperPositionLimit)
        pin.framesForwardKinematics(loaded.model, data, q)
        point = data.oMf[fid].act(np.array([0, 0, 0.1]))
        farthest = max(farthest, float(np.linalg.norm(point - found.centre)))
    assert farthest <= found.radius
    assert farthest > 0.7 * found.radius  # a bound, and not a loose one
    assert found.beyond(found.centre + np.array([0, 0, found.radius + 2.0])) == pytest.approx(2.0)


def test_a_stretched_planar_arm_reaches_exactly_its_link_lengths() -> None:
    model = RobotModel.from_mjcf(models_dir() / "planar_2link.xml")
    goal = FrameGoal(model.model.getFrameId("end_point"), "end_point", np.zeros(3))
    found = reach(model, goal)
    stretched = model.frame_placement(goal.frame, np.zeros(model.n))[0]
    assert np.linalg.norm(stretched - found.centre) == pytest.approx(found.radius)


def test_a_prismatic_joint_adds_its_travel() -> None:
    pm = pin.Model()
    slide = pm.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "slide")
    pm.lowerPositionLimit[0], pm.upperPositionLimit[0] = -0.2, 0.5
    placement = pin.SE3(np.eye(3), np.array([0.0, 0.3, 0.0]))
    hinge = pm.addJoint(slide, pin.JointModelRZ(), placement, "hinge")
    pm.lowerPositionLimit[1], pm.upperPositionLimit[1] = -3.0, 3.0
    pm.appendBodyToJoint(slide, pin.Inertia.FromSphere(1.0, 0.05), pin.SE3.Identity())
    pm.appendBodyToJoint(hinge, pin.Inertia.FromSphere(1.0, 0.05), pin.SE3.Identity())
    tip = pm.addFrame(pin.Frame("tip", hinge, 0, pin.SE3(np.eye(3), np.array([0.4, 0, 0])),
                                pin.FrameType.OP_FRAME))
    found = reach(RobotModel(pm, name="slider"), FrameGoal(tip, "tip", np.zeros(3)))
    assert found.radius == pytest.approx(0.5 + 0.3 + 0.4)
