"""A goal run's status and task metrics (cpbc.results.task_metrics) on the thesis's arm, in
short runs: reached at the IK posture, unreachable at the preflight's closest pose, and
stalled(singular) when the error is radial at the outstretched pose with the posture spring
at the start (no obstacle: its barrier would push the arm off the singular equilibrium);
never ``converged``."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from cpbc.resources import scenarios_dir
from cpbc.results.metrics import RunSummary
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import run_one

SCENARIO = scenarios_dir() / "planar_ch6_taskspace.yaml"


@pytest.fixture
def run(tmp_path: Path) -> Callable[[list[float], list[float], str], RunSummary]:
    def _run(goal: list[float], start: list[float] | None, posture: str,
             obstacle: bool = True) -> RunSummary:
        """A 1.5 s run from ``start`` (None: the preflight's posture)."""
        d = yaml.safe_load(SCENARIO.read_text())
        d["simulation"]["duration"] = 1.5
        d["goal"].update(position=goal, posture=posture)
        d["cases"] = [{"name": "start", "position": start or [0.3, 0.3]}]
        d["controllers"] = d["controllers"][:1]
        if not obstacle:
            d["constraints"] = d["constraints"][1:]
        path = tmp_path / "goal.yaml"
        path.write_text(yaml.safe_dump(d))
        setup = build(*load_scenario(path))
        if start is None:
            assert setup.goal is not None
            d["cases"][0]["position"] = setup.goal.posture.tolist()
            path.write_text(yaml.safe_dump(d))
            setup = build(*load_scenario(path))
        return run_one(setup, setup.cases[0], setup.controllers[0], "mujoco").summary

    return _run


def test_at_the_ik_posture_the_goal_is_reached_at_once(run) -> None:
    s = run([-1.5, 0.8660254, 0.0], [math.pi, 2 * math.pi / 3], "ik")
    assert s.status == "reached"
    assert s.reach_time == 0.0
    assert s.task_error_final is not None and s.task_error_final["position"] < 1e-6
    assert s.task_error_max is not None and s.task_error_max["position"] < 1e-3


def test_resting_at_the_closest_pose_of_an_unreachable_goal_reads_unreachable(run) -> None:
    # without the obstacle, whose barrier moves the law's rest off the preflight's (its
    # barrier weight is not the law's ρ = r·L)
    s = run([3.0, 1.0, 0.0], None, "ik", obstacle=False)
    assert s.status == "unreachable"
    assert s.task_error_final is not None
    assert s.task_error_final["position"] == pytest.approx(math.hypot(3, 1) - 2, abs=1e-3)


def test_a_radial_error_at_the_outstretched_pose_is_a_singular_stall(run) -> None:
    s = run([0.5, 0.0, 0.0], [0.0, 0.0], "start", obstacle=False)
    assert s.status == "stalled" and s.stall_kind == "singular"
    assert s.task_error_final is not None
    assert s.task_error_final["position"] == pytest.approx(1.5, abs=1e-3)


def _panda_goal(tmp_path: Path, duration: float, position: list[float] | None = None):
    """scenarios/panda_goal_pose.yaml's task-space CPBC alone, for ``duration`` s, to its own
    goal or to ``position``."""
    d = yaml.safe_load((scenarios_dir() / "panda_goal_pose.yaml").read_text())
    d["simulation"]["duration"] = duration
    d["controllers"] = [c for c in d["controllers"] if c["type"] == "cpbc"]
    if position is not None:
        d["goal"]["position"] = position
    path = tmp_path / "panda_goal.yaml"
    path.write_text(yaml.safe_dump(d))
    return build(*load_scenario(path))


def test_a_goal_held_in_its_band_while_the_joints_still_drift_is_reached(tmp_path) -> None:
    """The Panda's hand holds its goal to microns from 2.2 s on while the posture spring
    still moves the joints along their self-motion: reached, not not_settled."""
    import numpy as np

    setup = _panda_goal(tmp_path, 4.0)
    result = run_one(setup, setup.cases[0], setup.controllers[0], "mujoco")
    s = result.summary
    assert s.reach_time is not None and s.reach_time < 4.0 - 1.0  # held the last second
    assert s.task_error_final is not None and s.task_error_final["position"] < 1e-4
    # the joints still move: "at rest" alone would not call it reached
    assert np.max(np.abs(result.trajectory.velocity[-1])) > setup.criteria.velocity_tolerance
    assert s.status == "reached"


def test_a_goal_beyond_the_arms_reach_is_unreachable_before_and_after_a_short_run(
        tmp_path) -> None:
    """10 m from a Panda with a ball in its workspace: the preflight's descent runs into the
    ball's clearance, but no posture reaches the goal, so no constraint is blamed; a run
    shorter than the stall window is not judged as a stall."""
    setup = _panda_goal(tmp_path, 0.3, [10.0, 0.0, 0.5])
    assert setup.goal is not None
    found = setup.goal.preflight
    assert found.verdict == "unreachable" and found.blocked_by is None, found.describe()
    assert found.beyond_reach == pytest.approx(9.0, abs=0.1)
    assert "beyond the arm's reach" in found.describe()
    s = run_one(setup, setup.cases[0], setup.controllers[0], "mujoco").summary
    assert s.status == "unreachable" and s.stall_kind is None
