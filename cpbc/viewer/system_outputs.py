"""What a Part I system's run leaves besides its data (an arm's: cpbc.viewer.outputs): its
figures, and the arm's page drawing the system's MJCF geometry replayed from the logged
MuJoCo coordinates, with one timeline for the scene and the time plots; the plots show
MuJoCo's coordinates and the input, the margins each constrained quantity's distance to its
nearer bound (ConstrainedQuantity.margins, as the summary's), grouped by its margin type. A
system that is only its ODE (the integrator chain) has no body to draw: its page is its time
plots, the states against their bounds and the input."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from cpbc.results.plots import case_figures
from cpbc.results.saved_run import SavedCase, SavedRun, SavedTrajectory, SceneInfo, SummaryEntry
from cpbc.results.sweep import default_trace_frame
from cpbc.results.system_plots import plot_case, plot_path
from cpbc.scenario.runner import SystemResult
from cpbc.scenario.system_setup import SystemCase, SystemSetup
from cpbc.systems.ode_plant import Plant
from cpbc.viewer.export import write_view


def write_system_outputs(folder: Path, setup: SystemSetup, results: Sequence[SystemResult],
                         plots: bool = True) -> Path:
    """Into a run folder: every case's figures, unless ``plots`` is False (the thesis's time
    plots <case>/timeseries.png and, for a vehicle, path.png, cpbc.results.system_plots; the
    margins over time, margins.png, drawn as an arm's by cpbc.results.plots), and view.html.
    Returns the page."""
    run = saved_system_run(folder, setup, results)
    if plots:
        for case, saved in zip(setup.cases, run.cases, strict=True):
            runs = [(r.controller, r.trajectory) for r in results if r.case == case.name]
            (folder / case.name).mkdir(exist_ok=True)
            plot_case(folder / case.name / "timeseries.png", case.name, runs, setup.view)
            if setup.view.path is not None:
                plot_path(folder / case.name / "path.png", case.name, runs, setup.view)
            for name, fig in case_figures(saved, None, ("margins",)).items():
                fig.savefig(folder / case.name / f"{name}.png",
                            metadata={"Title": fig.get_suptitle(), "Software": "cpbc"})
    return write_view(run)


def ode_display_model(state_names: Sequence[str]) -> mujoco.MjModel:
    """A model with nothing to draw and a joint per state component: what the page poses
    for a system that is only its ODE (never simulated; its geometry-less bodies turn in
    place at the origin, so the scene stays empty and traces no path: the page's content is
    its time plots)."""
    bodies = "".join(
        f'<body name="{_bare(n)}"><joint name="{_bare(n)}" type="hinge"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body>' for n in state_names)
    return mujoco.MjModel.from_xml_string(f'<mujoco model="states"><worldbody>{bodies}'
                                          '</worldbody></mujoco>')


def _bare(name: str) -> str:
    """A state's name without its unit ("x3 [m]" → "x3")."""
    return name.split(" [")[0]


def _state_page(setup: SystemSetup, case: SystemCase, summary: SummaryEntry) -> None:
    """What the page of a system that is only its ODE shows of a run, into its ``summary``:
    the states (with the bounds of those constrained) and the input, no rates (the states
    are the system's coordinates: each is the rate of the one before)."""
    bounds: list[list[float] | None] = [None] * len(setup.state_names)
    for q in case.plant.constrained:
        if q.source == "state":
            bounds[q.index] = [q.lower, q.upper]
    summary["units"] = {"position": [n.partition("[")[2].rstrip("]") or "-"
                                     for n in setup.state_names]}
    summary["groups"] = ["position", "torque"]
    summary["titles"] = {"position": "States", "torque": "Input"}  # its coordinates: the states
    summary["position_bounds"] = bounds


def _units(model: mujoco.MjModel) -> dict[str, str | list[str]]:
    """The plots' units, one per coordinate: m for slide joints, rad for hinges (the input's
    panel is labelled with its name and unit)."""
    slide = [model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE for j in range(model.njnt)]
    return {"position": ["m" if s else "rad" for s in slide],
            "velocity": ["m/s" if s else "rad/s" for s in slide]}


def _saved(result: SystemResult, setup: SystemSetup, names: tuple[str, ...],
           units: dict[str, str | list[str]]) -> SavedTrajectory:
    traj = result.trajectory
    case = next(c for c in setup.cases if c.name == result.case)
    summary: SummaryEntry = {"status": result.summary.status, "controller": result.controller,
                             "case": result.case, "units": units,
                             "input_name": setup.input_name, "titles": {"torque": "Input"}}
    if traj.qpos is None or traj.qvel is None:  # only its ODE: the states are the coordinates
        qpos, qvel = traj.state, np.zeros_like(traj.state)
        _state_page(setup, case, summary)
    else:
        qpos, qvel = traj.qpos, traj.qvel
    quantities = case.plant.constrained
    margins = np.column_stack([q.margins(traj.state, traj.input) for q in quantities])
    n = qpos.shape[1]
    force = np.zeros((len(traj.time), n))
    force[:, 0] = traj.input  # the input in the first column, labelled in coordinate_names
    return SavedTrajectory(
        controller=result.controller, case=result.case, time=traj.time, position=qpos,
        velocity=qvel, torque=force, joint_torque=force, margins=margins,
        margin_names=tuple(q.name for q in quantities),
        margin_types=tuple(q.margin_type.key for q in quantities),
        lyapunov=np.full(len(traj.time), np.nan),
        target=np.zeros(n), coordinate_names=names, outcome=traj.outcome,
        summary=summary,
        coordinates=np.eye(n),
    )


def saved_system_run(folder: Path, setup: SystemSetup,
                     results: Sequence[SystemResult]) -> SavedRun:
    """The runs of a Part I scenario as a run folder's content: the system's MJCF (or, for
    a system that is only its ODE, :func:`ode_display_model`) and every run's signals."""
    plant = setup.cases[0].plant
    model = plant.load() if isinstance(plant, Plant) else ode_display_model(setup.state_names)
    names = tuple(model.joint(i).name for i in range(model.njnt))
    info = SceneInfo(np.eye(model.nq), default_trace_frame(model), setup.scenario.name, ())
    units = _units(model)
    cases = tuple(
        SavedCase(c.name, tuple(_saved(r, setup, names, units) for r in results
                                if r.case == c.name))
        for c in setup.cases)
    return SavedRun(folder, model, info, cases)
