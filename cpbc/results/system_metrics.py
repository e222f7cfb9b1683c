"""Results of a Part I system run: what the results show of the system (:class:`SystemView`)
and its summary, the arm's record (cpbc.results.metrics.RunSummary) with the fields that
apply filled and the system's own quantities in its SystemOutcome (peaks and bounds of every
constrained quantity, convergence on the components the system names). Written as an arm's
summaries (cpbc.results.io: summary.json and summary.csv), logs (cpbc.results.hdf5_log) and
figures (cpbc.results.system_plots, and the margins through cpbc.results.plots)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from cpbc.arrays import Array
from cpbc.results.metrics import RunSummary, SystemOutcome
from cpbc.simulation.trajectory import SystemTrajectory

if TYPE_CHECKING:  # the systems load with a Part I scenario, not with an arm's run
    from cpbc.systems.ode_plant import ConstrainedQuantity


@dataclass(frozen=True)
class Panel:
    """One time plot: ``scale`` × (state ``index``, or the input when ``index`` is None),
    with the bound ± ``bound`` (in the quantity's own unit, before ``scale``) drawn; an
    asymmetric interval gives its ``lower`` end too."""

    label: str
    index: int | None
    scale: float = 1.0
    bound: float | None = None
    lower: float | None = None


@dataclass(frozen=True)
class SystemView:
    """What the results show of a system, in the thesis's style.

    Attributes:
        panels: the time plots.
        phase: (x index, y index, x label, y label) of the phase portrait, or None.
        judged: the state components convergence is judged on (the pendulum, not its wheel).
        angles: components wrapped to (−π, π] before judging.
        design_bounds: a-priori bounds of the thesis evaluated for the gains (name → value).
        path: (horizontal position, altitude) indices of a vehicle's path, drawn in 3-D.
    """

    panels: tuple[Panel, ...]
    phase: tuple[int, int, str, str] | None
    judged: tuple[int, ...]
    angles: tuple[int, ...]
    design_bounds: dict[str, float] = field(default_factory=dict)
    path: tuple[int, int] | None = None


def _peak(v: Array, q: ConstrainedQuantity) -> tuple[float, float]:
    """(peak, bound) as magnitudes, from the side of (lower, upper) that ``v`` came closest
    to in proportion (max |v| and min(−lower, upper) when the interval is symmetric)."""
    if not v.size:
        return math.nan, min(-q.lower, q.upper)
    if q.lower == -q.upper or not (q.lower < 0.0 < q.upper):
        return float(np.max(np.abs(v))), min(-q.lower, q.upper)
    top, bottom = float(np.max(v)), float(np.min(v))
    if top / q.upper >= bottom / q.lower:
        return abs(top), q.upper
    return abs(bottom), -q.lower


def min_margin(traj: SystemTrajectory, q: ConstrainedQuantity) -> float:
    """The smallest margin of a quantity in a run (ConstrainedQuantity.margins: the distance
    to its nearer bound, in its unit) over the finite samples; NaN when there are none."""
    m = q.margins(traj.state, traj.input)
    m = m[np.isfinite(m)]
    return float(np.min(m)) if m.size else math.nan


def _judged(traj: SystemTrajectory, view: SystemView) -> Array:
    """|x_i| of the judged components per sample, angles wrapped."""
    cols = []
    for i in view.judged:
        v = traj.state[:, i]
        cols.append(np.abs(np.remainder(v + np.pi, 2 * np.pi) - np.pi) if i in view.angles
                    else np.abs(v))
    return np.max(np.column_stack(cols), axis=1)


#: controller_type of a Part I law with and without its barrier
BARRIER_LAW, PLAIN_LAW = "barrier backstepping", "backstepping"


def _crossings(traj: SystemTrajectory, constrained: Sequence[ConstrainedQuantity]
               ) -> tuple[dict[str, float], dict[str, float], list[str], list[str], float]:
    """Peaks and bounds of every constrained quantity, the constraints crossed, the plant's
    limits reached, and the first sample at a crossed constraint's bound (inf: none)."""
    peaks, bounds, crossed, reached, first = {}, {}, [], [], math.inf
    for q in constrained:
        v = q.values(traj.state, traj.input)
        out = np.nonzero((v <= q.lower) | (v >= q.upper))[0]
        peaks[q.name], bounds[q.name] = _peak(v[np.isfinite(v)], q)
        if out.size and q.limit:
            reached.append(q.name)
        elif out.size:
            crossed.append(q.name)
            first = min(first, float(traj.time[out[0]]))
    return peaks, bounds, crossed, reached, first


def _judge(traj: SystemTrajectory, err: Array, crossed: list[str], tolerance: float
           ) -> tuple[str, float | None]:
    """Status and settle time: settled once every judged component stays below
    ``tolerance`` to the end."""
    outside = np.nonzero(~(err < tolerance))[0]
    settled = traj.outcome == "completed" and (outside.size == 0 or outside[-1] < len(err) - 1)
    settle = (float(traj.time[outside[-1] + 1]) if outside.size else 0.0) if settled else None
    if traj.outcome != "completed":
        return traj.outcome, settle
    if crossed:
        return "constraint_violated", settle
    return ("converged" if settled else "not_settled"), settle


def summarise_system(
    case: str, controller: str, traj: SystemTrajectory, constrained: Sequence[ConstrainedQuantity],
    view: SystemView, state_names: Sequence[str], input_name: str, tolerance: float,
    barrier: bool = True,
) -> RunSummary:
    """A Part I run as the arm's record; ``barrier``: whether the law enforces the system's
    constraints (its plant's limits are enforced by none)."""
    peaks, bounds, crossed, reached, first = _crossings(traj, constrained)
    err = _judged(traj, view)
    status, settle = _judge(traj, err, crossed, tolerance)
    names = [*state_names, input_name.split(" ")[0]]
    columns = [*traj.state.T, traj.input]
    peak_abs = {n: float(np.nanmax(np.abs(c))) if np.isfinite(c).any() else math.nan
                for n, c in zip(names, columns, strict=True)}
    final = {n: float(c[-1]) for n, c in zip(names, columns, strict=True)}
    violated = traj.violated or (", ".join(crossed) if crossed else None)
    rate = (len(traj.time) / traj.wall_time if traj.backend == "mujoco" and traj.wall_time > 0
            else None)
    u = peak_abs[names[-1]]
    limit = next((min(-q.lower, q.upper) for q in constrained
                  if q.source == "input" and q.limit), None)
    outcome = SystemOutcome(peaks, bounds, peak_abs, final, dict(view.design_bounds), reached,
                            first if crossed else None)
    return RunSummary(
        controller=controller, controller_type=BARRIER_LAW if barrier else PLAIN_LAW,
        case=case, backend=traj.backend, status=status, end_time=traj.end_time,
        violated_constraint=violated, final_error=float(err[-1]) if err.size else math.nan,
        settle_time=settle, peak_joint_rates=[], rate_bounds=[], peak_torques=[u],
        peak_commanded_torques=[u], peak_joint_torques=[u],
        torque_limits=None if limit is None else [limit], peak_torque_norm=u,
        torque_bound=None, min_margins={q.name: min_margin(traj, q) for q in constrained},
        margin_types={q.name: q.margin_type.key for q in constrained},
        crossed_constraints=crossed,
        enforced_constraints=[q.name for q in constrained if barrier and not q.limit],
        max_lyapunov_increase=math.nan, initial_lyapunov=math.nan, max_contacts=0,
        saturated_steps=0, wall_time=traj.wall_time,
        control_steps=len(traj.time) if traj.backend == "mujoco" else 0,
        steps_per_second=rate, margin_units={q.name: q.unit for q in constrained},
        system=outcome)
