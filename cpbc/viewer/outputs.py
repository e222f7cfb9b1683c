"""What an arm's scenario run leaves besides its data: the scene files, the figures,
``view.html`` (a Part I system's: cpbc.viewer.system_outputs)."""

from __future__ import annotations

from concurrent.futures import Executor
from pathlib import Path

import mujoco

from cpbc.results.drawing import draw, figure_weight, share_out
from cpbc.results.margin_types import types_of
from cpbc.results.saved_run import (
    FIGURES,
    SceneInfo,
    load_run,
    write_scene,
)
from cpbc.results.sweep import SceneKinematics, default_trace_frame
from cpbc.scenario.build import ScenarioSetup
from cpbc.taskspace.goal import AxisGoal
from cpbc.viewer.export import write_view
from cpbc.viewer.goal_marker import goal_entry
from cpbc.viewer.reference_marker import reference_entry
from cpbc.viewer.scene import ViewSettings


def trace_frame(setup: ScenarioSetup, model: mujoco.MjModel) -> str:
    """The frame whose path is drawn: the first constrained point's frame (the thesis's
    end point, carried by an obstacle constraint) when the MuJoCo model has a site or body
    of that name, else :func:`default_trace_frame`."""
    for spec in setup.scenario.constraints:
        frame = getattr(spec, "frame", None)
        if isinstance(frame, str) and (
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame) >= 0
            or mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame) >= 0
        ):
            return frame
    return default_trace_frame(model)


def scene_info(setup: ScenarioSetup, model: mujoco.MjModel) -> SceneInfo:
    """Coordinates, traced frame and obstacle geoms of a scenario's scene."""
    obstacles = tuple(ob.name for ob in getattr(setup, "obstacles", ()))
    goal = None
    plan = getattr(setup, "goal", None)
    if plan is not None:
        rot = plan.goal.rotation
        goal = goal_entry(plan.goal.position, None if isinstance(rot, AxisGoal) else rot,
                          rot.world if isinstance(rot, AxisGoal) else None)
    ref = getattr(setup, "reference", None)
    drawn = None
    if ref is not None:
        plans = list(ref.plans.values())
        stretches = [st for p in plans for st in p.postures_path.stretches]
        drawn = reference_entry(plans[0].path if plans else ref.path, stretches)
    return SceneInfo(
        setup.model.coordinates.matrix, trace_frame(setup, model), setup.scenario.name, obstacles,
        goal, drawn,
    )


def scene_kinematics(setup: ScenarioSetup) -> SceneKinematics:
    """Kinematics of the scenario's scene (the plant's model, with its obstacles)."""
    model = setup.make_plant().model
    return scene_info(setup, model).kinematics(model)


#: Share of a run's figure work a helper process does while this one writes the page (it
#: draws the rest after): so both end at about the same time.
HELPER_SHARE = 0.65


def write_run_outputs(
    folder: Path,
    setup: ScenarioSetup,
    plots: bool = True,
    settings: ViewSettings | None = None,
    pool: Executor | None = None,
    figures_only: bool = False,
) -> list[Path]:
    """Into a run folder that already holds its trajectories and summary.json: the scene
    (scene.mjb.gz, scene.json), every case's figures (unless ``plots`` is False) and view.html.

    Helper processes of ``pool`` draw the figures while this process writes the page: all of
    them when they are the :func:`~cpbc.results.drawing.figure_helper`'s (``figures_only``,
    matplotlib loaded there while this process simulated), most of them when it is a spawned
    worker, this process drawing the rest.

    Returns:
        The figures and pages written.
    """
    model = setup.make_plant().model
    write_scene(folder, model, scene_info(setup, model))
    if not plots:
        return [write_view(load_run(folder), settings=settings)]
    if pool is None:
        return [*draw(folder), write_view(load_run(folder), settings=settings)]
    jobs = [(case.name, name) for case in setup.cases for name in FIGURES]
    types = len(set(types_of(setup.monitor, setup.model.length_coordinates)))
    weights = [figure_weight(name, setup.model.n, types) for _, name in jobs]
    if figures_only:  # the warm figure helpers draw them all, half the work each
        halves = [pool.submit(draw, folder, part)
                  for part in share_out(jobs, weights, (0.5, 0.5))]
        page = write_view(load_run(folder), settings=settings)
        return [*halves[0].result(), *halves[1].result(), page]
    # one spawned worker draws most of them
    theirs, ours = share_out(jobs, weights, (HELPER_SHARE, 1.0 - HELPER_SHARE))
    future = pool.submit(draw, folder, theirs)
    page = write_view(load_run(folder), settings=settings)
    return [*future.result(), *draw(folder, ours), page]
