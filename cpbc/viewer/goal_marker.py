"""The goal frame of a goal run on the page: a small triad (x red, y green, z blue) at the
goal position with the goal's axes, or, for an axis goal, the world axis the tool axis must
point along (blue) and a dot; only the dot for a position-only goal."""

from __future__ import annotations

from typing import Any

import meshcat
import meshcat.geometry as mg
import numpy as np

_COLOURS = np.array([[0.85, 0.2, 0.2], [0.2, 0.7, 0.25], [0.2, 0.35, 0.9]])


def goal_entry(position: Any, rotation: Any = None, axis: Any = None) -> dict[str, Any]:
    """The goal as scene.json stores it (lists of numbers)."""
    return {"position": np.asarray(position, dtype=float).tolist(),
            "rotation": None if rotation is None else np.asarray(rotation, float).tolist(),
            "axis": None if axis is None else np.asarray(axis, dtype=float).tolist()}


def segments(goal: dict[str, Any], size: float) -> tuple[Any, Any]:
    """The marker's segments: their ends (3, 2k) and colours (3, 2k), k = 3, 1 or 0."""
    p = np.asarray(goal["position"], dtype=float)
    if goal.get("rotation") is not None:
        directions = np.asarray(goal["rotation"], dtype=float).T  # rows: the goal's axes
        colours = _COLOURS
    elif goal.get("axis") is not None:
        directions = np.asarray(goal["axis"], dtype=float)[None, :]
        colours = _COLOURS[2:]
    else:
        directions, colours = np.zeros((0, 3)), np.zeros((0, 3))
    ends = np.vstack([p + t * size * d for d in directions for t in (0.0, 1.0)]
                     ).T if len(directions) else np.zeros((3, 0))
    return ends.astype(np.float32), np.repeat(colours, 2, axis=0).T.astype(np.float32)


def draw_goal(vis: meshcat.Visualizer, path: str, goal: dict[str, Any], size: float) -> None:
    """Draw ``goal`` (:func:`goal_entry`) under ``path``, its arms ``size`` long [m]."""
    p = np.asarray(goal["position"], dtype=float)
    dot = vis[f"{path}/dot"]
    dot.set_object(mg.Sphere(0.12 * size), mg.MeshPhongMaterial(color=0x222222, opacity=0.8))
    dot.set_transform(np.block([[np.eye(3), p[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
    ends, rgb = segments(goal, size)
    if not ends.shape[1]:
        return
    vis[f"{path}/axes"].set_object(mg.LineSegments(
        mg.PointsGeometry(ends, color=rgb), mg.LineBasicMaterial(vertexColors=True, linewidth=3)))
