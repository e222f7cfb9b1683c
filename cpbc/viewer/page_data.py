"""What the run's page (``view.html``) shows, as one JSON-ready dict.

* ``commands``: meshcat commands drawing what every case shares — background, camera, floor,
  obstacles, other world geoms, the arm at its target — and one hidden *template* arm. The
  page clones the template's meshes for every controller of every case (the geometry is
  stored once, however many arms are shown).
* per case and controller: body poses, the traced point (the page draws its path as a tube)
  and every body's clearance at the animation's frames;
* per case: the time plots (positions, rates, applied torques with the plant's limits,
  margins by constraint type), thinned to the smallest and largest sample of each of a few
  hundred time buckets, so that every peak of the run stays in the plot.

Arrays travel deflated, as ``{"deflated": base64}`` (:func:`packed`): meshcat's command bytes
as they are, float32 arrays with a ``stride`` as the byte planes of their successive
differences (cpbc.results.delta_planes), which deflate several times smaller than the floats
themselves. The page inflates them with the browser's DecompressionStream (view.js).
"""

from __future__ import annotations

import base64
import zlib
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cpbc.constraints.constraint_types import Array
from cpbc.results.delta_planes import decode, encode
from cpbc.results.margin_types import grouped, nearest_columns
from cpbc.results.palette import (
    BOUND_COLOUR,
    OBSTACLE_COLOUR,
    WARNING_COLOUR,
    controller_colour,
)
from cpbc.results.saved_run import SavedCase, SavedRun, SavedTrajectory, SummaryEntry
from cpbc.results.summary_table import joint_dynamics_note
from cpbc.results.thinning import Index, envelope
from cpbc.viewer.goal_marker import draw_goal
from cpbc.viewer.recorder import CommandRecorder
from cpbc.viewer.reference_marker import draw_applied, draw_reference
from cpbc.viewer.scene import ROOT, CaseScene, ViewSettings, segment

TEMPLATE = f"{ROOT}/_template"
_PLOT_BUCKETS = 400  # time buckets of a plotted curve (two samples each)


def packed(a: Array | bytes) -> dict[str, Any]:
    """An array for the page, deflated: bytes as they are; floats (sent in single precision)
    as the byte planes of the differences between successive rows, ``stride`` values a row."""
    if isinstance(a, bytes):
        payload, layout = a, {}
    else:
        a = np.asarray(a, dtype="<f4")
        stride = int(np.prod(a.shape[1:], dtype=int))
        payload, layout = encode(a.reshape(len(a), stride)).tobytes(), {"stride": stride}
    return {"deflated": base64.b64encode(zlib.compress(payload, 6)).decode("ascii"), **layout}


def unpacked(entry: dict[str, Any]) -> NDArray[Any]:
    """The array of a :func:`packed` entry, flat (what view.js decodes)."""
    raw = np.frombuffer(zlib.decompress(base64.b64decode(entry["deflated"])), np.uint8)
    if "stride" not in entry:
        return raw
    return decode(raw.reshape(4, -1, entry["stride"])).reshape(-1)


def _shared_scene(run: SavedRun, settings: ViewSettings) -> tuple[CaseScene, dict[str, Any]]:
    """The environment and the template arm, drawn once for the whole run."""
    first = run.cases[0].runs[0]
    kin = run.info.kinematics(run.model)
    scene = CaseScene(kin, run.cases[0].controllers, first.target, first.position[0], settings)
    recorder = CommandRecorder()
    vis = recorder.visualizer()
    scene.draw_environment(vis)
    if run.info.goal is not None:
        draw_goal(vis, f"{ROOT}/goal", run.info.goal, 0.1 * scene.extent[1])
    if run.info.reference is not None:
        draw_reference(vis, f"{ROOT}/reference", run.info.reference)
        for case in run.cases:
            for i, r in enumerate(case.runs):
                if r.applied is not None:
                    draw_applied(vis, f"{ROOT}/{case.name}/applied/{segment(r.controller)}",
                                 r.applied, controller_colour(i))
    bodies = []
    for b in scene.bodies:
        path = f"{TEMPLATE}/{segment(kin.body_names[b])}"
        scene.draw_template_body(vis, path, b)
        bodies.append({"name": kin.body_names[b], "path": path,
                       "geoms": [scene.geom_path(path, g) for g in scene.body_geoms(b)]})
    vis[TEMPLATE].set_property("visible", False)
    obstacles = [f"{ROOT}/obstacles/{segment(kin.geom_names[g])}"
                 for g in kin.obstacle_geoms]
    return scene, {"commands": [packed(c) for c in recorder.commands], "bodies": bodies,
                   "obstacles": obstacles}


def _status(summary: SummaryEntry) -> str:
    """A run's status, and its cause when the summary names one; under a torque-rate limit
    its peak rate against the limit; the controller's slowest call; the friction and rotor
    inertia of the model, when it had any."""
    status = str(summary.get("status", ""))
    cause = summary.get("cause")
    parts = [f"{status}; cause: {cause}" if cause else status]
    peak, limits = summary.get("peak_torque_rate"), summary.get("torque_rate_limits")
    if isinstance(peak, list) and isinstance(limits, list) and peak and limits:
        share = max(float(p) / float(lim) for p, lim in zip(peak, limits, strict=True))
        parts.append(f"peak torque rate {share:.0%} of its limit")
    slowest = summary.get("controller_time_max_us")
    if isinstance(slowest, (int, float)):
        parts.append(f"slowest controller call {float(slowest):.0f} µs")
    friction, armature = summary.get("friction"), summary.get("armature")
    joints = joint_dynamics_note(friction if isinstance(friction, dict) else None,
                                 armature if isinstance(armature, list) else None)
    if joints:
        parts.append(f"model with {joints}")
    return "; ".join(parts)


def _case_scene(run: SavedRun, case: SavedCase, shared: CaseScene) -> dict[str, Any]:
    """Poses, clearances and traces of every controller of a case."""
    first = case.runs[0]
    scene = CaseScene(shared.kin, case.controllers, first.target, first.position[0],
                      shared.settings, root=f"{ROOT}/{case.name}")
    sweeps = scene.sweeps(case.runs)
    controllers = []
    for r in case.runs:
        s = sweeps[r.controller]
        bodies = list(scene.bodies)
        pose = np.concatenate([s.body_position[:, bodies],
                               s.body_quaternion[:, bodies][..., [1, 2, 3, 0]]], axis=2)
        clear = s.body_clearance[:, bodies] if shared.kin.obstacle_geoms else None
        controllers.append({
            "name": r.controller, "colour": scene.colours[r.controller],
            "status": _status(r.summary), "frames": len(s.time),
            "pose": packed(pose), "tip": packed(s.trace),
            "clearance": None if clear is None else packed(np.minimum(clear, 1e3)),
        })
    nearest = None
    if shared.kin.obstacle_geoms and sweeps:
        length = max(len(s.time) for s in sweeps.values())
        near = np.full((length, len(shared.kin.obstacle_geoms)), 1e3)
        for s in sweeps.values():
            pad = np.vstack([s.obstacle_clearance,
                             np.repeat(s.obstacle_clearance[-1:], length - len(s.time), 0)])
            near = np.minimum(near, pad)
        nearest = packed(near)
    return {"controllers": controllers, "obstacleClearance": nearest, "root": f"{ROOT}/{case.name}"}


def _thinned(r: SavedTrajectory, columns: Sequence[Array]) -> Index:
    """Sample indices that keep every extreme of every plotted column of a run."""
    keep = [envelope(np.asarray(c, dtype=float), _PLOT_BUCKETS) for c in columns]
    return np.unique(np.concatenate(keep)) if keep else np.arange(len(r.time))


def _panels(case: SavedCase) -> tuple[list[dict[str, Any]], bool]:
    """Plot groups of a case (each a title and panels), and whether torques are per joint."""
    first = case.runs[0]
    n = len(first.coordinate_names)
    bounds = first.summary.get("rate_bounds") or [None] * n
    limits = first.summary.get("torque_limits")
    identity = bool(np.allclose(first.coordinates, np.eye(n)))
    joints = limits is not None and not identity
    names = first.coordinate_names
    # a run may name its own units (a Part I system's slide joints, its input)
    units = first.summary.get("units") or {}

    # a Part I system's one input, in the first column of the torques
    single = first.summary.get("input_name")

    def coordinate_panels(key: str, unit: str | list[str], extra: Any) -> list[dict[str, Any]]:
        out = []
        for k in range(1 if key == "torque" and single else n):
            label = f"joint {k + 1}" if key == "torque" and joints else names[k]
            if key == "torque" and single:
                out.append({"label": single, "key": key, "column": 0, "lines": extra(0)})
                continue
            each = unit[k] if isinstance(unit, list) else unit  # one per coordinate, or all
            out.append({"label": f"{label} [{each}]", "key": key, "column": k,
                        "lines": extra(k)})
        return out

    def rate_lines(k: int) -> list[dict[str, Any]]:
        b = bounds[k]
        return [] if b is None else [{"y": float(b), "label": f"bound ±{float(b):g}"},
                                     {"y": -float(b), "label": ""}]

    def torque_lines(k: int) -> list[dict[str, Any]]:
        found = None if limits is None else limits[k]  # None: no limit on this joint
        if found is None or not (joints or identity):
            return []
        lim = float(found)
        return [{"y": lim, "label": f"limit ±{lim:.4g}"}, {"y": -lim, "label": ""}]

    def position_lines(k: int) -> list[dict[str, Any]]:
        found = bounded[k] if k < len(bounded) else None  # a run may give its own bounds
        edges = [] if found is None else [{"y": float(found[0]), "label": "bound"},
                                          {"y": float(found[1]), "label": ""}]
        return [{"y": float(first.target[k]), "label": "target"}, *edges]

    bounded = first.summary.get("position_bounds") or []
    # a run may say which groups apply and name them (a system that is only its ODE: its
    # states and its input)
    titles = {"position": "Positions", "velocity": "Rates", "torque": "Torques applied",
              **(first.summary.get("titles") or {})}
    lines = {"position": position_lines, "velocity": rate_lines, "torque": torque_lines}
    default_units = {"position": "rad", "velocity": "rad/s", "torque": "N·m"}
    groups = [{"title": titles[key], "panels": coordinate_panels(
                  key, units.get(key, default_units[key]), lines[key])}
              for key in first.summary.get("groups") or list(lines)]
    margin_panels = []
    for kind, columns in grouped(first.margin_names, first.margin_types):
        named = nearest_columns([r.margins for r in case.runs], columns, 3)
        margin_panels.append({
            "label": f"{kind.label} [{kind.unit}]" if kind.unit else kind.label,
            "key": "margins", "named": named,
            "names": [first.margin_names[i] for i in named],
            "others": [i for i in columns if i not in named],
            "lines": [{"y": 0.0, "label": "boundary", "warning": True}],
        })
    if margin_panels:
        groups.append({"title": "Margins by type", "panels": margin_panels})
    return groups, joints


def _series(r: SavedTrajectory, groups: list[dict[str, Any]], joints: bool) -> dict[str, Any]:
    """The thinned samples of one run for every panel of the case."""
    torque = r.applied_torque(joints)
    columns: list[tuple[str, Array]] = []
    for g in groups:
        for p in g["panels"]:
            if p["key"] == "margins":
                for i in p["named"]:
                    columns.append((f"m{i}", r.margins[:, i]))
                if p["others"]:
                    rest = r.margins[:, p["others"]]
                    with np.errstate(all="ignore"):
                        columns.append((f"lo{p['label']}", np.nanmin(rest, axis=1)))
                        columns.append((f"hi{p['label']}", np.nanmax(rest, axis=1)))
            else:
                source = {"position": r.position, "velocity": r.velocity, "torque": torque}
                columns.append((f"{p['key']}{p['column']}", source[p["key"]][:, p["column"]]))
    idx = _thinned(r, [c for _, c in columns])
    return {"time": packed(r.time[idx]), "columns": {k: packed(c[idx]) for k, c in columns}}


def page_data(run: SavedRun, settings: ViewSettings | None = None) -> dict[str, Any]:
    """Everything the page shows of a run folder (see the module docstring)."""
    settings = settings or ViewSettings()
    shared, data = _shared_scene(run, settings)
    cases = []
    for case in run.cases:
        groups, joints = _panels(case)
        entry = _case_scene(run, case, shared)
        entry.update(
            name=case.name,
            duration=max(float(r.time[-1]) for r in case.runs),
            plots=groups,
            series=[_series(r, groups, joints) for r in case.runs],
        )
        cases.append(entry)
    data.update(
        title=run.info.scenario or run.folder.name,
        fps=settings.fps,
        warnDistance=settings.warn_distance,
        opacity=settings.opacity,
        markerRadius=shared.marker_radius,
        traceRadius=shared.trace_radius,
        colours={"warning": WARNING_COLOUR, "obstacle": OBSTACLE_COLOUR,
                 "bound": BOUND_COLOUR},
        cases=cases,
    )
    return data
