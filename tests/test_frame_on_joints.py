"""A frame read from a pass's joint kinematics (cpbc.kernels.task.frame_on_joints, as a
packed law's kernel reads its task frame) against Pinocchio's own frame placement and
LOCAL_WORLD_ALIGNED frame Jacobian, on serial arms and a branching tree."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from cpbc.kernels.task import frame_on_joints
from cpbc.model import RobotModel
from cpbc.model.loading import load_arm


@pytest.mark.parametrize("arm", ["panda", "ur5", "xarm7", "kinova", "baxter_left"])
def test_the_frame_from_the_joint_kinematics_is_pinocchios(arm: str) -> None:
    loaded = load_arm(arm)
    model = RobotModel(loaded.model, name=arm)
    pm, data = model.model, model.data
    frames = [i for i, f in enumerate(pm.frames) if f.parentJoint > 0]
    frames = frames[:: max(1, len(frames) // 12)]
    on_joints = [model.frame_on_joints(frame) for frame in frames]  # (a pass of its own)
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(5):
        q = rng.uniform(-2.0, 2.0, model.n)
        pin.computeAllTerms(pm, data, q, np.zeros(model.n))
        y = pin.computeStaticRegressor(pm, data, q).copy()
        jac = data.J.copy()
        for frame, found in zip(frames, on_joints, strict=True):
            assert found is not None
            placement, jacobian = np.empty((4, 4)), np.empty((6, model.n))
            frame_on_joints(y, jac, found[0], found[1], placement, jacobian)
            np.testing.assert_allclose(
                placement, pin.updateFramePlacement(pm, data, frame).homogeneous,
                rtol=0, atol=1e-12)
            np.testing.assert_allclose(
                jacobian, pin.getFrameJacobian(pm, data, frame,
                                               pin.ReferenceFrame.LOCAL_WORLD_ALIGNED),
                rtol=0, atol=1e-12)
            checked += 1
    assert checked >= 20


def test_a_frame_welded_to_the_world_is_read_by_the_pass() -> None:
    model = RobotModel(load_arm("panda").model, name="panda")
    assert model.frame_on_joints(0) is None  # the universe frame
