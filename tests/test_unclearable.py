"""Cover primitives no configuration clears (cpbc.constraints.clearance.unclearable): the
UR5 on a floor at z = 0 with the default clearance (every covered link). Its shoulder's
spheres sit in or on the floor whatever the joints do; kept, they refused every start."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from cpbc import run
from cpbc.constraints.clearance import Clearance
from cpbc.constraints.clearance.unclearable import SLACK, _distance
from cpbc.constraints.cover_cache import cached_cover
from cpbc.constraints.geometry import PlaneObstacle
from cpbc.errors import CpbcError
from cpbc.model.loading import load_arm
from cpbc.resources import scenarios_dir
from cpbc.scenario import build, load_scenario


def _ur5_on_the_floor(links: list[str] | None = None) -> dict:
    data = yaml.safe_load((scenarios_dir() / "ur5_bpbc.yaml").read_text())
    data["obstacles"] = [{"type": "plane", "name": "floor", "point": [0, 0, 0]}]
    clearance = next(c for c in data["constraints"] if c["type"] == "clearance")
    clearance.pop("links")
    if links is not None:
        clearance["links"] = links
    data["simulation"]["duration"] = 0.05
    return data


def _build(tmp_path: Path, data: dict):
    path = tmp_path / "ur5.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return build(*load_scenario(path))


def test_the_default_clearance_leaves_out_the_spheres_the_floor_always_holds(
        tmp_path: Path) -> None:
    setup = _build(tmp_path, _ur5_on_the_floor())
    (clearance,) = [c for c in setup.monitor.configuration if isinstance(c, Clearance)]
    left = {name for name, _ in clearance.left_out}
    assert {"shoulder_link#1", "upper_arm_link#6"} <= left
    assert all(obstacle == "floor" for _, obstacle in clearance.left_out)
    kept = {p.name for p in clearance.primitives}
    assert not left & kept
    assert {"upper_arm_link#0", "forearm_link#0"} <= kept  # the arm itself stays covered
    # what the note claims, checked on other configurations than the ones drawn
    arm = load_arm("ur5")
    cover = {p.name: p for p in cached_cover(arm.model, arm.collision_model)}
    floor = PlaneObstacle("floor", np.zeros(3), np.array([0.0, 0.0, 1.0]))
    data = arm.model.createData()
    rng = np.random.default_rng(7)
    for _ in range(200):
        pin.framesForwardKinematics(arm.model, data, rng.uniform(
            arm.model.lowerPositionLimit, arm.model.upperPositionLimit))
        for name in left:
            p = cover[name]
            centre = data.oMf[arm.model.getFrameId(p.frame)].act(p.start)
            assert _distance(centre[None], floor)[0] - p.radius <= clearance.margin + SLACK


def test_links_the_user_lists_are_kept_as_given(tmp_path: Path) -> None:
    data = _ur5_on_the_floor(["shoulder_link", "upper_arm_link", "forearm_link"])
    with pytest.raises(CpbcError, match=r"clearance\[(shoulder|upper_arm)_link\|floor\]"):
        _build(tmp_path, data)


def test_the_run_says_what_it_left_out(tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    data = copy.deepcopy(_ur5_on_the_floor())
    data["controllers"] = data["controllers"][1:]
    path = tmp_path / "ur5.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert run.main([str(path), "--out", str(tmp_path / "out"), "--quiet", "--no-plots",
                     "--workers", "1"]) == 0
    err = capsys.readouterr().err
    said = " ".join(err.split())
    assert "clearance 'clearance' leaves out" in said and "shoulder_link#1 in floor" in said
