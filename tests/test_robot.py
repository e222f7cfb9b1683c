"""``python -m cpbc.robot`` (cpbc.robot) on files a new user brings: a ``package://`` name
that differs from its folder (``--package-dir NAME=PATH``), whose skeleton runs as printed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cpbc import robot, run
from cpbc.model.arms import arm_urdf

ONE_LINK = """<robot name="one">
  <link name="base"/>
  <link name="arm">
    <inertial><mass value="1"/><origin xyz="0.1 0 0"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><mesh filename="package://arm_support/meshes/arm.stl"/></geometry>
    </collision>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>
</robot>
"""


@pytest.fixture
def arm(tmp_path: Path) -> tuple[Path, Path]:
    """A URDF whose meshes are package://arm_support/…, in a folder called arm_files (as
    rtb-data's iiwa: kuka_lbr_iiwa_support in kuka_lbr_iiwa), and that folder."""
    folder = tmp_path / "arm_files"
    (folder / "meshes").mkdir(parents=True)
    mesh = arm_urdf("panda").parents[1] / "meshes" / "collision" / "link1.stl"
    (folder / "meshes" / "arm.stl").write_bytes(mesh.read_bytes())
    (folder / "urdf").mkdir()
    urdf = folder / "urdf" / "arm.urdf"
    urdf.write_text(ONE_LINK)
    return urdf, folder


def test_an_unmapped_package_is_refused_saying_how_to_map_it(
        arm: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    urdf, _ = arm
    assert robot.main([str(urdf)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1
    assert "--package-dir arm_support=FOLDER" in err


def test_a_mapped_package_loads_and_its_skeleton_runs_as_printed(
        arm: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf, folder = arm
    assert robot.main([str(urdf), "--package-dir", f"arm_support={folder}",
                       "--duration", "0.5"]) == 0
    printed = capsys.readouterr().out
    assert f"package_dirs: [arm_support={folder.resolve()}]" in printed
    scenario = tmp_path / "skeleton.yaml"
    scenario.write_text(printed)
    out = tmp_path / "out"
    assert run.main([str(scenario), "--quiet", "--no-plots", "--workers", "1",
                     "--out", str(out)]) == 0, capsys.readouterr().err
    for s in json.loads((out / "summary.json").read_text()):
        assert s["status"] not in ("diverged", "constraint_violated"), s
        assert s["crossed_constraints"] == [], s


def test_a_package_dir_that_is_not_a_folder_is_refused_naming_the_option(
        arm: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf, _ = arm
    assert robot.main([str(urdf), "--package-dir", f"arm_support={tmp_path / 'nope'}"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "--package-dir arm_support=" in err and "is not a folder" in err


# dm-control's Jaco in miniature: the last link weighs next to nothing, its joint's armature
# (the rotor) is what it has to move
ROTOR_DRIVEN = """<mujoco><worldbody><body name="l1">
  <joint name="j1" type="hinge" axis="0 1 0" range="-1 1" armature="0.5"/>
  <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04" mass="1"/>
  <body name="l2" pos="0.3 0 0"><joint name="j2" type="hinge" axis="1 0 0" armature="0.2"/>
    <geom type="sphere" size="0.01" mass="1e-9"/></body></body></worldbody></mujoco>"""


def test_a_link_moved_by_its_rotor_gets_the_files_armature_and_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "rotor.xml"
    path.write_text(ROTOR_DRIVEN)
    assert robot.main([str(path), "--duration", "0.5"]) == 0
    printed = capsys.readouterr().out
    assert "armature: from_model" in printed and "links of j2 have less than" in printed
    scenario = tmp_path / "skeleton.yaml"
    scenario.write_text(printed)
    out = tmp_path / "out"
    assert run.main([str(scenario), "--quiet", "--no-plots", "--workers", "1",
                     "--out", str(out)]) == 0, capsys.readouterr().err
    for s in json.loads((out / "summary.json").read_text()):
        assert s["status"] not in ("diverged", "constraint_violated"), s
        assert s["crossed_constraints"] == [], s


# robosuite-models' ARX5 in miniature: the base's collision geom reaches into the first
# link's at every configuration (the base is welded to the world, so MuJoCo does not filter
# the pair as parent and child)
BASE_IN_LINK = """<mujoco><worldbody><body name="base">
  <geom type="cylinder" size="0.05 0.05" pos="0 0 0.05" mass="1"/>
  <body name="l1" pos="0 0 0.1"><joint name="j1" type="hinge" axis="0 0 1" range="-3 3"/>
    <geom type="cylinder" size="0.05 0.05" pos="0 0 -0.002" mass="1"/>
    <body name="l2" pos="0 0 0.05"><joint name="j2" type="hinge" axis="0 1 0" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/></body></body>
  </body></worldbody></mujoco>"""


def test_an_mjcf_arms_own_contacts_do_not_hold_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "base_in_link.xml"
    path.write_text(BASE_IN_LINK)
    assert robot.main([str(path), "--duration", "2"]) == 0
    scenario = tmp_path / "skeleton.yaml"
    scenario.write_text(capsys.readouterr().out)
    out = tmp_path / "out"
    assert run.main([str(scenario), "--quiet", "--no-plots", "--workers", "1",
                     "--out", str(out)]) == 0, capsys.readouterr().err
    for s in json.loads((out / "summary.json").read_text()):
        assert s["status"] == "converged" and s["crossed_constraints"] == [], s


def test_a_skeleton_with_slow_gains_lasts_long_enough_to_settle(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The xArm7's held loop tolerates ω_n = 2 only, and its coupled wrist rings: at the
    former 5 s both laws ended not_settled (0.007 rad off); 20/ω_n = 10 s it settles."""
    assert robot.main(["xarm7"]) == 0
    printed = capsys.readouterr().out
    assert "omega_n: 2.0" in printed and "duration: 10.0" in printed
    scenario = tmp_path / "skeleton.yaml"
    scenario.write_text(printed)
    out = tmp_path / "out"
    assert run.main([str(scenario), "--quiet", "--no-plots", "--workers", "1",
                     "--out", str(out)]) == 0, capsys.readouterr().err
    for s in json.loads((out / "summary.json").read_text()):
        assert s["status"] == "converged" and s["crossed_constraints"] == [], s


# robosuite-models' ALOHA in miniature: the wrist's motor (±0.5 N·m) cannot hold its link
# level (1.5 N·m of gravity), and its range leaves no posture where it hangs
WEAK_WRIST = """<mujoco><worldbody><body name="base">
  <body name="l1"><joint name="j1" type="hinge" axis="0 0 1" range="-3 3"/>
    <geom type="cylinder" size="0.05 0.05" pos="0 0 0.05" mass="1"/>
    <body name="l2" pos="0 0 0.1"><joint name="j2" type="hinge" axis="0 1 0" range="-0.1 0.1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/></body></body>
  </body></worldbody>
  <actuator><motor joint="j1" ctrlrange="-50 50"/><motor joint="j2" ctrlrange="-0.5 0.5"/>
  </actuator></mujoco>"""


def test_an_mjcf_arm_its_motors_cannot_hold_is_refused_not_given_a_lock_it_cannot_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A URDF's skeleton locks such a joint; an MJCF's joints cannot be locked, and the
    skeleton that locked them was refused by cpbc.run ("locking joints needs a URDF")."""
    path = tmp_path / "weak_wrist.xml"
    path.write_text(WEAK_WRIST)
    assert robot.main([str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1, err
    assert "the motors of j2 (0.5 N·m) cannot hold the arm up" in err
    assert "MJCF arm's joints cannot be locked" in err and "effort limits in the file" in err
