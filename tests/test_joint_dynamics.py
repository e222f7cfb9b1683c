"""The joints' rotor inertia and friction (cpbc.model.joint_dynamics) in the controller's
model and the MuJoCo plant: Pinocchio's D with armature against MuJoCo's mj_fullM, the
model's friction against its formula, and what MJCF and URDF files declare read as
declared."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from cpbc.errors import ModelError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.joint_dynamics import JointDynamics
from cpbc.model.loading import load_arm
from cpbc.resources import models_dir

# an FR3's rotor inertia (franky-sim's MuJoCo model)
FR3_ARMATURE = np.array([0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074])


def test_pinocchio_inertia_with_armature_equals_mujoco_full_m() -> None:
    """The Panda with an FR3's rotor inertia: Pinocchio's CRBA (the controller's D) equals
    MuJoCo's mj_fullM with the same dof_armature, and its ABA MuJoCo's forward dynamics
    with the same viscous friction, at random states."""
    arm = load_arm("panda")
    joints = JointDynamics(FR3_ARMATURE, np.full(7, 0.21), np.zeros(7))
    model = RobotModel(joints.on_pinocchio(arm.model), viscous_friction=joints.viscous)
    plant = arm.mujoco_model()
    joints.on_mujoco(plant)
    data = mujoco.MjData(plant)
    rng = np.random.default_rng(36)
    bare = RobotModel(arm.model)
    for _ in range(5):
        q = rng.uniform(arm.position_lower, arm.position_upper)
        dq, tau = rng.normal(size=7), rng.normal(scale=5.0, size=7)
        data.qpos[:], data.qvel[:], data.ctrl[:] = q, dq, tau
        mujoco.mj_forward(plant, data)
        full = np.zeros((7, 7))
        mujoco.mj_fullM(plant, data, full)
        np.testing.assert_allclose(model.inertia(q), full, atol=1e-10)
        np.testing.assert_allclose(model.inertia(q) - bare.inertia(q), np.diag(FR3_ARMATURE),
                                   atol=1e-12)
        np.testing.assert_allclose(model.forward_dynamics(q, dq, tau), data.qacc, atol=1e-8)


def test_a_light_wrist_meets_its_whole_dry_friction_while_it_slides() -> None:
    """The xArm7's last joint (a link of 1.4e-4 kg·m²) with 0.01 kg·m² of rotor inertia and
    2 N·m of Coulomb friction, sliding at 1.5 rad/s and pushed along by its friction's level
    (as a brake that cancels the model's friction pushes it): MuJoCo's frictionloss opposes
    it with its whole level, as it does where the MJCF declares the armature. With the
    constants MuJoCo derived at compile time (no armature) it gave 0.39 N·m."""
    arm = load_arm("xarm7")
    joints = JointDynamics(np.array([0.05, 0.05, 0.03, 0.03, 0.01, 0.01, 0.01]),
                           np.zeros(7), np.array([0.5, 0.5, 0.4, 0.4, 2.0, 2.0, 2.0]))
    plant = arm.mujoco_model()
    joints.on_mujoco(plant)
    spec = arm.mujoco_spec()
    for joint, armature in zip(spec.joints, joints.armature, strict=True):
        joint.armature = armature
    declared = spec.compile()
    np.testing.assert_allclose(plant.dof_invweight0, declared.dof_invweight0, rtol=1e-9)
    data = mujoco.MjData(plant)
    data.qpos[:] = [0.0, -0.5, 0.0, 0.8, 0.0, 1.0, 0.0]
    data.qvel[6] = 1.5
    data.qfrc_applied[6] = 2.0
    mujoco.mj_forward(plant, data)
    assert data.qfrc_constraint[6] == pytest.approx(-2.0, abs=1e-3)


def test_armature_is_copied_not_set_on_the_given_model() -> None:
    arm = load_arm("panda")
    JointDynamics(FR3_ARMATURE, np.zeros(7), np.zeros(7)).on_pinocchio(arm.model)
    np.testing.assert_array_equal(arm.model.armature, np.zeros(7))


def test_coulomb_friction_is_a_smoothed_sign_and_dissipates(rng: np.random.Generator) -> None:
    """f = F_d ẋ + T⁻ᵀ F_c tanh(T⁻¹ẋ/ε) in the planar arm's absolute link angles: its
    formula, ẋᵀf ≥ 0, and the same f in the state, in forward dynamics and in zero."""
    path = models_dir() / "planar_2link.xml"
    coords = LinearCoordinates.absolute_link_angles(2)
    fc, fd = np.array([0.8, 0.3]), np.array([0.1, 0.05])
    model = RobotModel.from_mjcf(path, coordinates=coords, viscous_friction=fd,
                                 coulomb_friction=fc, friction_smoothing=0.02)
    assert model.has_friction
    t = coords.matrix
    t_inv = np.linalg.inv(t)
    for _ in range(20):
        x, dx = rng.uniform(-2, 2, 2), rng.normal(scale=0.05, size=2)
        dq = t_inv @ dx
        expected = t_inv.T @ (fd * dq + fc * np.tanh(dq / 0.02))
        f = model.dissipation(dx)
        np.testing.assert_allclose(f, expected, atol=1e-14)
        assert dx @ f >= 0.0
        np.testing.assert_allclose(model.state(x, dx).dissipation, expected, atol=1e-14)
    np.testing.assert_array_equal(model.dissipation(np.zeros(2)), np.zeros(2))
    # far above ε the friction is the level itself
    np.testing.assert_allclose(model.dissipation(t @ np.array([1.0, -1.0])) - t_inv.T @ (
        fd * [1.0, -1.0]), t_inv.T @ (fc * [1.0, -1.0]), rtol=1e-12)


@pytest.mark.parametrize(("kwargs", "word"), [
    ({"coulomb_friction": [0.1, -0.2]}, "coulomb_friction"),
    ({"coulomb_friction": [0.1, 0.2, 0.3]}, "coulomb_friction"),
    ({"coulomb_friction": [0.1, np.nan]}, "coulomb_friction"),
    ({"friction_smoothing": 0.0}, "friction_smoothing"),
])
def test_bad_friction_is_refused_by_name(kwargs: dict, word: str) -> None:
    with pytest.raises(ModelError, match=word):
        RobotModel.from_mjcf(models_dir() / "planar_2link.xml", **kwargs)


def test_bad_joint_dynamics_are_refused_by_name() -> None:
    with pytest.raises(ModelError, match="armature"):
        JointDynamics(np.array([0.1, -1.0]), np.zeros(2), np.zeros(2))
    with pytest.raises(ModelError, match="coulomb"):
        JointDynamics(np.array([0.1, 0.1]), np.zeros(2), np.zeros(3))


def _declaring_mjcf(folder: Path) -> Path:
    """The planar arm with armature, damping and frictionloss on its joints."""
    text = (models_dir() / "planar_2link.xml").read_text()
    text = text.replace('damping="0" armature="0" frictionloss="0"',
                        'damping="0.2" armature="0.1" frictionloss="0.3"')
    text = text.replace('<joint name="joint2"/>',
                        '<joint name="joint2" armature="0.05" frictionloss="0.7"/>')
    path = folder / "declaring.xml"
    path.write_text(text)
    return path


def test_an_mjcf_is_read_as_it_declares(tmp_path: Path) -> None:
    path = _declaring_mjcf(tmp_path)
    found = JointDynamics.declared(pin.buildModelFromMJCF(str(path)))
    np.testing.assert_array_equal(found.armature, [0.1, 0.05])
    np.testing.assert_array_equal(found.viscous, [0.2, 0.2])
    np.testing.assert_array_equal(found.coulomb, [0.3, 0.7])
    plant = mujoco.MjModel.from_xml_path(str(path))  # MuJoCo reads the same
    np.testing.assert_array_equal(plant.dof_armature, found.armature)
    np.testing.assert_array_equal(plant.dof_damping, found.viscous)
    np.testing.assert_array_equal(plant.dof_frictionloss, found.coulomb)


URDF = """<robot name="two">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.2 0 0"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.2 0 0"/><mass value="0.5"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="10" velocity="2"/>
    <dynamics damping="0.1" friction="0.2" armature="0.05"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="10" velocity="2"/>
    <dynamics damping="0.3" friction="0.4"/></joint>
</robot>
"""


def test_a_urdf_is_read_as_it_declares(tmp_path: Path) -> None:
    """<dynamics damping friction> (Pinocchio's parser) and <dynamics armature> (cpbc's)."""
    path = tmp_path / "two.urdf"
    path.write_text(URDF)
    arm = load_arm(path)
    found = JointDynamics.declared(arm.model, arm.urdf_text)
    np.testing.assert_array_equal(found.armature, [0.05, 0.0])
    np.testing.assert_array_equal(found.viscous, [0.1, 0.3])
    np.testing.assert_array_equal(found.coulomb, [0.2, 0.4])
