"""A scenario's ``reference:`` (cpbc.reference): the path checked and built (errors name
``reference.path.…``), the goal at its first sample (the laws are built for it, as for a
``goal:``), the note of a start away from that sample (approached first), and per law the plan the
governor reads (the posture path, its inadmissible stretches and the V normalisation)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path as FilePath

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.geometry import Obstacle
from cpbc.controllers.controller import Controller
from cpbc.errors import ParameterError, ScenarioError
from cpbc.model.robot_model import RobotModel
from cpbc.reference.csv_path import read_csv_path
from cpbc.reference.governor import GovernorSettings
from cpbc.reference.paths import Circle, Lissajous, Path, Scaled, Waypoints
from cpbc.reference.plan import ReferencePlan, plan_reference
from cpbc.reference.tracker import ReferenceTracker, tracking
from cpbc.scenario import schema as s
from cpbc.scenario.goal_build import GoalPlan, goal_of, plan
from cpbc.taskspace.goal import FrameGoal


@dataclass(frozen=True)
class ReferenceSetup:
    """The path, the governor's settings, the feed-forward and each law's plan (by the
    controller's name)."""

    path: Path
    goal: FrameGoal
    settings: Mapping[str, GovernorSettings]
    feedforward: bool
    plans: Mapping[str, ReferencePlan]

    def tracker(self, name: str, law: Controller, run: Controller, period: float,
                phase: float = 0.0, turns: Array | None = None) -> ReferenceTracker:
        """A fresh tracker of the law ``name`` for one run (``run``: the law as the loop runs
        it, possibly inside its safeguard), starting at path time ``phase``; ``turns``: whole
        turns of the continuous joints added to the posture path, for a run whose start is
        wound (cpbc.taskspace.posture)."""
        plan = self.plans[name]
        if turns is not None:
            plan = replace(plan, postures=plan.postures + turns)
        found = tracking(law, period, plan, self.settings[name], self.feedforward, run)
        if phase > 0.0:
            found.start_at(phase)
        return found

    def phase(self, name: str, seed: int) -> float:
        """A path time drawn uniformly outside the law's inadmissible stretches (a
        campaign's reference phase), seeded."""
        plan = self.plans[name]
        rng = np.random.default_rng([seed, 26])
        stretches = plan.postures_path.stretches
        for _ in range(1000):
            s = float(rng.uniform(0.0, plan.path.duration))
            if not any(a - plan.period <= s < b + plan.period for a, b, _ in stretches):
                return s
        return 0.0


def _path(spec: s.PathSpec, scenario_file: FilePath) -> Path:
    field = "reference.path"
    try:
        if spec.waypoints is not None:
            field += ".waypoints"
            w = spec.waypoints
            return Waypoints(np.array([p.time for p in w.points]),
                             np.array([p.position for p in w.points], dtype=float),
                             w.interpolation)
        if spec.circle is not None:
            field += ".circle"
            c = spec.circle
            return Circle(np.asarray(c.centre, float), c.radius, np.asarray(c.normal, float),
                          c.speed, c.laps, c.phase,
                          None if c.start_axis is None else np.asarray(c.start_axis, float))
        if spec.lissajous is not None:
            field += ".lissajous"
            li = spec.lissajous
            return Lissajous(np.asarray(li.centre, float), np.asarray(li.amplitude, float),
                             np.asarray(li.frequency, float), li.period,
                             None if li.phase is None else np.asarray(li.phase, float), li.laps)
        assert spec.csv is not None
        return read_csv_path((scenario_file.parent / spec.csv).resolve())
    except ParameterError as exc:
        name = exc.parameter if exc.parameter.startswith("reference.") else (
            f"{field}.{exc.parameter}")
        raise ScenarioError(name, str(exc)) from None
    except ValueError as exc:  # ragged waypoint positions
        raise ScenarioError(field, f"each waypoint needs 3 coordinates ({exc})") from None


def _as_goal(spec: s.ReferenceSpec, first: Array) -> s.GoalSpec:
    return s.GoalSpec(frame=spec.frame, offset=spec.offset, position=first.tolist(),
                      orientation=spec.orientation, tolerance=spec.tolerance, posture="ik")


def _renamed(exc: ScenarioError) -> ScenarioError:
    return ScenarioError(exc.field.replace("goal.", "reference.", 1), exc.message)


def reference_goal(spec: s.ReferenceSpec, model: RobotModel, scene: Mapping[str, Obstacle],
                   monitor: ConstraintSet, scenario_file: FilePath, starts: list[Array],
                   seeds: list[Array], check: Callable[[Array, str], None],
                   periodic: Array | None = None) -> tuple[Path, GoalPlan]:
    """The path and the goal at its first sample with its IK posture (the laws' build). A
    case may start away from that sample: the law approaches it while the governor paces
    the path by its budget (:func:`approach_notes` says so)."""
    path = _path(spec.path, scenario_file)
    first = path.sample(np.zeros(1))[0][0]
    goal_spec = _as_goal(spec, first)
    try:
        goal = goal_of(goal_spec, model, scene, monitor)
        found = plan(goal_spec, goal, model, monitor, starts[0], seeds, check, periodic)
    except ScenarioError as exc:
        raise _renamed(exc) from None
    return path, found


def approach_notes(goal: FrameGoal, path: Path, model: RobotModel, tolerance: float,
                   cases: Sequence[tuple[str, Array]]) -> list[str]:
    """One line per case (name, start) whose frame starts farther from the path's first
    sample than ``tolerance``: the run approaches that sample first."""
    first = path.sample(np.zeros(1))[0][0]
    notes = []
    for name, x0 in cases:
        gap = float(np.linalg.norm(model.point_position(goal.frame, x0, goal.offset)
                                   - first))
        if gap > tolerance:
            notes.append(
                f"case '{name}': the frame '{goal.frame_name}' starts {gap * 1000:.3g} mm from "
                f"the reference's first sample (tolerance {tolerance * 1000:g} mm): the law "
                "brings it there first, the governor pacing the path by the law's energy "
                "(the path waits while it is above the budget)")
    return notes


def reference_setup(spec: s.ReferenceSpec, path: Path, goal: GoalPlan,
                    laws: Mapping[str, tuple[Controller, s.ControllerSpec]],
                    period: float) -> ReferenceSetup:
    """Each law's governor settings (its own ``on_infeasible`` when given) and plan of its
    path (at its own ``reference_speed``) from the goal's posture."""
    g = spec.governor
    settings = {name: GovernorSettings(g.budget, g.gain, g.catch_up, g.max_speed, g.margin,
                                       c.on_infeasible or g.on_infeasible)
                for name, (_, c) in laws.items()}
    plans = {name: plan_reference(law, goal.goal, path if c.reference_speed is None else
                                  Scaled(path, c.reference_speed), goal.posture,
                                  settings[name], period)
             for name, (law, c) in laws.items()}
    return ReferenceSetup(path, goal.goal, settings, spec.feedforward == "velocity", plans)
