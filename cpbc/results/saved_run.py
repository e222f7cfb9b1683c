"""A run folder read back: the scene it was simulated in and every trajectory it logged.

``python -m cpbc.run`` writes, next to ``summary.json`` and ``trajectories.h5`` (every run's
log, cpbc.results.hdf5_log), the scene the runs happened in:

* ``scene.mjb.gz``: the compiled MuJoCo model with the scenario's obstacles (binary MJB,
  gzipped — meshes halve —, so a replay needs no model or mesh files; it loads with the same
  MuJoCo version; folders of earlier versions hold it as a plain ``scene.mjb``);
* ``scene.json``: the controller's coordinates ``x = T q`` and the frame whose path is traced.

The figures and the viewer read a run only through :func:`load_run`. Folders of earlier
versions, a ``<case>/<controller>/trajectory.npz`` per run instead of ``trajectories.h5``,
still load.
"""

from __future__ import annotations

import gzip
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

import h5py
import mujoco
import numpy as np

from cpbc.constraints.constraint_types import Array
from cpbc.errors import CpbcError
from cpbc.results.delta_planes import load_earlier_log
from cpbc.results.hdf5_log import LOG_FILE, read_run
from cpbc.results.sweep import SceneKinematics

SCENE_MODEL = "scene.mjb.gz"
PLAIN_SCENE_MODEL = "scene.mjb"  # what earlier versions wrote
SCENE_INFO = "scene.json"
SUMMARY = "summary.json"
EARLIER_TRAJECTORY = "trajectory.npz"  # a run's log in folders of earlier versions
#: The figures of each case, ``<case>/<name>.png`` (cpbc.results.plots draws them).
FIGURES = ("positions", "rates", "torques", "lyapunov", "margins", "path", "task_error",
           "governor")


class _SummaryKeys(TypedDict):
    controller: str
    case: str


class SummaryEntry(_SummaryKeys, total=False):
    """One run's object in summary.json (:meth:`cpbc.results.metrics.RunSummary.as_dict`),
    as far as the figures and the viewer read it: non-finite numbers are null there, and
    hand-made or earlier entries may lack keys. The entry holds the summary's other keys too.
    """

    status: str
    rate_bounds: list[float | None]
    torque_limits: list[float | None] | None
    torque_bound: float | None
    units: dict[str, str | list[str]]  # the plots' units when not an arm's (per coordinate or all)
    # a system that is only its ODE (its page: cpbc.viewer.outputs): the page's groups of
    # plots ("position", "velocity", "torque"), their titles, and a bound interval per
    # position (None: unbounded)
    groups: list[str]
    titles: dict[str, str]
    position_bounds: list[list[float] | None]
    input_name: str  # a Part I system's one input, with its unit: the torques' one panel
    cause: str | None  # why a failed run likely failed, when foreseen (RunSummary.cause)


@dataclass(frozen=True)
class SceneInfo:
    """What a replay needs besides the MuJoCo model.

    Attributes:
        coordinates: T of the controller's coordinates x = T q, shape (n, n).
        trace_frame: MuJoCo site or body whose path is drawn (the end point).
        scenario: name of the scenario.
        obstacles: names of the world geoms that are the scenario's obstacles (None: every
            world geom but planes).
        goal: a goal run's goal, drawn as a triad (cpbc.viewer.goal_marker.goal_entry):
            position, rotation (3 × 3) or None, axis (world) or None; None for joint runs.
    """

    coordinates: Array
    trace_frame: str
    scenario: str = ""
    obstacles: tuple[str, ...] | None = None
    goal: dict[str, Any] | None = None
    # a reference run's path and inadmissible stretches (cpbc.viewer.reference_marker)
    reference: dict[str, Any] | None = None

    def to_json(self) -> str:
        return json.dumps(
            {
                "coordinates": np.asarray(self.coordinates, dtype=float).tolist(),
                "trace_frame": self.trace_frame,
                "scenario": self.scenario,
                "obstacles": None if self.obstacles is None else list(self.obstacles),
                "goal": self.goal,
                "reference": self.reference,
            },
            indent=2,
        )

    @classmethod
    def from_json(cls, text: str) -> SceneInfo:
        d = json.loads(text)
        obstacles = d.get("obstacles")
        return cls(
            np.array(d["coordinates"], dtype=float),
            d["trace_frame"],
            d.get("scenario", ""),
            None if obstacles is None else tuple(obstacles),
            d.get("goal"),
            d.get("reference"),
        )

    def kinematics(self, model: mujoco.MjModel) -> SceneKinematics:
        """The scene's kinematics with this run's coordinates, traced frame and obstacles."""
        return SceneKinematics(model, self.coordinates, self.trace_frame, self.obstacles)


@dataclass(frozen=True)
class SavedTrajectory:
    """One controller on one case, as logged (controller coordinates).

    Attributes:
        controller, case: names.
        time: (N,) [s].
        position, velocity: (N, n) [rad, rad/s].
        torque: (N, n) generalised forces asked for.
        joint_torque: (N, n) joint torques applied.
        margins: (N, m) margin of every monitored constraint, as a distance to its bound
            in its type's unit (cpbc.results.margin_types).
        margin_names: (m,) their names.
        margin_types: (m,) their type keys ("position", "rate", "clearance", …).
        lyapunov: (N,) V.
        target: (n,).
        coordinate_names: (n,).
        outcome: "completed", "diverged" or "constraint_violated".
        summary: this run's entry of summary.json.
        coordinates: T of x = T q, shape (n, n).
    """

    controller: str
    case: str
    time: Array
    position: Array
    velocity: Array
    torque: Array
    joint_torque: Array
    margins: Array
    margin_names: tuple[str, ...]
    lyapunov: Array
    target: Array
    coordinate_names: tuple[str, ...]
    outcome: str
    summary: SummaryEntry
    margin_types: tuple[str, ...] = ()
    coordinates: Array = field(default_factory=lambda: np.eye(0))
    task_error: Array | None = None  # a goal run's (position m, angle rad), (N, 2)
    # a reference run's applied path time s_v [s] and blocked flag per sample, (N,)
    path_time: Array | None = None
    blocked: Array | None = None
    path_lag: Array | None = None
    applied: Array | None = None  # the applied reference point per sample, (N, 3)

    def commanded_torque(self, joints: bool = False) -> Array:
        """What the controller asked for, (N, n): in its coordinates, or per joint
        (τ_q = Tᵀ τ, row by row τ T)."""
        return self.torque @ self.coordinates if joints else self.torque

    def applied_torque(self, joints: bool = False) -> Array:
        """What the plant applied after its torque limit, (N, n): per joint, or in the
        controller's coordinates (τ = T⁻ᵀ τ_q, row by row τ_q T⁻¹)."""
        if joints:
            return self.joint_torque
        return np.linalg.solve(self.coordinates.T, self.joint_torque.T).T


@dataclass(frozen=True)
class SavedCase:
    """Every controller's run on one case, in the scenario's order."""

    name: str
    runs: tuple[SavedTrajectory, ...]

    @property
    def controllers(self) -> tuple[str, ...]:
        return tuple(r.controller for r in self.runs)


@dataclass(frozen=True)
class SavedRun:
    """A whole run folder."""

    folder: Path
    model: mujoco.MjModel
    info: SceneInfo
    cases: tuple[SavedCase, ...]

    def case(self, name: str) -> SavedCase:
        for c in self.cases:
            if c.name == name:
                return c
        raise CpbcError(
            f"run '{self.folder}' has no case '{name}'; cases: {[c.name for c in self.cases]}"
        )


def write_scene(folder: Path, model: mujoco.MjModel, info: SceneInfo) -> None:
    """Write ``scene.mjb.gz`` and ``scene.json`` into a run folder."""
    buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    (folder / SCENE_MODEL).write_bytes(gzip.compress(buffer.tobytes(), compresslevel=6))
    (folder / SCENE_INFO).write_text(info.to_json())


def _trajectory(d: dict[str, Any], summary: SummaryEntry, coordinates: Array) -> SavedTrajectory:
    names = tuple(str(s) for s in d["margin_names"])
    # runs written before margins had types: every margin of an unknown type
    types = (tuple(str(s) for s in d["margin_types"]) if "margin_types" in d
             else ("other",) * len(names))
    return SavedTrajectory(
        controller=str(summary["controller"]),
        case=str(summary["case"]),
        time=d["time"],
        position=d["position"],
        velocity=d["velocity"],
        torque=d["torque"],
        joint_torque=d["joint_torque"],
        margins=d["margins"],
        margin_names=names,
        margin_types=types,
        coordinates=coordinates,
        lyapunov=d["lyapunov"],
        target=d["target"],
        coordinate_names=tuple(str(s) for s in d["coordinate_names"]),
        outcome=str(d["outcome"]),
        summary=summary,
        task_error=d.get("task_error"),
        path_time=d.get("path_time"),
        blocked=d.get("blocked"),
        path_lag=d.get("path_lag"),
        applied=d.get("applied"),
    )


def _logs(folder: Path, summaries: list[SummaryEntry]) -> list[dict[str, Any]]:
    """Every run's log, in the order of summary.json: from trajectories.h5, or from the
    trajectory.npz files of a folder an earlier version wrote."""
    names = [(str(s["case"]), str(s["controller"])) for s in summaries]
    if not (folder / LOG_FILE).is_file():
        paths = [folder / case / ctrl / EARLIER_TRAJECTORY for case, ctrl in names]
        for path in paths:
            if not path.is_file():
                raise CpbcError(f"run folder '{folder}' lacks {LOG_FILE}")
        return [load_earlier_log(p) for p in paths]
    try:
        with h5py.File(folder / LOG_FILE, "r") as f:
            return [read_run(f, case, ctrl) for case, ctrl in names]
    except KeyError as exc:
        raise CpbcError(f"{folder / LOG_FILE} lacks a run of summary.json ({exc})") from None
    except OSError as exc:
        raise CpbcError(f"cannot read {folder / LOG_FILE}: {exc}") from None


def _is_system_run(folder: Path) -> bool:
    """A Part I run's summary.json: run objects with a ``system`` outcome."""
    try:
        runs = json.loads((folder / SUMMARY).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(runs, list) and bool(runs) and all(
        isinstance(r, dict) and isinstance(r.get("system"), dict) for r in runs)


def load_run(folder: Path | str) -> SavedRun:
    """Read a run folder written by ``python -m cpbc.run``.

    Raises:
        CpbcError: when the folder lacks summary.json, the scene files or a trajectory.
    """
    folder = Path(folder)
    model_file = folder / (PLAIN_SCENE_MODEL if (folder / PLAIN_SCENE_MODEL).is_file()
                           else SCENE_MODEL)
    missing = [n for n in (SUMMARY, model_file.name, SCENE_INFO) if not (folder / n).is_file()]
    if missing and _is_system_run(folder):
        raise CpbcError(f"'{folder}' holds a Part I system run, which this replay does not "
                        "read: open its view.html in a browser")
    if missing:
        raise CpbcError(
            f"'{folder}' is not a complete run folder: missing {', '.join(missing)} "
            "(run the scenario again with python -m cpbc.run to write them)"
        )
    try:
        data = model_file.read_bytes()
        if model_file.name == SCENE_MODEL:
            data = gzip.decompress(data)
        model = mujoco.MjModel.from_binary_path(PLAIN_SCENE_MODEL, {PLAIN_SCENE_MODEL: data})
    except (ValueError, OSError) as exc:
        raise CpbcError(f"cannot load {model_file}: {exc}") from exc
    info = SceneInfo.from_json((folder / SCENE_INFO).read_text())
    summaries = json.loads((folder / SUMMARY).read_text())
    by_case: dict[str, list[SavedTrajectory]] = {}
    for s, log in zip(summaries, _logs(folder, summaries), strict=True):
        by_case.setdefault(str(s["case"]), []).append(_trajectory(log, s, info.coordinates))
    cases = tuple(SavedCase(name, tuple(runs)) for name, runs in by_case.items())
    return SavedRun(folder, model, info, cases)
