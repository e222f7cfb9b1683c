"""Thesis-style figures of a run: every controller of a case overlaid, bounds dashed.

Per case, into ``<run>/<case>/``:

=================  ==========================================================  =================
file               content                                                     thesis
=================  ==========================================================  =================
``positions.png``  x_k(t) per coordinate, target dashed                        Figs 6.2, 7.1, 7.4
``rates.png``      ẋ_k(t) per coordinate, rate bounds ±B_k dashed              Figs 6.3, 7.2, 7.5
``torques.png``    τ_k(t) per coordinate and ‖τ‖(t) with each controller's     Figs 7.3, 7.6
                   theoretical bound (7.32/7.40) dashed in its colour
``lyapunov.png``   V(t) on a log axis
``margins.png``    margin of every monitored constraint, zero dashed
``path.png``       planar arms only: end-point path in the xy-plane with the   Fig 6.4
                   obstacles cut by the arm's plane, the arm at start and target
=================  ==========================================================  =================

Every curve is drawn from the logged samples themselves: long runs are thinned to the
smallest and largest sample of each of a few thousand time buckets (never interpolated), so a
figure's extremes are exactly the run's; the tests compare them with ``summary.json``.
matplotlib is imported here only, with the Agg canvas and no pyplot state.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Collection, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon

from cpbc.constraints.constraint_types import Array
from cpbc.results.margin_types import grouped, nearest_columns
from cpbc.results.palette import (
    BOUND_COLOUR,
    OBSTACLE_COLOUR,
    WARNING_COLOUR,
    controller_colour,
)
from cpbc.results.saved_run import FIGURES, SavedCase, SavedRun, SavedTrajectory
from cpbc.results.sweep import SceneKinematics
from cpbc.results.thinning import envelope

_WIDTH = 7.0  # inches
_PANEL = 2.1  # inches per stacked panel
_DPI = 110
_PATH_SAMPLES = 4000  # end-point samples drawn per controller in path.png
_PLANAR_TOL = 1e-6  # [m] spread of the traced point's z below which the arm is planar


def _figure(rows: int, title: str, height: float | None = None, width: float = _WIDTH
            ) -> tuple[Figure, list[Axes]]:
    h = height or (0.9 + _PANEL * rows)
    fig = Figure(figsize=(width, h), dpi=_DPI)
    FigureCanvasAgg(fig)
    # Fixed margins in inches: matplotlib's constrained layout took most of a figure's time.
    fig.subplots_adjust(left=1.0 / width, right=1 - 0.2 / width, top=1 - 0.5 / h,
                        bottom=0.55 / h, hspace=0.3 * _PANEL / (_PANEL - 0.3))
    axes = list(fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])
    fig.suptitle(title, fontsize=11)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    return fig, axes


def _curve(ax: Axes, t: Array, y: Array, **style: Any) -> None:  # Line2D properties
    idx = envelope(y)
    ax.plot(t[idx], y[idx], **{"lw": 1.4, **style})


def _legend(ax: Axes) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=8, framealpha=0.85)


def _symbol(name: str, rate: bool = False) -> str:
    """``theta1`` → mathtext θ₁ (θ̇₁ for a rate); other names as they are (``d<name>/dt``)."""
    m = re.fullmatch(r"(theta|q|x)_?(\d+)", name)
    if m is None:
        return f"d{name}/dt" if rate else name
    base = r"\theta" if m.group(1) == "theta" else m.group(1)
    symbol = r"\dot{" + base + "}" if rate else base
    return f"${symbol}_{{{m.group(2)}}}$"


def _each(case: SavedCase) -> list[tuple[SavedTrajectory, str]]:
    return [(r, controller_colour(i)) for i, r in enumerate(case.runs)]


def _title(case: SavedCase, what: str) -> str:
    return f"{what} — case '{case.name}'"


def positions_figure(case: SavedCase) -> Figure:
    """x_k(t) of every controller, target x_d,k dashed (Figs 6.2, 7.1, 7.4)."""
    first = case.runs[0]
    fig, axes = _figure(len(first.coordinate_names), _title(case, "Positions"))
    for k, (ax, name) in enumerate(zip(axes, first.coordinate_names, strict=True)):
        for r, colour in _each(case):
            _curve(ax, r.time, r.position[:, k], color=colour, label=r.controller)
        ax.axhline(first.target[k], color=BOUND_COLOUR, ls="--", lw=1.0, label="target")
        ax.set_ylabel(f"{_symbol(name)} [rad]")
        _legend(ax)
    return fig


def rates_figure(case: SavedCase) -> Figure:
    """ẋ_k(t) of every controller with the rate bounds ±B_k dashed (Figs 6.3, 7.2, 7.5)."""
    first = case.runs[0]
    fig, axes = _figure(len(first.coordinate_names), _title(case, "Rates"))
    bounds = first.summary.get("rate_bounds") or [None] * len(first.coordinate_names)
    for k, (ax, name) in enumerate(zip(axes, first.coordinate_names, strict=True)):
        for r, colour in _each(case):
            _curve(ax, r.time, r.velocity[:, k], color=colour, label=r.controller)
        b = bounds[k]
        if b is not None:
            ax.axhline(float(b), color=BOUND_COLOUR, ls="--", lw=1.0, label=f"bound ±{b:g}")
            ax.axhline(-float(b), color=BOUND_COLOUR, ls="--", lw=1.0)
        ax.set_ylabel(f"{_symbol(name, rate=True)} [rad/s]")
        _legend(ax)
    return fig


def _joint_frame(case: SavedCase) -> bool:
    """Whether torques are drawn per joint: when the plant limits them (the limits are per
    joint) and the controller's coordinates are not the joints."""
    first = case.runs[0]
    limited = first.summary.get("torque_limits") is not None
    return limited and not np.allclose(first.coordinates, np.eye(len(first.coordinates)))


def torques_figure(case: SavedCase) -> Figure:
    """τ_k(t) applied per coordinate (what the controller asked for, where the plant's limit
    cut it, thin), the plant's limits ±τ_max dashed, and ‖τ‖(t) asked for with each
    controller's theoretical bound (7.32/7.40) dashed in its colour."""
    first = case.runs[0]
    n = len(first.coordinate_names)
    joints = _joint_frame(case)
    fig, axes = _figure(n + 1, _title(case, "Torques"))
    limits = first.summary.get("torque_limits")
    for k, ax in enumerate(axes[:n]):
        for r, colour in _each(case):
            applied, asked = r.applied_torque(joints), r.commanded_torque(joints)
            # single-precision logs: equal up to their rounding unless the limit cut in
            if not np.allclose(applied[:, k], asked[:, k], rtol=1e-5, atol=1e-6,
                               equal_nan=True):
                _curve(ax, r.time, asked[:, k], color=colour, lw=0.7, alpha=0.6,
                       label=f"{r.controller} asked")
            _curve(ax, r.time, applied[:, k], color=colour, label=r.controller)
        found = None if limits is None else limits[k]  # None: no limit on this joint
        if found is not None and (joints or _identity(first)):
            lim = float(found)
            ax.axhline(lim, color=BOUND_COLOUR, ls="--", lw=1.0, label=f"limit ±{lim:.4g}")
            ax.axhline(-lim, color=BOUND_COLOUR, ls="--", lw=1.0)
        what = f"joint {k + 1}" if joints else _symbol(first.coordinate_names[k])
        ax.set_ylabel(f"τ of {what} [N·m]")
        _legend(ax)
    ax = axes[n]
    for r, colour in _each(case):
        _curve(ax, r.time, np.linalg.norm(r.torque, axis=1), color=colour, label=r.controller)
        bound = r.summary.get("torque_bound")
        if bound is not None:
            ax.axhline(
                float(bound),
                color=colour,
                ls="--",
                lw=1.0,
                label=f"{r.controller} bound {float(bound):.4g}",
            )
    ax.set_ylabel("‖τ‖ asked [N·m]")
    _legend(ax)
    return fig


def _identity(r: SavedTrajectory) -> bool:
    return bool(np.allclose(r.coordinates, np.eye(len(r.coordinates))))


def lyapunov_figure(case: SavedCase) -> Figure:
    """V(t) of every controller on a log axis (samples where V ≤ 0 or undefined are gaps)."""
    fig, (ax,) = _figure(1, _title(case, "Lyapunov function V"), height=3.4)
    for r, colour in _each(case):
        v = np.where(np.isfinite(r.lyapunov) & (r.lyapunov > 0), r.lyapunov, np.nan)
        _curve(ax, r.time, v, color=colour, label=r.controller)
    ax.set_yscale("log")
    ax.set_ylabel("V")
    _legend(ax)
    return fig


def task_error_figure(case: SavedCase) -> Figure | None:
    """A goal run's task error: the position [mm] and, for an orientation goal, the angle
    [rad] to the goal against time, on log axes (None for joint runs)."""
    runs = [(r, c) for r, c in _each(case) if r.task_error is not None]
    if not runs:
        return None
    angled = any(r.task_error is not None and bool(np.any(r.task_error[:, 1] > 0))
                 for r, _ in runs)
    fig, axes = _figure(2 if angled else 1, _title(case, "task error"),
                        height=5.0 if angled else 3.4)
    for r, colour in runs:
        assert r.task_error is not None
        for ax, values in zip(axes, (r.task_error[:, 0] * 1000.0, r.task_error[:, 1]),
                              strict=False):
            _curve(ax, r.time, np.where(values > 0, values, np.nan), color=colour,
                   label=r.controller)
    for ax, label in zip(axes, ("position [mm]", "angle [rad]"), strict=False):
        ax.set_yscale("log")
        ax.set_ylabel(label)
    _legend(axes[0])
    return fig


def governor_figure(case: SavedCase) -> Figure | None:
    """A reference run's governor: the applied path time s_v against the run time (the
    nominal t dotted, blocked samples in red) and the lag min(t, T) − s_v (None for other runs)."""
    runs = [(r, c) for r, c in _each(case) if r.path_time is not None]
    if not runs:
        return None
    fig, (top, low) = _figure(2, _title(case, "reference governor"), height=5.0)
    t_end = max(float(r.time[-1]) for r, _ in runs)
    top.plot([0.0, t_end], [0.0, t_end], ":", color="0.5", lw=1.0, label="t (nominal)")
    for r, colour in runs:
        assert r.path_time is not None
        _curve(top, r.time, r.path_time, color=colour, label=r.controller)
        if r.blocked is not None and np.any(r.blocked):
            hit = np.asarray(r.blocked, dtype=bool)
            top.plot(r.time[hit], r.path_time[hit], ".", color="red", ms=2)
        if r.path_lag is not None:
            _curve(low, r.time, r.path_lag, color=colour)
    top.set_ylabel("path time s_v [s]")
    low.set_ylabel("lag min(t, T) − s_v [s]")
    _legend(top)
    return fig


_NAMED = 3  # constraints of a type drawn and named one by one; the rest as a shaded range
_STYLES = ("-", "--", ":")


def margins_figure(case: SavedCase) -> Figure | None:
    """Margins grouped by constraint type, one panel per type in its unit (rad, rad/s, m,
    J; see cpbc.results.margin_types), zero dashed; None when nothing is monitored.

    In a panel, the three constraints that came nearest their bounds are drawn one by one
    (a line style each, the controller's colour); every other constraint of the type lies
    in the shaded range between the smallest and the largest of their margins.
    """
    first = case.runs[0]
    groups = grouped(first.margin_names, first.margin_types)
    if not groups:
        return None
    fig, axes = _figure(len(groups), _title(case, "Constraint margins by type (> 0 is admissible)"),
                        width=_WIDTH + 2.6)
    fig.subplots_adjust(right=1 - 2.7 / (_WIDTH + 2.6))  # the legends go right of the panels
    for ax, (kind, columns) in zip(axes, groups, strict=True):
        named = nearest_columns([r.margins for r in case.runs], columns, _NAMED)
        rest = [i for i in columns if i not in named]
        top = 0.0
        for r, colour in _each(case):
            if rest:
                lo, hi = _range(r.margins[:, rest])
                keep = np.union1d(envelope(lo), envelope(hi))
                ax.fill_between(r.time[keep], lo[keep], hi[keep], color=colour, alpha=0.15, lw=0)
                top = max(top, float(np.nanmax(lo)))
            for i, style in zip(named, _STYLES, strict=False):
                _curve(ax, r.time, r.margins[:, i], color=colour, ls=style,
                       label=f"{r.controller}: {first.margin_names[i]}")
                top = max(top, float(np.nanmax(r.margins[:, i])))
        ax.axhline(0.0, color=WARNING_COLOUR, ls="--", lw=1.0)
        low = ax.get_ylim()[0]
        if rest and top > 0:  # the far constraints' range would squash the near ones
            ax.set_ylim(low, top + 0.05 * (top - low))
        ax.set_ylabel(f"{kind.label} [{kind.unit}]" if kind.unit else kind.label, fontsize=9)
        _type_legend(ax, case, [first.margin_names[i] for i in named], len(rest))
    return fig


def _type_legend(ax: Axes, case: SavedCase, named: Sequence[str], others: int) -> None:
    """Controllers by colour, constraints by line style, the shaded range of the others."""
    handles: list[Line2D | Patch] = [
        Line2D([], [], color=c, lw=2.5, label=r.controller) for r, c in _each(case)]
    handles += [Line2D([], [], color=BOUND_COLOUR, ls=st, lw=1.4, label=n)
                for n, st in zip(named, _STYLES, strict=False)]
    if others:
        handles.append(Patch(color=BOUND_COLOUR, alpha=0.15, label=f"range of {others} others"))
    handles.append(Line2D([], [], color=WARNING_COLOUR, ls="--", lw=1.0, label="boundary"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5,
              framealpha=0.9, borderaxespad=0.0)


def _range(values: Array) -> tuple[Array, Array]:
    """Smallest and largest of several margins at every sample (NaN where none is finite)."""
    with np.errstate(all="ignore"):
        finite = np.asarray(np.isfinite(values).any(axis=1))
        lo = np.where(finite, np.nanmin(np.where(finite[:, None], values, 0.0), axis=1), np.nan)
        hi = np.where(finite, np.nanmax(np.where(finite[:, None], values, 0.0), axis=1), np.nan)
    return lo, hi


def _finite(r: SavedTrajectory) -> tuple[Array, Array]:
    ok = np.all(np.isfinite(r.position), axis=1)
    return r.time[ok], r.position[ok]


def _end_points(kin: SceneKinematics, r: SavedTrajectory) -> Array:
    time, position = _finite(r)
    step = max(1, len(time) // _PATH_SAMPLES)
    idx = np.unique(np.r_[np.arange(0, len(time), step), len(time) - 1])
    out = np.empty((len(idx), 3))
    for j, k in enumerate(idx):
        kin.pose(position[k])
        out[j] = kin.traced_point()
    return out


def _arm_polyline(kin: SceneKinematics, x: Array) -> Array:
    """Body origins from the first moving body to the traced point, shape (K, 3)."""
    d = kin.pose(x)
    moving = [b for b in range(1, kin.model.nbody) if kin.model.body_jntnum[b] > 0]
    pts = [d.xpos[b].copy() for b in moving]
    return np.array([*pts, kin.traced_point()])


def _outline(
    model: mujoco.MjModel, data: mujoco.MjData, g: int, z: float
) -> Circle | Polygon | None:
    """Obstacle geom ``g`` where the plane at height z cuts it (the xy-shadow for non-spheres)."""
    centre, rot, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
    style = {"facecolor": OBSTACLE_COLOUR, "edgecolor": BOUND_COLOUR, "alpha": 0.55, "lw": 1.0}
    gtype = model.geom_type[g]
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        dz = z - centre[2]
        if abs(dz) >= size[0]:
            return None
        return Circle(tuple(centre[:2]), float(np.sqrt(size[0] ** 2 - dz**2)), **style)
    if gtype == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[g]
        adr, num = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        local = model.mesh_vert[adr : adr + num].astype(float)
    else:
        # Points on the geom's bounding shape: box corners, rings of cylinders and capsules.
        a = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)
        if gtype == mujoco.mjtGeom.mjGEOM_BOX:
            local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            local = local * size
        elif gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
            u, v = np.meshgrid(a, np.linspace(0, np.pi, 13))
            unit = [np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v) + 0 * u]
            local = np.column_stack([c.ravel() for c in unit]) * size
        else:  # cylinder, capsule: rings at the ends (capsule caps widen the shadow by r)
            r, h = size[0], size[1] + (size[0] if gtype == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0)
            ring = np.column_stack([r * np.cos(a), r * np.sin(a)])
            local = np.vstack([np.column_stack([ring, np.full(len(a), s * h)]) for s in (-1, 1)])
    pts = (local @ rot.T + centre)[:, :2]
    return Polygon(_convex_hull(pts), closed=True, **style)


def _convex_hull(pts: Array) -> Array:
    """Monotone-chain convex hull of 2-D points, counter-clockwise, shape (K, 2)."""
    p = np.unique(pts.round(12), axis=0)
    if len(p) < 3:
        return p

    def half(points: Array) -> list[Array]:
        out: list[Array] = []
        for q in points:
            while len(out) >= 2 and np.cross(out[-1] - out[-2], q - out[-2]) <= 0:
                out.pop()
            out.append(q)
        return out

    lower, upper = half(p), half(p[::-1])
    return np.array(lower[:-1] + upper[:-1])


def path_figure(case: SavedCase, kin: SceneKinematics) -> Figure | None:
    """End-point paths in the xy-plane with the obstacles (Fig 6.4); None for a spatial arm."""
    paths = [_end_points(kin, r) for r in case.runs]
    z = float(paths[0][0, 2])
    if np.ptp(np.concatenate([p[:, 2] for p in paths])) >= _PLANAR_TOL:
        return None
    fig = Figure(figsize=(6.2, 6.2), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    fig.suptitle(_title(case, f"Path of '{kin.trace_frame}' in the xy-plane"), fontsize=11)
    data = kin.pose(case.runs[0].position[0])
    for g in kin.obstacle_geoms:
        patch = _outline(kin.model, data, g, z)
        if patch is not None:
            patch.set_label(kin.geom_names[g])
            ax.add_patch(patch)
    start = _arm_polyline(kin, _finite(case.runs[0])[1][0])
    goal = _arm_polyline(kin, case.runs[0].target)
    ax.plot(start[:, 0], start[:, 1], "o-", color="#9a9a9a", lw=3, ms=4, label="arm at start")
    ax.plot(goal[:, 0], goal[:, 1], "o--", color=BOUND_COLOUR, lw=1.5, ms=4, label="arm at target")
    for (r, colour), p in zip(_each(case), paths, strict=True):
        ax.plot(p[:, 0], p[:, 1], color=colour, lw=1.6, label=r.controller)
        ax.plot(p[-1, 0], p[-1, 1], "s", color=colour, ms=5)
    ax.plot(start[-1, 0], start[-1, 1], "o", color="black", ms=6)
    ax.plot(goal[-1, 0], goal[-1, 1], "*", color="black", ms=11, label="target end point")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    _legend(ax)
    return fig


def case_figures(
    case: SavedCase, kin: SceneKinematics | None, names: Collection[str] = FIGURES
) -> dict[str, Figure]:
    """The figures of a case by name (all of FIGURES by default); absent ones are left out."""
    makers: dict[str, Callable[[], Figure | None]] = {
        "positions": lambda: positions_figure(case),
        "rates": lambda: rates_figure(case),
        "torques": lambda: torques_figure(case),
        "lyapunov": lambda: lyapunov_figure(case),
        "margins": lambda: margins_figure(case),
        "path": lambda: None if kin is None else path_figure(case, kin),
        "task_error": lambda: task_error_figure(case),
        "governor": lambda: governor_figure(case),
    }
    out = {}
    for name, make in makers.items():
        if name not in names:
            continue
        fig = make()
        if fig is not None:
            out[name] = fig
    return out


def write_plots(
    run: SavedRun,
    folder: Path | None = None,
    cases: Sequence[str] | None = None,
    only: Collection[tuple[str, str]] | None = None,
) -> list[Path]:
    """Write every case's figures as ``<folder>/<case>/<name>.png``; returns the paths.

    Args:
        run: a run folder read back with :func:`cpbc.results.saved_run.load_run`.
        folder: where to write; the run's own folder when omitted.
        cases: the names of the cases to draw; all when omitted.
        only: (case, figure) pairs to draw; all when omitted (several processes can share
            a run's figures this way).
    """
    folder = run.folder if folder is None else Path(folder)
    kin = run.info.kinematics(run.model)
    written = []
    for case in run.cases:
        if cases is not None and case.name not in cases:
            continue
        out = folder / case.name
        out.mkdir(parents=True, exist_ok=True)
        names = FIGURES if only is None else [n for c, n in only if c == case.name]
        for name, fig in case_figures(case, kin, names).items():
            path = out / f"{name}.png"
            fig.savefig(path, metadata={"Title": fig.get_suptitle(), "Software": "cpbc"})
            written.append(path)
    return written
