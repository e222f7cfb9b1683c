"""The arm's reach: how far from its first joint a frame's point can ever be, whatever the
constraints (TASKSPACE §3.3's ``unreachable`` made certain).

Along a serial chain, joint k+1's origin is fixed in joint k's moving frame, at a distance
‖ᵏp_{k+1}‖ (its placement in its parent) from joint k's origin; a revolute joint turns about
an axis through its own origin, so that distance holds at every configuration, and a
prismatic joint adds at most its travel max(|lower|, |upper|). By the triangle inequality the
point stays within

    R = Σ_{k≥2} ‖ᵏ⁻¹p_k‖ + Σ_prismatic travel_k + ‖ᴷp_point‖

of the first joint's origin (fixed: a revolute first joint turns about it; a prismatic one's
travel is in the sum). A goal farther than R plus its tolerance cannot be reached by any
posture, so the preflight calls it ``unreachable`` before a constraint it would run into
can be blamed for it, and its run is ``unreachable`` however long or short.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.model.robot_model import RobotModel
from cpbc.taskspace.goal import FrameGoal


@dataclass(frozen=True)
class Reach:
    """The ball the goal's point can reach: ``centre`` (the first joint's origin, world m)
    and ``radius`` R [m] (infinite when a prismatic joint's travel is unbounded)."""

    centre: Array
    radius: float

    def beyond(self, point: Array) -> float:
        """How far ``point`` lies outside the ball [m] (≤ 0: inside)."""
        return float(np.linalg.norm(np.asarray(point, dtype=float) - self.centre)) - self.radius


def reach(model: RobotModel, goal: FrameGoal) -> Reach:
    """The reach of ``goal``'s point of its frame (module docstring)."""
    pm = model.model
    frame = pm.frames[goal.frame]
    chain = [j for j in pm.supports[frame.parentJoint] if j > 0]
    offset = np.zeros(3) if goal.offset is None else np.asarray(goal.offset, dtype=float)
    tip = frame.placement.translation + frame.placement.rotation @ offset
    if not chain:  # a frame fixed to the world: it reaches only where it is
        return Reach(np.asarray(frame.placement.translation, dtype=float) + offset, 0.0)
    data = pm.createData()
    pin.forwardKinematics(pm, data, pin.neutral(pm))
    first = chain[0]
    centre = data.oMi[pm.parents[first]].act(pm.jointPlacements[first].translation)
    radius = float(np.linalg.norm(tip))
    radius += sum(float(np.linalg.norm(pm.jointPlacements[j].translation)) for j in chain[1:])
    prismatic = model.length_joints  # joints[1:]
    for j in chain:
        if prismatic[j - 1]:
            i = pm.joints[j].idx_q
            radius += float(max(abs(pm.lowerPositionLimit[i]), abs(pm.upperPositionLimit[i])))
    return Reach(np.array(centre, dtype=float), radius)
