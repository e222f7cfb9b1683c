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
from collections.abc import Callable, Sequence
from pathlib import Path

import mujoco
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon

from cpbc.constraints.base import Array
from cpbc.results.palette import (
    BOUND_COLOUR,
    OBSTACLE_COLOUR,
    WARNING_COLOUR,
    controller_colour,
)
from cpbc.results.saved_run import SavedCase, SavedRun, SavedTrajectory
from cpbc.results.sweep import SceneKinematics

FIGURES = ("positions", "rates", "torques", "lyapunov", "margins", "path")
_WIDTH = 7.0  # inches
_PANEL = 2.1  # inches per stacked panel
_DPI = 110
_PATH_SAMPLES = 4000  # end-point samples drawn per controller in path.png
_PLANAR_TOL = 1e-6  # [m] spread of the traced point's z below which the arm is planar
_BUCKETS = 1500  # time buckets of a thinned curve (two samples each)


def _figure(rows: int, title: str, height: float | None = None) -> tuple[Figure, list[Axes]]:
    fig = Figure(figsize=(_WIDTH, height or (0.9 + _PANEL * rows)), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = list(fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])
    fig.suptitle(title, fontsize=11)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    return fig, axes


def envelope(y: Array, buckets: int = _BUCKETS) -> Array:
    """Indices of the samples of ``y`` a thinned curve keeps, in time order.

    The first and last samples and, in each of ``buckets`` equal runs of samples, the
    smallest and the largest (NaN samples are never preferred). All samples when short.
    """
    n = len(y)
    if n <= 2 * buckets:
        return np.arange(n)
    b = -(-n // buckets)
    padded = np.full(b * (-(-n // b)), np.nan)
    padded[:n] = y
    rows = padded.reshape(-1, b)
    offset = np.arange(rows.shape[0]) * b
    lo = np.argmin(np.where(np.isnan(rows), np.inf, rows), axis=1) + offset
    hi = np.argmax(np.where(np.isnan(rows), -np.inf, rows), axis=1) + offset
    idx = np.unique(np.concatenate([[0, n - 1], lo, hi]))
    return idx[idx < n]


def _curve(ax: Axes, t: Array, y: Array, **style: object) -> None:
    idx = envelope(y)
    ax.plot(t[idx], y[idx], lw=1.4, **style)


def _legend(ax: Axes) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=8, framealpha=0.85)


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


def torques_figure(case: SavedCase) -> Figure:
    """τ_k(t) per coordinate and ‖τ‖(t), each controller's theoretical ‖τ‖ bound dashed."""
    first = case.runs[0]
    n = len(first.coordinate_names)
    fig, axes = _figure(n + 1, _title(case, "Torques"))
    for k, (ax, name) in enumerate(zip(axes[:n], first.coordinate_names, strict=True)):
        for r, colour in _each(case):
            _curve(ax, r.time, r.torque[:, k], color=colour, label=r.controller)
        ax.set_ylabel(f"τ of {_symbol(name)} [N·m]")
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
    ax.set_ylabel("‖τ‖ [N·m]")
    _legend(ax)
    return fig


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


def margins_figure(case: SavedCase) -> Figure | None:
    """The margin of every monitored constraint, zero dashed; None when there are none."""
    names = case.runs[0].margin_names
    if not names:
        return None
    fig, axes = _figure(len(names), _title(case, "Constraint margins (> 0 is admissible)"))
    for i, (ax, name) in enumerate(zip(axes, names, strict=True)):
        for r, colour in _each(case):
            enforced = name in (r.summary.get("enforced_constraints") or [])
            label = f"{r.controller} (enforced)" if enforced else r.controller
            _curve(ax, r.time, r.margins[:, i], color=colour, label=label)
        ax.axhline(0.0, color=WARNING_COLOUR, ls="--", lw=1.0, label="boundary")
        ax.set_ylabel(name, fontsize=9)
    _legend(axes[0])
    return fig


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


def case_figures(case: SavedCase, kin: SceneKinematics | None) -> dict[str, Figure]:
    """Every figure of a case by name (see FIGURES); absent ones are left out."""
    makers: dict[str, Callable[[], Figure | None]] = {
        "positions": lambda: positions_figure(case),
        "rates": lambda: rates_figure(case),
        "torques": lambda: torques_figure(case),
        "lyapunov": lambda: lyapunov_figure(case),
        "margins": lambda: margins_figure(case),
        "path": lambda: None if kin is None else path_figure(case, kin),
    }
    out = {}
    for name, make in makers.items():
        fig = make()
        if fig is not None:
            out[name] = fig
    return out


def write_plots(
    run: SavedRun, folder: Path | None = None, cases: Sequence[str] | None = None
) -> list[Path]:
    """Write every case's figures as ``<folder>/<case>/<name>.png``; returns the paths.

    Args:
        run: a run folder read back with :func:`cpbc.results.saved_run.load_run`.
        folder: where to write; the run's own folder when omitted.
        cases: the names of the cases to draw; all when omitted.
    """
    folder = run.folder if folder is None else Path(folder)
    kin = run.info.kinematics(run.model)
    written = []
    for case in run.cases:
        if cases is not None and case.name not in cases:
            continue
        out = folder / case.name
        out.mkdir(parents=True, exist_ok=True)
        for name, fig in case_figures(case, kin).items():
            path = out / f"{name}.png"
            fig.savefig(path, metadata={"Title": fig.get_suptitle(), "Software": "cpbc"})
            written.append(path)
    return written
