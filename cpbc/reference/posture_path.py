"""The posture path x_n(s) of a reference and its steady-state admissibility (TASKSPACE §3.3):
an IK continuation along the path (each sample seeded by the one before, with the preflight's
barrier-respecting descent of cpbc.taskspace.ik), and a scan that marks the samples whose
posture is not in S_δ = {every configuration margin ≥ δ} or that the IK cannot reach, naming
the constraint. Boundaries between an admissible and an inadmissible sample are refined by
bisection to ``resolution`` (the control period), so the first inadmissible path time is
known to within one period."""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import pairwise

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.model.robot_model import RobotModel
from cpbc.reference.paths import Path
from cpbc.taskspace.goal import FrameGoal
from cpbc.taskspace.ik import preflight

ITERATIONS = 60


@dataclass(frozen=True)
class Sample:
    """The posture at one path time: x_n, and the constraint that makes it inadmissible
    (None when it is in S_δ and reaches the path point)."""

    s: float
    posture: Array
    blocked_by: str | None


@dataclass(frozen=True)
class PosturePath:
    """x_n on a grid of path times, and the inadmissible stretches [start, end) with the
    constraint that blocks each (``end`` = inf when it lasts to the path's end)."""

    s: Array
    postures: Array
    stretches: tuple[tuple[float, float, str], ...]

    def posture(self, s: float) -> Array:
        """x_n(s), linear between grid samples."""
        return np.array([np.interp(s, self.s, self.postures[:, j])
                         for j in range(self.postures.shape[1])])


class _Scan:
    def __init__(self, model: RobotModel, constraints: ConstraintSet, goal: FrameGoal,
                 path: Path, delta: float) -> None:
        self.model, self.goal, self.path, self.delta = model, goal, path, delta
        self.config = ConstraintSet(model.n, constraints.configuration)
        self.names = self.config.names

    def at(self, s: float, seed: Array) -> Sample:
        p = self.path.sample(np.array([s]))[0][0]
        found = preflight(self.model, self.config, replace(self.goal, position=p), seed,
                          iterations=ITERATIONS)
        x = found.posture
        if found.verdict != "reachable":
            return Sample(s, x, found.blocked_by or "unreachable")
        if self.names:
            m = self.config.margins(x, np.zeros(self.model.n))
            k = int(np.argmin(m))
            if m[k] < self.delta:
                return Sample(s, x, self.names[k])
        return Sample(s, x, None)

    def boundary(self, good: Sample, bad: Sample, resolution: float) -> Sample:
        """The first inadmissible sample after ``good``, to within ``resolution``."""
        while bad.s - good.s > resolution:
            mid = self.at(0.5 * (good.s + bad.s), good.posture)
            good, bad = (good, mid) if mid.blocked_by else (mid, bad)
        return bad


def posture_path(model: RobotModel, constraints: ConstraintSet, goal: FrameGoal, path: Path,
                 start: Array, delta: float, step: float, resolution: float) -> PosturePath:
    """The continuation from ``start`` on a grid of ``step`` [s] and its stretches."""
    scan = _Scan(model, constraints, goal, path, delta)
    grid = np.append(np.arange(0.0, path.duration, step), path.duration)
    samples = [scan.at(0.0, start)]
    for s in grid[1:]:
        samples.append(scan.at(float(s), samples[-1].posture))
    stretches: list[tuple[float, float, str]] = []
    begin: Sample | None = samples[0] if samples[0].blocked_by else None
    for prev, cur in pairwise(samples):
        if cur.blocked_by and not prev.blocked_by:
            begin = scan.boundary(prev, cur, resolution)
        elif prev.blocked_by and not cur.blocked_by and begin is not None:
            stretches.append((begin.s, cur.s, str(begin.blocked_by)))  # cur: admissible
            begin = None
    if begin is not None:
        stretches.append((begin.s, float("inf"), str(begin.blocked_by)))
    postures = np.array([smp.posture for smp in samples])
    return PosturePath(grid, postures, tuple(stretches))
