"""Moving references for a frame (TASKSPACE §2.4, §3): paths with their nominal timing, the
moving target the laws' springs read, the posture path and its admissibility, the explicit
reference governor on the path parameter, and the controller wrapper that runs them."""

from cpbc.reference.csv_path import read_csv_path
from cpbc.reference.governor import GovernorSettings, PathGovernor
from cpbc.reference.paths import Circle, Lissajous, Path, Waypoints
from cpbc.reference.plan import ReferencePlan, plan_reference
from cpbc.reference.target import MovingTarget, steer
from cpbc.reference.tracker import ReferenceTracker, tracking

__all__ = [
    "Circle",
    "GovernorSettings",
    "Lissajous",
    "MovingTarget",
    "Path",
    "PathGovernor",
    "ReferencePlan",
    "ReferenceTracker",
    "Waypoints",
    "plan_reference",
    "read_csv_path",
    "steer",
    "tracking",
]
