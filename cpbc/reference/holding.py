"""Which constraint holds an arm off its streamed target (``blocked_by``).

At rest the laws balance the spring's pull −∂U/∂x against the barrier sum Σ ∇φ_i/φ_i
(CPBC: ∂U/∂x = ρ Σ ∇φ_i/φ_i, cpbc.controllers.cpbc). So the constraint that holds the arm
short of a target is the one whose log-barrier ln φ̃_i falls fastest along the pull: the
largest rate −∇φ̃_i·d/φ̃_i along the unit joint direction d toward the target (φ̃ = φ but
for a localised clearance, which is slack beyond its influence distance). A rate below
``STEEP`` means that no barrier is near enough to hold the arm: the target is out of reach
(the workspace's edge, a singular direction), reported as ``unreachable``.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet

STEEP = 1.0  # [1/rad]: a barrier that falls slower along the pull than e per radian is slack
UNREACHABLE = "unreachable"


def holding_constraint(constraints: ConstraintSet, x: Array, pull: Array) -> str:
    """The configuration constraint whose ln φ̃ falls fastest at ``x`` along the joint
    direction ``pull`` (any length), or ``unreachable`` when none falls at ``STEEP`` or
    faster, or the pull is zero."""
    size = float(np.linalg.norm(pull))
    if not size > 0:
        return UNREACHABLE
    d = pull / size
    best, name = STEEP, UNREACHABLE
    for c in constraints.configuration:
        phi, grad = c.evaluate(x)
        rate = -(grad @ d) * c.barrier_ratio(phi)
        k = int(np.argmax(rate))
        if rate[k] >= best:
            best, name = float(rate[k]), c.names[k]
    return name
