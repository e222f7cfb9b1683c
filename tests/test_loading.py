"""URDF arms in both engines: same joints, same dynamics, same kinematics; clear errors."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from cpbc.errors import ModelError
from cpbc.model.arms import ARMS, arm_urdf, available_arms
from cpbc.model.loading import LoadedArm, load_arm, load_urdf, narrow
from cpbc.model.urdf_text import resolve_mesh_uri


@cache
def _arm(name: str) -> tuple[LoadedArm, mujoco.MjModel]:
    arm = load_arm(name)
    return arm, arm.mujoco_model()


def _random_states(arm: LoadedArm, rng: np.random.Generator, count: int = 4):
    lo = np.where(np.isfinite(arm.position_lower), arm.position_lower, -np.pi)
    hi = np.where(np.isfinite(arm.position_upper), arm.position_upper, np.pi)
    for _ in range(count):
        yield rng.uniform(lo, hi), rng.normal(size=arm.n)


def _agreement(arm: LoadedArm, mj: mujoco.MjModel, rng: np.random.Generator) -> None:
    data = mujoco.MjData(mj)
    pdata = arm.model.createData()
    for q, v in _random_states(arm, rng):
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_forward(mj, data)
        m_mj = np.zeros((mj.nv, mj.nv))
        mujoco.mj_fullM(mj, data, m_mj)
        m_pin = pin.crba(arm.model, pdata, q)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        np.testing.assert_allclose(m_pin, m_mj, atol=1e-10)
        bias = pin.rnea(arm.model, pdata, q, v, np.zeros(arm.n))
        np.testing.assert_allclose(bias, data.qfrc_bias, atol=1e-9)
        pin.framesForwardKinematics(arm.model, pdata, q)
        compared = 0
        for b in range(1, mj.nbody):
            name = mj.body(b).name
            if arm.model.existFrame(name, pin.FrameType.BODY):
                placement = pdata.oMf[arm.model.getFrameId(name, pin.FrameType.BODY)]
                np.testing.assert_allclose(placement.translation, data.xpos[b], atol=1e-10)
                np.testing.assert_allclose(placement.rotation,
                                           data.xmat[b].reshape(3, 3), atol=1e-10)
                compared += 1
        assert compared >= arm.n - 1


@pytest.mark.parametrize("name", available_arms())
def test_pinocchio_and_mujoco_agree(name: str, rng: np.random.Generator) -> None:
    arm, mj = _arm(name)
    names = tuple(mj.joint(i).name for i in range(mj.njnt))
    assert names == arm.joint_names
    assert mj.nu == arm.n  # one motor per driven joint
    np.testing.assert_allclose(mj.opt.gravity, [0, 0, -9.81])
    assert np.all(mj.dof_damping == 0) and np.all(mj.dof_frictionloss == 0)
    _agreement(arm, mj, rng)


def test_at_least_panda_ur5_and_another_arm() -> None:
    assert {"panda", "ur5"} <= set(available_arms())
    assert len(available_arms()) >= 3


def test_locked_joints_at_a_value_agree(rng: np.random.Generator) -> None:
    arm = load_arm("panda", {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.01})
    assert arm.n == 7 and "panda_finger_joint1" not in arm.joint_names
    _agreement(arm, arm.mujoco_model(), rng)
    # a revolute joint locked away from zero: the UR5's wrist 3
    ur = load_arm("ur5", {"wrist_3_joint": 0.7, "elbow_joint": -1.1})
    assert ur.n == 4
    _agreement(ur, ur.mujoco_model(), rng)


def test_limits_come_from_the_urdf() -> None:
    arm, mj = _arm("panda")
    np.testing.assert_allclose(arm.effort_limit, [87, 87, 87, 87, 12, 12, 12])
    np.testing.assert_allclose(arm.velocity_limit, [2.175] * 4 + [2.61] * 3)
    assert arm.position_lower[3] == pytest.approx(-3.0718)
    assert arm.position_upper[5] == pytest.approx(3.7525)
    np.testing.assert_allclose(mj.jnt_range[:, 0], arm.position_lower)  # hard stops in MuJoCo


def test_robot_geoms_do_not_touch_each_other_or_the_world() -> None:
    _, mj = _arm("panda")
    data = mujoco.MjData(mj)
    for q in (np.zeros(7), np.array([0, -0.3, 0, -2.2, 0, 2.0, 0.8])):
        data.qpos[:] = q
        mujoco.mj_forward(mj, data)
        assert data.ncon == 0


def test_unknown_robot_lists_the_available_ones() -> None:
    with pytest.raises(ModelError, match=r"available: .*panda.*ur5"):
        load_arm("nao")


def test_missing_urdf(tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="URDF file not found"):
        load_urdf(tmp_path / "nope.urdf")


_ONE_LINK = """<robot name="one">
  <link name="base"/>
  <link name="arm">
    <inertial><mass value="1"/><origin xyz="0 0 0.1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><mesh filename="{mesh}"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>
</robot>
"""


def test_missing_mesh_is_named(tmp_path: Path) -> None:
    urdf = tmp_path / "one.urdf"
    urdf.write_text(_ONE_LINK.format(mesh="package://nowhere/meshes/arm.stl"))
    with pytest.raises(ModelError, match=r"package://nowhere/meshes/arm\.stl"):
        load_urdf(urdf)


def test_a_package_in_a_folder_of_another_name_is_mapped_by_name(tmp_path: Path) -> None:
    """rtb-data's iiwa: package://kuka_lbr_iiwa_support/ lives in a folder called
    kuka_lbr_iiwa. Unmapped, the error says how to map it; mapped, the arm loads."""
    mesh = arm_urdf("panda").parents[1] / "meshes" / "collision" / "link1.stl"
    folder = tmp_path / "kuka_lbr_iiwa"
    (folder / "meshes").mkdir(parents=True)
    (folder / "meshes" / "arm.stl").write_bytes(mesh.read_bytes())
    urdf = tmp_path / "urdf" / "one.urdf"
    urdf.parent.mkdir()
    urdf.write_text(_ONE_LINK.format(mesh="package://kuka_lbr_iiwa_support/meshes/arm.stl"))
    with pytest.raises(ModelError, match=r"kuka_lbr_iiwa_support=FOLDER in robot\.package_dirs"):
        load_urdf(urdf)
    arm = load_urdf(urdf, package_dirs=[f"kuka_lbr_iiwa_support={folder}"])
    assert arm.joint_names == ("j1",)
    assert str(folder / "meshes" / "arm.stl") in arm.urdf_text


def test_relative_and_package_meshes_resolve(tmp_path: Path) -> None:
    share = arm_urdf("panda").parents[4]  # .../share
    mesh = share / "example-robot-data/robots/panda_description/meshes/collision/link1.stl"
    found = resolve_mesh_uri(
        "package://example-robot-data/robots/panda_description/meshes/collision/link1.stl",
        tmp_path / "x.urdf", [(None, share)],
    )
    assert found == mesh.resolve()
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "arm.stl").write_bytes(mesh.read_bytes())
    urdf = tmp_path / "one.urdf"
    urdf.write_text(_ONE_LINK.format(mesh="meshes/arm.stl"))
    arm = load_urdf(urdf)
    assert arm.joint_names == ("j1",)
    assert arm.mujoco_model().nu == 1


def test_locked_joint_errors() -> None:
    with pytest.raises(ModelError, match=r"not in panda\.urdf; its joints"):
        load_arm("panda", {"wrist": 0.0})
    with pytest.raises(ModelError, match="outside its range"):
        load_arm("panda", {"panda_finger_joint1": 0.5})


def test_registry_entries_exist() -> None:
    for name in ARMS:
        assert arm_urdf(name).is_file()


def test_named_arms_mark_their_tool_centre_point() -> None:
    arm, mj = _arm("panda")
    site = mj.site("end_point")
    assert mj.body(int(site.bodyid[0])).name == "panda_hand_tcp" == arm.tip
    _, ur = _arm("ur5")
    assert ur.body(int(ur.site("end_point").bodyid[0])).name == "tool0"


# -- continuous joints and Collada meshes -------------------------------------------------
_CONTINUOUS = """<robot name="two">
  <link name="base"/>
  <link name="l1">
    <inertial><mass value="1"/><origin xyz="0.2 0 0"/>
      <inertia ixx="0.01" iyy="0.02" izz="0.03" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="l2">
    <inertial><mass value="0.5"/><origin xyz="0.1 0 0"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="j1" type='continuous'><parent link="base"/><child link="l1"/>
    <axis xyz="0 1 0"/><limit effort="7" velocity="3" lower="-1" upper="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="5" velocity="2"/></joint>
</robot>
"""


def test_continuous_joints_are_unbounded_revolute_in_both_engines(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    urdf = tmp_path / "two.urdf"
    urdf.write_text(_CONTINUOUS)
    arm = load_urdf(urdf)
    assert arm.continuous_joints == ("j1",)
    assert arm.model.nq == arm.model.nv == 2  # the angle, not (cos, sin)
    assert arm.position_lower[0] == -np.inf and arm.position_upper[0] == np.inf
    assert (arm.position_lower[1], arm.position_upper[1]) == (-2, 2)  # revolute untouched
    assert arm.effort_limit[0] == 7 and arm.velocity_limit[0] == 3
    mj = arm.mujoco_model()
    assert list(mj.jnt_limited) == [0, 1]
    _agreement(arm, mj, rng)
    # far past the ±1 the URDF wrote (which a continuous joint ignores): the same pose
    data = mujoco.MjData(mj)
    for q1 in (5.0, -40.0):
        data.qpos[:] = [q1, 0.3]
        mujoco.mj_forward(mj, data)
        pdata = arm.model.createData()
        pin.framesForwardKinematics(arm.model, pdata, np.array([q1, 0.3]))
        fid = arm.model.getFrameId("l2", pin.FrameType.BODY)
        np.testing.assert_allclose(pdata.oMf[fid].translation, data.xpos[mj.body("l2").id],
                                   atol=1e-10)


def test_a_continuous_joint_can_be_locked(tmp_path: Path, rng: np.random.Generator) -> None:
    urdf = tmp_path / "two.urdf"
    urdf.write_text(_CONTINUOUS)
    arm = load_urdf(urdf, {"j1": 4.0})  # no range to check against
    assert arm.joint_names == ("j2",)
    _agreement(arm, arm.mujoco_model(), rng)


def test_kinova_loads_with_continuous_joints_and_collada_meshes() -> None:
    arm, mj = _arm("kinova")
    assert set(arm.continuous_joints) == {"j2s6s200_joint_1", "j2s6s200_joint_4",
                                          "j2s6s200_joint_6"}
    assert ".dae" not in arm.urdf_text.lower()  # both engines read the converted meshes
    assert mj.nmesh > 0 and mj.nq == mj.nv == 6
    limited = dict(zip(arm.joint_names, mj.jnt_limited, strict=True))
    assert not limited["j2s6s200_joint_1"] and limited["j2s6s200_joint_2"]


def test_collada_conversion_keeps_the_triangles(tmp_path: Path, monkeypatch) -> None:
    import coal

    from cpbc.model.meshes import mujoco_mesh

    monkeypatch.setenv("CPBC_CACHE_DIR", str(tmp_path / "cache"))
    source = arm_urdf("kinova").parents[1] / "meshes" / "forearm.dae"
    converted = mujoco_mesh(source)
    assert converted.suffix == ".stl" and converted.parent == tmp_path / "cache" / "meshes"
    assert mujoco_mesh(source) == converted  # cached: the same file, not converted again

    def read(p: Path) -> np.ndarray:
        bvh = coal.MeshLoader().load(str(p), np.ones(3))
        return np.asarray(bvh.vertices())

    a, b = read(source), read(converted)
    np.testing.assert_allclose(a.min(0), b.min(0), atol=1e-6)
    np.testing.assert_allclose(a.max(0), b.max(0), atol=1e-6)
    spec = mujoco.MjSpec()  # and MuJoCo decodes it
    spec.add_mesh(name="m", file=str(converted))
    spec.worldbody.add_body().add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m")
    assert spec.compile().nmeshvert > 0


def test_an_unreadable_mesh_is_a_model_error(tmp_path: Path) -> None:
    (tmp_path / "arm.dae").write_text("<COLLADA>not really</COLLADA>")
    urdf = tmp_path / "one.urdf"
    urdf.write_text(_ONE_LINK.format(mesh="arm.dae"))
    with pytest.raises(ModelError, match=r"arm\.dae"):
        load_urdf(urdf)


# -- links welded to the base or to each other; package:// from the URDF ------------------
@pytest.mark.parametrize("urdf", [
    "tiago_description/robots/tiago.urdf",  # antennas welded to the base
    "pr2_description/urdf/pr2.urdf",  # a sensor mount
    "b1_description/urdf/b1-z1.urdf",  # the quadruped's base
    "anymal_b_simple_description/robots/anymal-kinova.urdf",
])
def test_links_welded_to_the_base_keep_the_dynamics(urdf: str, rng: np.random.Generator) -> None:
    arm = load_urdf(arm_urdf("panda").parents[2] / urdf)
    _agreement(arm, arm.mujoco_model(), rng)


_VIRTUAL = """<robot name="virtual">
  <link name="base"/>
  <link name="between"/>
  <link name="arm">
    <inertial><mass value="1"/><origin xyz="0 0 0.3"/>
      <inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="ab" type="revolute"><parent link="base"/><child link="between"/>
    <axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>
  <joint name="bc" type="revolute"><parent link="between"/><child link="arm"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>
</robot>
"""


def test_a_massless_link_between_joints_is_regularised_in_both_engines(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    from cpbc.model.inertias import MIN_MASS, mujoco_accepts

    urdf = tmp_path / "virtual.urdf"
    urdf.write_text(_VIRTUAL)
    arm = load_urdf(urdf)
    assert arm.regularised == ("ab",)
    inertia = arm.model.inertias[arm.model.getJointId("ab")]
    assert mujoco_accepts(inertia) and inertia.mass == MIN_MASS
    _agreement(arm, arm.mujoco_model(), rng)


def test_branches_are_numbered_alike_in_both_engines(tmp_path: Path) -> None:
    text = _CONTINUOUS.replace('name="j1"', 'name="z1"').replace(
        "<parent link=\"l1\"/>", "<parent link=\"base\"/>")
    urdf = tmp_path / "branches.urdf"
    urdf.write_text(text)  # two joints on the base, written "z1" before "j2"
    arm = load_urdf(urdf)
    assert arm.joint_names == ("j2", "z1")
    assert tuple(arm.mujoco_model().joint(i).name for i in range(2)) == arm.joint_names


def test_package_uris_resolve_from_the_urdf_first(tmp_path: Path) -> None:
    mesh = arm_urdf("panda").parents[1] / "meshes" / "collision" / "link1.stl"
    for where in ("mine", "elsewhere"):
        folder = tmp_path / where / "my_arm" / "meshes"
        folder.mkdir(parents=True)
        (folder / "arm.stl").write_bytes(mesh.read_bytes())
    (tmp_path / "mine" / "my_arm" / "urdf").mkdir()
    urdf = tmp_path / "mine" / "my_arm" / "urdf" / "one.urdf"
    urdf.write_text(_ONE_LINK.format(mesh="package://my_arm/meshes/arm.stl"))
    arm = load_urdf(urdf, package_dirs=[tmp_path / "elsewhere"])
    assert str(tmp_path / "mine" / "my_arm" / "meshes" / "arm.stl") in arm.urdf_text
    assert "elsewhere" not in arm.urdf_text


def test_package_dirs_that_do_not_exist_are_an_error(tmp_path: Path) -> None:
    urdf = tmp_path / "one.urdf"
    urdf.write_text(_ONE_LINK.format(mesh="package://nowhere/meshes/arm.stl"))
    with pytest.raises(ModelError, match=r"package_dirs .*nope.* do not exist") as info:
        load_urdf(urdf, package_dirs=[tmp_path / "nope"])
    assert info.value.parameter == "package_dirs"


@pytest.mark.parametrize(("name", "robot_joints"), [
    ("tiago_arm", 48), ("tiago_pro_left", 33), ("pr2_left", 30), ("pr2_right", 30),
    ("b1_z1", 19), ("anymal_kinova", 18)])
def test_the_arm_of_a_larger_robot_drives_only_its_arm(name: str, robot_joints: int,
                                                       rng: np.random.Generator) -> None:
    """A named arm of a mobile manipulator or a legged robot drives the arm's joints alone:
    every other joint of the robot (wheels, legs, torso, head, hand) is locked, at 0 moved
    into its range, and the arm's dynamics agree in both engines."""
    from cpbc.model.arms import ARMS

    arm = load_arm(name)
    entry = ARMS[name]
    assert arm.joint_names == entry.driven
    assert len(arm.locked_joints) == robot_joints - len(entry.driven)
    full = pin.buildModelFromXML(arm.urdf_text)
    for joint, value in arm.locked_joints.items():
        idx = full.joints[full.getJointId(joint)].idx_q
        lo, hi = full.lowerPositionLimit[idx], full.upperPositionLimit[idx]
        assert value == (float(np.clip(0.0, lo, hi)) if lo <= hi else 0.0)
    mj = arm.mujoco_model()
    assert mj.nv == len(entry.driven)
    _agreement(arm, mj, rng)


def test_narrowed_ranges_reach_both_engines_and_stay_inside_the_urdfs() -> None:
    arm = load_arm("ur5")
    narrow(arm, {"elbow_joint": (-1.0, 2.0)})
    i = arm.joint_names.index("elbow_joint")
    assert (arm.position_lower[i], arm.position_upper[i]) == (-1.0, 2.0)
    assert tuple(arm.model.lowerPositionLimit[[i]]) == (-1.0,)
    assert tuple(arm.mujoco_model().jnt_range[i]) == (-1.0, 2.0)
    with pytest.raises(ModelError, match="not inside the URDF's") as found:
        narrow(arm, {"elbow_joint": (-10.0, 2.0)})
    assert found.value.parameter == "ranges"
    with pytest.raises(ModelError, match="not a driven joint"):
        narrow(arm, {"nope": (0.0, 1.0)})
