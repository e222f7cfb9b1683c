"""Figures of a Part I system run in the thesis's style: time plots per case with the
bounds dashed, the phase portrait, and a vehicle's path in 3-D (an arm's: cpbc.results.plots).

matplotlib is imported only with the Agg canvas and no pyplot state, as in plots.py.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from cpbc.arrays import Array
from cpbc.results.palette import BOUND_COLOUR, controller_colour
from cpbc.results.system_metrics import Panel, SystemView
from cpbc.simulation.trajectory import SystemTrajectory


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
