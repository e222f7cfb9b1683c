"""The page's goal frame (cpbc.viewer.goal_marker): stored in scene.json, drawn as a triad
(three coloured segments from the goal position along its axes) or one axis."""

from __future__ import annotations

import numpy as np

from cpbc.results.saved_run import SceneInfo
from cpbc.viewer.goal_marker import draw_goal, goal_entry, segments
from cpbc.viewer.recorder import CommandRecorder


def test_goal_round_trips_through_scene_json() -> None:
    goal = goal_entry([0.4, 0.3, 0.35], np.eye(3))
    info = SceneInfo(np.eye(2), "end_point", "s", (), goal)
    assert SceneInfo.from_json(info.to_json()).goal == goal
    assert SceneInfo.from_json(SceneInfo(np.eye(2), "end_point").to_json()).goal is None


def test_a_triad_is_three_segments_and_an_axis_goal_one() -> None:
    for entry, count in ((goal_entry([0.4, 0.3, 0.35], np.eye(3)), 3),
                            (goal_entry([0.4, 0.3, 0.35], axis=[0, 0, -1]), 1),
                            (goal_entry([0.4, 0.3, 0.35]), 0)):
        recorder = CommandRecorder()
        draw_goal(recorder.visualizer(), "/cpbc/goal", entry, 0.1)
        assert len(recorder.commands) == (3 if count else 2)  # dot, its place (+ segments)
        ends, colours = segments(entry, 0.1)
        assert ends.shape == colours.shape == (3, 2 * count)
        p = np.array(entry["position"])
        for k in range(count):  # from the goal, 0.1 m along an axis
            assert np.allclose(ends[:, 2 * k], p)
            assert np.isclose(np.linalg.norm(ends[:, 2 * k + 1] - p), 0.1, atol=1e-6)
