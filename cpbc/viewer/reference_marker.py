"""A reference run's path on the page: the requested path (grey), its inadmissible stretches
as the governor's plans found them (red), and each run's applied reference (the
controller's colour, under its case)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import meshcat
import meshcat.geometry as mg
import numpy as np

from cpbc.arrays import Array

PATH_SAMPLES = 600  # the requested path's samples on the page
_GREY, _RED = 0x888888, 0xD62728


def reference_entry(path: Any, stretches: Sequence[tuple[float, float, str]]
                    ) -> dict[str, Any]:
    """The reference as scene.json stores it: ``path`` (k, 3) and ``blocked`` (a list of
    polylines, one per inadmissible stretch), lists of numbers."""
    s = np.linspace(0.0, path.duration, PATH_SAMPLES)
    points = path.sample(s)[0]
    blocked = []
    for begin, end, _ in stretches:
        inside = (s >= begin) & (s <= min(end, path.duration))
        if np.count_nonzero(inside) >= 2:
            blocked.append(points[inside].tolist())
    return {"path": points.tolist(), "blocked": blocked}


def _line(vis: meshcat.Visualizer, path: str, points: Array, colour: int,
          width: float) -> None:
    pts = np.asarray(points, dtype=np.float32).T
    if pts.shape[1] < 2:
        return
    vis[path].set_object(mg.Line(mg.PointsGeometry(pts),
                                 mg.LineBasicMaterial(color=colour, linewidth=width)))


def draw_reference(vis: meshcat.Visualizer, path: str, entry: dict[str, Any]) -> None:
    """Draw :func:`reference_entry` under ``path``."""
    _line(vis, f"{path}/path", np.asarray(entry["path"]), _GREY, 2.0)
    for k, stretch in enumerate(entry.get("blocked") or []):
        _line(vis, f"{path}/blocked_{k}", np.asarray(stretch), _RED, 5.0)


def draw_applied(vis: meshcat.Visualizer, path: str, applied: Array, colour: str) -> None:
    """A run's applied reference (N, 3) as a line in ``colour`` (#rrggbb)."""
    _line(vis, path, np.asarray(applied)[:: max(1, len(applied) // 2000)],
          int(colour[1:], 16), 3.0)
