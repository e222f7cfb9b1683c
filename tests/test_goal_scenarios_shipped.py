"""The shipped goal scenarios, cheaply: panda_goal_pose's preflight finds a posture inside S
that reaches the goal (gripper down) and half a second of TS-CPBC keeps every margin;
planar_ch6_taskspace's singular start is flagged and its posture is the thesis's target."""

from __future__ import annotations

import math

import numpy as np
import yaml

from cpbc.resources import scenarios_dir
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import run_one


def test_panda_goal_pose_preflight_and_a_short_run(tmp_path) -> None:
    d = yaml.safe_load((scenarios_dir() / "panda_goal_pose.yaml").read_text())
    d["simulation"]["duration"] = 0.5
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(d))
    setup = build(*load_scenario(path))
    assert setup.goal is not None
    found = setup.goal.preflight
    assert found.verdict == "reachable", found.describe()
    assert found.error.position < 1e-4 and found.error.angle < 1e-3
    assert np.all(setup.monitor.configuration_margins(setup.goal.posture) > 0)
    entry = next(c for c in setup.controllers if c.name == "TS-CPBC")
    s = run_one(setup, setup.cases[0], entry, "mujoco").summary
    assert s.status == "not_settled"  # half a second: on its way, never "converged"
    assert not s.crossed_constraints and s.max_contacts == 0
    assert s.task_error_final is not None and s.task_error_max is not None
    assert s.task_error_final["position"] < s.task_error_max["position"]


def test_planar_ch6_taskspace_flags_its_singular_start() -> None:
    setup = build(*load_scenario(scenarios_dir() / "planar_ch6_taskspace.yaml"))
    assert setup.goal is not None
    assert setup.goal.preflight.singular_start
    assert np.allclose(setup.goal.posture, [math.pi, 2 * math.pi / 3], atol=1e-4)
    assert [c.controller.shaping.alpha for c in setup.controllers] == [0.2, 0.05]  # type: ignore[attr-defined]


def test_a_singular_start_s_branch_is_the_rule_s_not_the_roundoff_s() -> None:
    """From the outstretched pose the descent's first step along the elbow is roundoff alone:
    starts a few ulps to either side of it, which any host's products could make, all reach
    the same elbow (cpbc.taskspace.ik._off_singular), and a start already bent the other
    way keeps its own branch."""
    from cpbc.constraints.constraint_set import ConstraintSet
    from cpbc.taskspace.ik import preflight

    setup = build(*load_scenario(scenarios_dir() / "planar_ch6_taskspace.yaml"))
    assert setup.goal is not None
    config = ConstraintSet(setup.model.n, setup.monitor.configuration)
    for tiny in ([0.0, 0.0], [1e-13, 0.0], [0.0, 1e-13], [-1e-13, 0.0], [0.0, -1e-13]):
        found = preflight(setup.model, config, setup.goal.goal, np.array(tiny))
        assert found.singular_start and found.verdict == "reachable"
        assert np.allclose(found.posture, [math.pi, 2 * math.pi / 3], atol=1e-4), tiny
    bent = preflight(setup.model, config, setup.goal.goal, np.array([0.3, 0.6]))
    assert not bent.singular_start
    assert np.allclose(bent.posture, [2 * math.pi / 3, math.pi], atol=1e-4)
