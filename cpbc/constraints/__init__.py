"""Constraint layer: configuration constraints φ(x) > 0 and velocity constraints ψ(x, ẋ) > 0."""

from cpbc.constraints.clearance import Clearance
from cpbc.constraints.constraint_set import BarrierTerms, ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.cover_cache import cached_cover
from cpbc.constraints.covering import LinkPrimitive, cover_links
from cpbc.constraints.geometry import (
    BoxObstacle,
    CapsuleObstacle,
    Obstacle,
    PlaneObstacle,
    SphereObstacle,
)
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.linear_limit import LinearLimit, joint_position_limit
from cpbc.constraints.point_outside_sphere import PointOutsideSphere
from cpbc.constraints.rate_limit import RateLimit, joint_rate_limit

__all__ = [
    "BarrierTerms",
    "BoxObstacle",
    "CapsuleObstacle",
    "Clearance",
    "ConfigurationConstraint",
    "ConstraintSet",
    "KineticEnergyLimit",
    "LinearLimit",
    "LinkPrimitive",
    "Obstacle",
    "PlaneObstacle",
    "PointOutsideSphere",
    "RateLimit",
    "SphereObstacle",
    "VelocityConstraint",
    "cached_cover",
    "cover_links",
    "joint_position_limit",
    "joint_rate_limit",
]
