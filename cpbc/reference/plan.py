"""A reference planned offline for one law (TASKSPACE §3.2): the path's point and tangent on
the control grid, the posture path x_n(s) with its inadmissible stretches, and the
normalisation s(ΦΨ(x_n(s), 0)) of the law's V, so that the governor's per-step work is a
table look-up."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.controllers.controller import Controller
from cpbc.errors import ConstraintViolation
from cpbc.reference.governor import GovernorSettings
from cpbc.reference.paths import Path
from cpbc.reference.posture_path import PosturePath, posture_path
from cpbc.taskspace.goal import FrameGoal

SCAN_STEP = 0.02  # the posture path's grid [s of path time]
BLEND_SAMPLES = 21  # postures checked along a rejoin's straight blend


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
        rows, row_tangents: [p | x_n](s_k) and their tangents side by side, (m, 3 + n):
            what the tracker interpolates each step, once for both (made from the above).
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
    rows: Array = field(init=False, repr=False)
    row_tangents: Array = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "rows", np.hstack((self.points, self.postures)))
        object.__setattr__(self, "row_tangents",
                           np.hstack((self.tangents, self.posture_tangents)))

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


def blend_admissible(config: ConstraintSet, x0: Array, x1: Array, delta: float,
                     samples: int = BLEND_SAMPLES) -> bool:
    """Whether every posture of the straight blend from ``x0`` to ``x1`` keeps every
    configuration margin ≥ δ (at ``samples`` evenly spaced points, both ends included)."""
    if config.empty:
        return True
    zero = np.zeros(len(x0))
    for w in np.linspace(0.0, 1.0, samples):
        x = (1.0 - w) * x0 + w * x1
        try:
            if float(np.min(config.margins(x, zero))) < delta:
                return False
        except ConstraintViolation:
            return False
    return True


def _rejoinable(law: Controller, coarse: PosturePath, delta: float) -> PosturePath:
    """The stretches whose rejoin blend (from the posture where the governor stops to the
    one at the stretch's end) leaves a configuration margin below δ/2 made to last to the
    path's end: rejoin stops there."""
    config = ConstraintSet(law.model.n, law.constraints.configuration)
    kept = []
    for begin, end, name in coarse.stretches:
        if not math.isinf(end) and not blend_admissible(
                config, coarse.posture(begin), coarse.posture(end), 0.5 * delta):
            end, name = math.inf, f"{name} (no admissible rejoin)"
        kept.append((begin, end, name))
    return replace(coarse, stretches=tuple(kept))


def plan_reference(law: Controller, goal: FrameGoal, path: Path, start: Array,
                   settings: GovernorSettings, period: float) -> ReferencePlan:
    """The tables for ``law`` following ``path`` with ``goal``'s frame, orientation and
    offset, from the posture ``start``."""
    coarse = posture_path(law.model, law.constraints, goal, path, start, settings.margin,
                          SCAN_STEP, period)
    if settings.on_infeasible == "rejoin":
        coarse = _rejoinable(law, coarse, settings.margin)
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
