"""Results of a Part I system run: the summary (peaks and bounds of every constrained
quantity, convergence on the components the system names) and the figures in the thesis's
style (time plots per case, the phase portrait). The logs: cpbc.results.hdf5_log.

matplotlib is imported only with the Agg canvas and no pyplot state, as in plots.py.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from cpbc.arrays import Array
from cpbc.results.palette import BOUND_COLOUR, controller_colour
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

    def as_dict(self) -> dict[str, object]:
        return {k: _finite_or_none(v) for k, v in self.__dict__.items()}


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
    return SystemSummary(case, controller, traj.backend, status, traj.end_time, violated,
                         first if crossed else None, settle, peaks, bounds, peak_abs, final,
                         dict(view.design_bounds), traj.wall_time, tuple(reached))


def write_system_summaries(folder: Path, summaries: Sequence[SystemSummary]) -> None:
    (folder / "summary.json").write_text(
        json.dumps([s.as_dict() for s in summaries], indent=2, allow_nan=False))


def _signal(traj: SystemTrajectory, p: Panel) -> Array:
    return p.scale * (traj.input if p.index is None else traj.state[:, p.index])


#: A time plot with a bound shows at most this many times the bound.
CLIP = 3.0


def plot_case(path: Path, case: str, runs: Sequence[tuple[str, SystemTrajectory]],
              view: SystemView) -> None:
    """Every law's run of one case: one panel per quantity against time (bounds dashed),
    and the phase portrait when the system has one."""
    n = len(view.panels) + (view.phase is not None)
    fig = Figure(figsize=(7.0, 2.1 * n), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    for k, (ax, p) in enumerate(zip(axes, view.panels, strict=False)):
        for i, (name, traj) in enumerate(runs):
            ax.plot(traj.time, _signal(traj, p), color=controller_colour(i), lw=1.2, label=name)
        label = p.label
        if p.bound is not None:
            edge = p.bound * abs(p.scale)
            low = -edge if p.lower is None else p.lower * p.scale
            for b in (edge, low):
                ax.axhline(b, color=BOUND_COLOUR, ls="--", lw=0.8)
            peak = max(float(np.nanmax(np.abs(_signal(t, p)), initial=0.0)) for _, t in runs)
            if peak > CLIP * edge:  # a run far past the bound would flatten the others
                ax.set_ylim(-CLIP * edge, CLIP * edge)
                label += f"\n(clipped at ±{CLIP:g}× bound; peak {peak:.4g})"
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
        if k == len(view.panels) - 1:
            ax.set_xlabel("time [s]")
    axes[0].set_title(f"case {case}")
    axes[0].legend(fontsize=8, loc="best")
    if view.phase is not None:
        ix, iy, lx, ly = view.phase
        ax = axes[-1]
        for i, (_, traj) in enumerate(runs):
            ax.plot(traj.state[:, ix], traj.state[:, iy], color=controller_colour(i), lw=1.2)
            ax.plot(traj.state[0, ix], traj.state[0, iy], "o", color=controller_colour(i))
        ax.set_xlabel(lx)
        ax.set_ylabel(ly)
        ax.set_title("phase portrait", fontsize=9)
        ax.grid(alpha=0.3)
    fig.savefig(path)


def plot_path(path: Path, case: str, runs: Sequence[tuple[str, SystemTrajectory]],
              view: SystemView) -> None:
    """The vehicle's path in 3-D (downrange, one lane per law, altitude): a longitudinal
    flight is planar, so each law's path is drawn in its own lane, with its shadow on the
    ground h = 0."""
    assert view.path is not None
    ix, ih = view.path
    fig = Figure(figsize=(7.0, 4.5), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    for i, (name, traj) in enumerate(runs):
        x, h = traj.state[:, ix], traj.state[:, ih]
        lane = np.full_like(x, float(i))
        ax.plot(x, lane, h, color=controller_colour(i), lw=1.2, label=name)
        ax.plot(x, lane, np.zeros_like(h), color=controller_colour(i), lw=0.6, alpha=0.3)
        ax.plot([x[-1]], [float(i)], [h[-1]], "o", color=controller_colour(i), ms=3)
    ax.set_yticks(range(len(runs)), [name for name, _ in runs])
    ax.set_xlabel("downrange x [m]")
    ax.set_zlabel("altitude h [m]")
    ax.set_title(f"case {case}: flight path", fontsize=9)
    ax.legend(fontsize=8, loc="upper left")
    fig.savefig(path)
