"""Colours shared by the figures and the 3-D viewer, so a controller looks the same in both."""

from __future__ import annotations

import numpy as np

#: One colour per controller of a case, in the scenario's order (red is kept for warnings).
CONTROLLER_COLOURS: tuple[str, ...] = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
)
#: Drawn where a clearance reaches zero (and for crossed bounds).
WARNING_COLOUR = "#d62728"
#: Obstacles far from every link.
OBSTACLE_COLOUR = "#8f96a3"
#: The robot posed at its target.
TARGET_COLOUR = "#3a3a3a"
#: Bounds, targets and zero lines in the figures.
BOUND_COLOUR = "#222222"


def controller_colour(index: int) -> str:
    """Colour of the ``index``-th controller of a case (cycles after eight)."""
    return CONTROLLER_COLOURS[index % len(CONTROLLER_COLOURS)]


def rgb(colour: str) -> np.ndarray:
    """``"#rrggbb"`` as floats in [0, 1], shape (3,)."""
    h = colour.lstrip("#")
    if len(h) != 6:
        raise ValueError(f"expected a colour '#rrggbb', got '{colour}'")
    return np.array([int(h[i : i + 2], 16) / 255.0 for i in (0, 2, 4)])


def clearance_colour(base: str, clearance: np.ndarray, warn_distance: float) -> np.ndarray:
    """Blend ``base`` towards the warning colour as a clearance shrinks to zero.

    The weight is ``w = clip(1 − clearance / warn_distance, 0, 1)``: the base colour at or
    beyond ``warn_distance``, the warning colour at zero clearance and in penetration.

    Args:
        base: colour far from obstacles.
        clearance: distances [m], any shape.
        warn_distance: clearance at which the blend starts [m], > 0.

    Returns:
        RGB in [0, 1], shape ``clearance.shape + (3,)``.
    """
    if not warn_distance > 0:
        raise ValueError(f"warn_distance must be > 0, got {warn_distance}")
    w = np.clip(1.0 - np.asarray(clearance, dtype=float) / warn_distance, 0.0, 1.0)[..., None]
    return (1.0 - w) * rgb(base) + w * rgb(WARNING_COLOUR)
