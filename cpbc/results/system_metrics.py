"""Results of a Part I system run: what the results show of the system (:class:`SystemView`)
and the summary (peaks and bounds of every constrained quantity, convergence on the
components the system names). Written with an arm's summaries (cpbc.results.io: summary.json
and summary.csv), logs (cpbc.results.hdf5_log) and figures (cpbc.results.system_plots)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.simulation.trajectory import SystemTrajectory
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


@dataclass(frozen=True)
class SystemSummary:
    """One run. ``peaks``/``bounds``: max |value| and the bound on |value| of every
    constrained quantity; ``peak_abs``/``final_state``: every state component and the input."""

    case: str
    controller: str
    backend: str
    status: str  # converged, not_settled, constraint_violated, diverged
    end_time: float
    violated: str | None
    crossed_at: float | None  # first sample at which a constrained quantity was at its bound
    settle_time: float | None
    peaks: dict[str, float]
    bounds: dict[str, float]
    peak_abs: dict[str, float]
    final_state: dict[str, float]
    design_bounds: dict[str, float]
    wall_time: float
    limits_reached: tuple[str, ...] = ()  # the plant's limits its run reached (not violations)
    # MuJoCo's control steps per wall-clock second; None for the reference, whose samples
    # are not its steps
    steps_per_second: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {k: _finite_or_none(v) for k, v in self.__dict__.items()}

    def csv_row(self) -> dict[str, object]:
        """The columns of summary.csv (cpbc.results.io.CSV_COLUMNS) that apply to a Part I
        run; the peaks and bounds, which have no arm column, are in summary.json."""
        crossed = self.violated.split(", ") if self.violated else []
        margins = "; ".join(f"{n} {self.bounds[n] - p:.6g}" for n, p in self.peaks.items())
        samples_per_second = "" if self.steps_per_second is None else f"{self.steps_per_second:.6g}"
        return {"controller": self.controller, "case": self.case, "backend": self.backend,
                "status": self.status, "end_time": self.end_time,
                "settle_time": self.settle_time, "worst_margins": margins,
                "crossed_constraints": " ".join(crossed), "wall_time": self.wall_time,
                "steps_per_second": samples_per_second,
                "violated_constraint": self.violated or ""}


def _finite_or_none(v: object) -> object:
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite_or_none(x) for k, x in v.items()}
    return v


def _values(traj: SystemTrajectory, q: ConstrainedQuantity) -> Array:
    return traj.input if q.source == "input" else traj.state[:, q.index]


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


def _judged(traj: SystemTrajectory, view: SystemView) -> Array:
    """|x_i| of the judged components per sample, angles wrapped."""
    cols = []
    for i in view.judged:
        v = traj.state[:, i]
        cols.append(np.abs(np.remainder(v + np.pi, 2 * np.pi) - np.pi) if i in view.angles
                    else np.abs(v))
    return np.max(np.column_stack(cols), axis=1)


def summarise_system(
    case: str, controller: str, traj: SystemTrajectory, constrained: Sequence[ConstrainedQuantity],
    view: SystemView, state_names: Sequence[str], input_name: str, tolerance: float,
) -> SystemSummary:
    peaks, bounds, crossed, reached, first = {}, {}, [], [], math.inf
    for q in constrained:
        v = _values(traj, q)
        out = np.nonzero((v <= q.lower) | (v >= q.upper))[0]
        peaks[q.name], bounds[q.name] = _peak(v[np.isfinite(v)], q)
        if out.size and q.limit:
            reached.append(q.name)
        elif out.size:
            crossed.append(q.name)
            first = min(first, float(traj.time[out[0]]))
    err = _judged(traj, view)
    outside = np.nonzero(~(err < tolerance))[0]
    settled = traj.outcome == "completed" and (outside.size == 0 or outside[-1] < len(err) - 1)
    settle = (float(traj.time[outside[-1] + 1]) if outside.size else 0.0) if settled else None
    if traj.outcome != "completed":
        status = traj.outcome
    elif crossed:
        status = "constraint_violated"
    else:
        status = "converged" if settled else "not_settled"
    names = [*state_names, input_name.split(" ")[0]]
    columns = [*traj.state.T, traj.input]
    peak_abs = {n: float(np.nanmax(np.abs(c))) if np.isfinite(c).any() else math.nan
                for n, c in zip(names, columns, strict=True)}
    final = {n: float(c[-1]) for n, c in zip(names, columns, strict=True)}
    violated = traj.violated or (", ".join(crossed) if crossed else None)
    rate = (len(traj.time) / traj.wall_time if traj.backend == "mujoco" and traj.wall_time > 0
            else None)
    return SystemSummary(case, controller, traj.backend, status, traj.end_time, violated,
                         first if crossed else None, settle, peaks, bounds, peak_abs, final,
                         dict(view.design_bounds), traj.wall_time, tuple(reached), rate)
