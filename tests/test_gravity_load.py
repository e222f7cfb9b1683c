"""Gravity beyond the motors: a target no motor can hold is refused naming the
joint, its torque and its limit; a path that leaves a motor no room to brake over gravity
warns, and a run on it that fails names it as its cause, in the status line, the summary
and on the page; ``python -m cpbc.robot`` prints the load at its suggested target."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from cpbc.model.gravity_load import joint_loads
from cpbc.model.robot_model import RobotModel
from cpbc.results.metrics import RunSummary
from cpbc.results.summary_table import status_text
from cpbc.robot import main as robot_main
from cpbc.run import main
from cpbc.scenario.build import build
from cpbc.scenario.load import load_any


def _write(folder: Path, scenario: dict) -> Path:
    path = folder / f"{scenario['name']}.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    return path


def test_a_target_no_motor_can_hold_is_refused(tmp_path: Path, monkeypatch, capsys) -> None:
    """The UR5's shoulder holds 59 N·m at this target; at 0.3 of its 150 N·m it cannot."""
    monkeypatch.chdir(tmp_path)
    path = _write(tmp_path, {
        "name": "ur5_weak", "robot": {"model": "ur5"},
        "simulation": {"duration": 0.5, "torque_limit_scale": 0.3},
        "target": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        "cases": [{"name": "near", "position": [0.0, -0.1, 0.0, 0.0, 0.0, 0.0]}],
        "controllers": [{"type": "pd_gravity", "kp": 50, "kd": 10}],
    })
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: target: the motors cannot hold the arm there"), err
    assert "'shoulder_lift_joint'" in err and "59.17 N·m" in err and "limit 45 N·m" in err
    assert "Traceback" not in err
    assert [p.name for p in tmp_path.iterdir()] == ["ur5_weak.yaml"]  # nothing written


# Baxter's right arm swung up from low: its shoulder (right_s1, 50 N·m) holds the start (39 N·m)
# and the target (46 N·m) but not the arm stretched out half-way (53 N·m).
BAXTER_SAG = {
    "name": "baxter_sag", "robot": {"model": "baxter_right"},
    "simulation": {"duration": 1.0},
    "target": [0.0, -0.2, 0.0, 1.284, 0.0, 0.2616, 0.0],
    "cases": [{"name": "low", "position": [0.0, -0.9, 0.0, 0.0, 0.0, 0.2616, 0.0]}],
    "constraints": [
        {"type": "joint_position_limit", "name": "joint_ranges", "lower": "from_model",
         "upper": "from_model"},
        {"type": "joint_rate_limit", "name": "joint_rates", "bounds": "from_model",
         "scale": 0.5},
    ],
    "controllers": [{"type": "cpbc", "name": "CPBC", "omega_n": 5.0, "zeta": 1.0,
                     "shaping": {"type": "power", "alpha": 0.2}}],
}


def test_a_path_beyond_the_motors_warns_and_the_failed_run_names_it(tmp_path: Path,
                                                                    capsys) -> None:
    out = tmp_path / "out"
    assert main([str(_write(tmp_path, BAXTER_SAG)), "--out", str(out), "--quiet",
                 "--no-plots"]) == 0
    captured = capsys.readouterr()
    (warning,) = [line for line in captured.err.splitlines() if line.startswith("warning:")]
    assert ("case 'low': gravity on 'right_s1' is 53.03 N·m 55% of the way to the target, "
            "more than its torque limit 50 N·m") in warning
    (run,) = json.loads((out / "summary.json").read_text())
    assert run["status"] == "constraint_violated"
    assert run["cause"].startswith("gravity on 'right_s1' is 53.03 N·m")
    status = status_text(RunSummary(**{k: v for k, v in run.items()
                                   if k in RunSummary.__dataclass_fields__}))
    assert status.startswith("constraint_violated @") and status.endswith(
        f"; cause: {run['cause']}")  # the table's status line
    assert "cause: gravity on" in captured.out
    page = (out / "view.html").read_text()
    data = json.loads(re.search(r"window\.CPBC_DATA = (\{.*?\});\n</script>", page,
                                re.S).group(1))  # type: ignore[union-attr]
    (shown,) = data["cases"][0]["controllers"]
    # the page's status line: the status and its cause, then the controller's slowest call
    assert shown["status"].startswith(f"constraint_violated; cause: {run['cause']}; ")
    assert "slowest controller call" in shown["status"]


@pytest.mark.parametrize("name", ["ur5_bpbc", "panda_cpbc_sphere"])
def test_the_shipped_arm_scenarios_raise_no_gravity_warning(name: str) -> None:
    scenario, file = load_any(name)
    assert build(scenario, file).gravity_on_path == {}  # type: ignore[arg-type]


def test_robot_prints_the_gravity_load_at_the_suggested_target(capsys) -> None:
    assert robot_main(["baxter_right"]) == 0
    text = capsys.readouterr().out
    assert "# gravity at the suggested target [N·m]" in text
    (line,) = [x for x in text.splitlines() if x.startswith("#   right_s1 ") and " of " in x]
    # mid-range, right_s1 would need 47.71 + 2.91 of its 50 N·m (101 %): the suggested target
    # is lowered until every motor carries the arm with room to brake
    assert "# (the target is lowered from mid-range" in text
    gravity, allowance, limit = float(line.split()[2]), float(line.split()[4]), 50.0
    assert line.split()[5:7] == ["of", "50"] and gravity + allowance <= 0.8 * limit
    assert yaml.safe_load(text)["robot"] == {"model": "baxter_right"}  # still a scenario


def test_the_suggested_target_is_mid_range_where_the_motors_carry_the_arm() -> None:
    """The Panda carries itself at mid-range: its skeleton's target stays there; Baxter's
    right_s1 does not (101 % with the brake's allowance): its target is lowered, and every
    motor then has the allowance to spare."""
    from cpbc.robot import describe, suggested_pose
    from cpbc.scenario.skeleton import home

    panda = describe("panda")
    np.testing.assert_array_equal(suggested_pose(panda)[0], home(panda.limits)[0])
    baxter = describe("baxter_right")
    middle, lowered = home(baxter.limits)[0], suggested_pose(baxter)[0]
    model = RobotModel(pin.Model(baxter.pin_model))
    assert max(x.share for x in joint_loads(model, middle, baxter.limits.effort)) > 1.0
    assert max(x.share for x in joint_loads(model, lowered, baxter.limits.effort)) <= 0.8
    assert np.all((lowered >= baxter.limits.lower) & (lowered <= baxter.limits.upper))
