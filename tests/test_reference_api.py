"""The docs' moving-reference example (docs/task-space.md) runs as printed, and a streamed
target moves the arm: the tracker wraps a goal law for cpbc.simulation.loop.run_mujoco."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from cpbc.reference import tracking
from cpbc.scenario import build, load_scenario
from cpbc.simulation.loop import run_mujoco

PAGE = Path(__file__).resolve().parents[1] / "docs" / "task-space.md"
API_PAGE = PAGE.with_name("api.md")


def test_the_docs_example_runs(capsys: object) -> None:
    text = PAGE.read_text()
    code = re.search(r"<!-- reference-example -->\n```python\n(.*?)```", text, re.S)
    assert code is not None
    assert len(code.group(1).strip().splitlines()) <= 16
    scope: dict[str, object] = {}
    exec(compile(code.group(1), "docs example", "exec"), scope)
    traj, law = scope["traj"], scope["law"]
    assert traj.outcome == "completed"  # type: ignore[attr-defined]
    assert law.governor.s > 0.9 and not law.governor.blocks  # type: ignore[attr-defined]


def test_a_streamed_target_is_followed() -> None:
    setup = build(*load_scenario("panda_goal_pose"))
    entry, goal = setup.controllers[1], setup.goal
    assert goal is not None
    law = tracking(entry.controller, 1e-3, run=setup.controller(entry))
    law.set_target(goal.goal.position + np.array([0.0, 0.0, 0.05]))
    model = setup.model
    traj = run_mujoco(setup.make_plant(), law, model.coordinates, goal.posture, np.zeros(7),
                      replace(setup.loop_settings, duration=1.5))
    p = model.point_position(goal.goal.frame, traj.position[-1], goal.goal.offset)
    assert traj.outcome == "completed"
    assert np.linalg.norm(p - law.requested) < 0.01


def test_the_api_pages_policy_loop_runs() -> None:
    """The user's own MuJoCo loop of docs/api.md, a policy at 50 Hz and the law at 1 kHz,
    brings the hand to the streamed point."""
    code = re.search(r"<!-- policy-loop -->\n```python\n(.*?)```", API_PAGE.read_text(), re.S)
    assert code is not None
    assert len(code.group(1).strip().splitlines()) <= 16
    scope: dict[str, object] = {}
    exec(compile(code.group(1), "api example", "exec"), scope)
    law, setup, data = scope["law"], scope["setup"], scope["data"]
    hand = setup.model.point_position(law.frame, data.qpos, law.offset)  # type: ignore[attr-defined]
    assert np.linalg.norm(hand - law.requested) < 0.01  # type: ignore[attr-defined]
    assert law.blocked_by is None  # type: ignore[attr-defined]
