"""Links with a mass and an all-zero inertia tensor (cpbc.model.solid_inertias), as in
rtb-data's Lynxmotion AL5D: given the inertia of a solid box of their geometry, said so by
``cpbc.robot``, whose printed skeleton then runs as printed with nothing crossed (raised only
to MuJoCo's least, its CPBC crossed joint 4's range at thousands of rad/s)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from cpbc import robot, run
from cpbc.model.loading import load_urdf
from cpbc.model.solid_inertias import solid_box

# the AL5D's joints, masses and (as boxes) the bounding boxes of its link meshes
LINKS = [  # name, mass, box sides, box centre
    ("link1", 0.187, "0.108 0.094 0.046", "0.007 0 0.008"),
    ("link2", 0.044, "0.174 0.032 0.077", "0.071 0 0.0025"),
    ("link3", 0.207, "0.255 0.038 0.056", "0.073 -0.004 -0.001"),
    ("link4", 0.081, "0.098 0.050 0.069", "0.037 0.008 -0.002"),
]
JOINTS = [  # name, parent, child, origin xyz, origin rpy
    ("j1", "base", "link1", "0 0 0.06858", "0 3.141592653 0"),
    ("j2", "link1", "link2", "0.002 0 0", "0 1.570796325 -1.570796325"),
    ("j3", "link2", "link3", "0.14679 0 0", "0 3.141592653 1.570796325"),
    ("j4", "link3", "link4", "0.17751 0 0", "3.141592653 0 1.570796325"),
]
ZERO = 'ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"'


def _urdf(geometry: bool = True) -> str:
    links = ['<link name="base"><inertial><mass value="0.092"/>'
             f'<inertia {ZERO}/></inertial></link>']
    for name, mass, sides, centre in LINKS:
        visual = (f'<visual><origin xyz="{centre}"/><geometry><box size="{sides}"/></geometry>'
                  "</visual>" if geometry else "")
        links.append(f'<link name="{name}"><inertial><mass value="{mass}"/>'
                     f"<inertia {ZERO}/></inertial>{visual}</link>")
    joints = [f'<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
              f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/>'
              '<limit effort="1000" lower="-1.570796325" upper="1.570796325" velocity="0"/>'
              "</joint>" for n, p, c, xyz, rpy in JOINTS]
    return '<robot name="al5d">' + "".join(links + joints) + "</robot>"


def test_a_point_mass_link_gets_its_geometrys_solid_box(tmp_path: Path) -> None:
    path = tmp_path / "al5d.urdf"
    path.write_text(_urdf())
    arm = load_urdf(path)
    assert arm.estimated == ("j1", "j2", "j3", "j4")
    assert arm.regularised == ()  # MuJoCo takes the estimates as they are
    j4 = arm.model.inertias[arm.model.getJointId("j4")]
    assert np.allclose(j4.inertia, solid_box(0.081, np.array([0.098, 0.050, 0.069])))
    assert j4.mass == pytest.approx(0.081)
    mj = arm.mujoco_model()  # the same inertia in the plant
    body = mj.jnt_bodyid[mj.joint("j4").id]
    assert np.allclose(np.sort(mj.body_inertia[body]), np.sort(np.diag(j4.inertia)))
    assert isinstance(j4, pin.Inertia)


def test_a_point_mass_link_without_geometry_is_left_to_the_least_mujoco_takes(
        tmp_path: Path) -> None:
    path = tmp_path / "al5d.urdf"
    path.write_text(_urdf(geometry=False))
    arm = load_urdf(path)
    assert arm.estimated == ()
    assert arm.regularised == ("j1", "j2", "j3", "j4")


def test_the_printed_skeleton_runs_as_printed_with_nothing_crossed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "al5d.urdf"
    path.write_text(_urdf())
    assert robot.main([str(path), "--duration", "3"]) == 0
    printed = capsys.readouterr().out
    assert "inertia estimated from the mass and the geometry, as a solid box" in printed
    scenario = tmp_path / "skeleton.yaml"
    scenario.write_text(printed)
    out = tmp_path / "out"
    assert run.main([str(scenario), "--quiet", "--no-plots", "--workers", "1",
                     "--out", str(out)]) == 0, capsys.readouterr().err
    runs = json.loads((out / "summary.json").read_text())
    assert {r["controller"] for r in runs} == {"PD_gravity", "CPBC"}
    for r in runs:
        assert r["status"] == "converged", (r["controller"], r["status"])
        assert r["crossed_constraints"] == [], r["controller"]
