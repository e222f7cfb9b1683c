"""A reference planned offline for one law (TASKSPACE §3.2): the path's point and tangent on
the control grid, the posture path x_n(s) with its inadmissible stretches, and the
normalisation s(ΦΨ(x_n(s), 0)) of the law's V, so that the governor's per-step work is a
table look-up."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.base import Controller
from cpbc.errors import ConstraintViolation
from cpbc.reference.governor import GovernorSettings
from cpbc.reference.paths import Path
from cpbc.reference.posture_path import PosturePath, posture_path
from cpbc.taskspace.goal import FrameGoal

SCAN_STEP = 0.02  # the posture path's grid [s of path time]


@dataclass(frozen=True)
class ReferencePlan:
    """Tables on the control grid s_k = k h (k = 0 … m − 1).

    Attributes:
        goal: the frame goal (frame, offset, orientation) the path moves.
        path, period: the path and h.
        points, tangents: p(s_k), dp/ds(s_k), (m, 3); speeds: |dp/ds(s_k)|, as a list.
        postures: x_n(s_k), (m, n); posture_tangents: dx_n/ds(s_k), (m, n).
        log_norm: ln s(ΦΨ(x_n(s_k), 0)) of the law, as a list (V̄ = V·exp(log_norm)).
        postures_path: the coarse continuation and its stretches.
        blend_times: per stretch, |p(end) − p(start)| over the nominal speed at its end.
    """

    goal: FrameGoal
    path: Path
    period: float
    points: Array
    tangents: Array
    speeds: list[float]
    postures: Array
    posture_tangents: Array
    log_norm: list[float]
    postures_path: PosturePath
    blend_times: tuple[float, ...]

    def index(self, s: float) -> int:
        return min(int(s / self.period + 0.5), len(self.speeds) - 1)


def log_norm(law: Controller, x: Array) -> float:
    """ln s(ΦΨ(x, 0)) of the law's shaping (0 for a law without barriers)."""
    shaping = getattr(law, "shaping", None)
    if shaping is None or law.constraints.empty:
        return 0.0
    state = law.constraints.state(law.model, x, np.zeros(law.model.n))
    try:
        bar = law.constraints.barrier(state)
    except ConstraintViolation:
        return math.inf
    return float(shaping.log_s(bar.log_phi + bar.log_psi))


def plan_reference(law: Controller, goal: FrameGoal, path: Path, start: Array,
                   settings: GovernorSettings, period: float) -> ReferencePlan:
    """The tables for ``law`` following ``path`` with ``goal``'s frame, orientation and
    offset, from the posture ``start``."""
    coarse = posture_path(law.model, law.constraints, goal, path, start, settings.margin,
                          SCAN_STEP, period)
    grid = np.arange(0.0, path.duration + 0.5 * period, period)
    points, tangents = path.sample(grid)
    postures = np.column_stack([np.interp(grid, coarse.s, coarse.postures[:, j])
                                for j in range(law.model.n)])
    norms = [log_norm(law, x) for x in coarse.postures]
    norm_table = np.interp(grid, coarse.s, np.minimum(norms, 700.0))
    blends = []
    for begin, end, _ in coarse.stretches:
        if math.isinf(end):
            blends.append(period)
            continue
        p = path.sample(np.array([begin, end]))
        speed = max(float(np.linalg.norm(p[1][1])), 1e-6)
        blends.append(float(np.linalg.norm(p[0][1] - p[0][0])) / speed)
    return ReferencePlan(replace(goal), path, period, points, tangents,
                         np.linalg.norm(tangents, axis=1).tolist(), postures,
                         np.gradient(postures, period, axis=0),
                         norm_table.tolist(), coarse, tuple(blends))
