"""``view.html`` for a Part I system run: the system's MJCF geometry replayed from the logged
MuJoCo coordinates, with the same page as an arm's (one timeline for the scene and the time
plots). The plots show MuJoCo's coordinates and the input; the margins are each constrained
quantity's distance to its bound, in its own unit."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from cpbc.results.saved_run import SavedCase, SavedRun, SavedTrajectory, SceneInfo
from cpbc.results.sweep import default_trace_frame
from cpbc.scenario.system_build import SystemSetup
from cpbc.scenario.system_runner import SystemResult
from cpbc.systems.ode_plant import Plant
from cpbc.viewer.export import write_view


def _units(setup: SystemSetup, model: mujoco.MjModel) -> dict[str, str | list[str]]:
    """The plots' units, one per coordinate: m for slide joints, rad for hinges; the input's
    own unit."""
    slide = [model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE for j in range(model.njnt)]
    unit = setup.input_name.partition("[")[2].rstrip("]") or "-"
    return {"position": ["m" if s else "rad" for s in slide],
            "velocity": ["m/s" if s else "rad/s" for s in slide],
            "torque": f"input {unit}"}


def _saved(result: SystemResult, setup: SystemSetup, names: tuple[str, ...],
           units: dict[str, str | list[str]]) -> SavedTrajectory:
    traj = result.trajectory
    assert traj.qpos is not None and traj.qvel is not None  # both loops log them
    case = next(c for c in setup.cases if c.name == result.case)
    quantities = case.plant.constrained
    margins = np.column_stack([
        min(-q.lower, q.upper) - np.abs(traj.input if q.source == "input"
                                        else traj.state[:, q.index])
        for q in quantities])
    n = traj.qpos.shape[1]
    force = np.zeros((len(traj.time), n))
    force[:, 0] = traj.input  # the input in the first column, labelled in coordinate_names
    return SavedTrajectory(
        controller=result.law, case=result.case, time=traj.time, position=traj.qpos,
        velocity=traj.qvel, torque=force, joint_torque=force, margins=margins,
        margin_names=tuple(q.name for q in quantities),
        margin_types=("other",) * len(quantities), lyapunov=np.full(len(traj.time), np.nan),
        target=np.zeros(n), coordinate_names=names, outcome=traj.outcome,
        summary={"status": result.summary.status, "controller": result.law,
                 "case": result.case, "units": units},
        coordinates=np.eye(n),
    )


def write_system_view(folder: Path, setup: SystemSetup,
                      results: Sequence[SystemResult]) -> Path | None:
    """Write ``folder/view.html`` for the runs of a Part I scenario; returns its path, or None
    (nothing written) for a system that is only its ODE: an integrator chain has no body to
    pose, and its time plots are the figures already written."""
    plant = setup.cases[0].plant
    if not isinstance(plant, Plant):
        return None
    model = plant.load()
    names = tuple(model.joint(i).name for i in range(model.njnt))
    info = SceneInfo(np.eye(model.nq), default_trace_frame(model), setup.scenario.name, ())
    units = _units(setup, model)
    cases = tuple(
        SavedCase(c.name, tuple(_saved(r, setup, names, units) for r in results
                                if r.case == c.name))
        for c in setup.cases)
    return write_view(SavedRun(folder, model, info, cases))
