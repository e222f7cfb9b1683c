"""Cover primitives that no configuration takes clear of an obstacle.

An automatic cover wraps each link's collision mesh; at the base of an arm those primitives
may reach through a floor plane the arm stands on (the UR5's ``shoulder_link`` sphere below
its shoulder, and the sphere at the shoulder end of its ``upper_arm_link``, whose centre
lies on the shoulder's axis: below a floor at z = 0, or within 3 mm above it, whatever the
joints do). A clearance that keeps such a primitive refuses nearly every start ("move the
state inside every constraint") although no motion could help. A primitive counts as such
when its clearance stays within ``SLACK`` of the margin (or below) at every one of
``SAMPLES`` configurations drawn across the joint ranges and at the neutral one; the default
clearance (no ``links`` given) leaves it out, and the run says so.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.constraints.covering import LinkPrimitive
from cpbc.constraints.geometry import Obstacle, point_rounded_box

#: Configurations drawn across the joint ranges (besides the neutral one).
SAMPLES = 64
#: How far above the margin a primitive must get at some configuration to be kept [m].
SLACK = 0.01
#: Points along a capsule's axis at which its distance is measured (its least is no less
#: than the capsule's: a primitive found inside at them is inside).
AXIS_POINTS = 5


def _distance(points: Array, obstacle: Obstacle) -> Array:
    """Signed distance of world points (k, 3) to the obstacle's rounded box (< 0: inside)."""
    core = obstacle.core()
    u = (points - core.centre) @ core.rotation
    k = len(points)
    return np.asarray(point_rounded_box(u, np.tile(core.half_extents, (k, 1)),
                                        np.full(k, core.rounding))[0], dtype=float)


def unclearable(model: pin.Model, primitives: Sequence[LinkPrimitive],
                obstacles: Sequence[Obstacle], margin: float, seed: int = 0
                ) -> list[tuple[str, str]]:
    """(primitive, obstacle) names of the pairs whose clearance stays ≤ ``margin`` + SLACK at
    every sampled configuration (module docstring)."""
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi)
    rng = np.random.default_rng(seed)
    configurations = [pin.neutral(model)] + [rng.uniform(lo, hi) for _ in range(SAMPLES)]
    data = model.createData()
    along = np.linspace(0.0, 1.0, AXIS_POINTS)[:, None]
    inside = np.ones((len(primitives), len(obstacles)), dtype=bool)
    for q in configurations:
        pin.framesForwardKinematics(model, data, q)
        for i, p in enumerate(primitives):
            if not inside[i].any():
                continue
            frame = data.oMf[model.getFrameId(p.frame)]
            local = p.start + along * (p.end - p.start)
            world = local @ frame.rotation.T + frame.translation
            for j, o in enumerate(obstacles):
                if inside[i, j]:
                    clearance = float(_distance(world, o).min()) - p.radius
                    inside[i, j] = clearance <= margin + SLACK
    return [(primitives[i].name, obstacles[j].name) for i, j in zip(*np.nonzero(inside),
                                                                   strict=True)]
