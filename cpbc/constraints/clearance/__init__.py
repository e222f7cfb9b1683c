"""Clearance between the whole arm and the obstacles (and between its own links).

One scalar configuration constraint per (robot primitive, obstacle) pair and per
self-collision pair, all evaluated together: the sphere pairs by compiled kernels over
tables packed at construction (cpbc.kernels.clearance), the capsule groups by numpy.

The package, one concept per module:

- ``constraint``: :class:`Clearance`, the coordinator (arguments, values, gradients,
  curvature, the localised barrier's terms);
- ``spheres``: the sphere primitives' pairs (their packed tables; distances, the law's
  factors and force by kernels; gradients, curvature);
- ``capsules``: the capsule primitives' groups (against spheres, capsules, boxes and planes,
  and self pairs);
- ``layout``: the set-up of the pairs from the link covers, and the capsules' broad phase;
- ``kinematics``: points fixed on links over Pinocchio's static regressor;
- ``tables``: the constant wrench/cross tables of the hot path;
- ``clearance_kind``: the scenario's ``type: clearance`` (its spec and factory), whose
  ``KINDS`` the package exports (cpbc.constraints.constraint_kind).
"""

from cpbc.constraints.clearance.clearance_kind import KINDS
from cpbc.constraints.clearance.constraint import Clearance

__all__ = ["KINDS", "Clearance"]
