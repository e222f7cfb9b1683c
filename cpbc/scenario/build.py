"""From a validated Scenario to runnable objects: model, plant, constraints, controllers."""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import (
    ConfigurationConstraint,
    ConstraintSet,
    VelocityConstraint,
)
from cpbc.constraints.geometry import Obstacle
from cpbc.controllers.hold import plant_step
from cpbc.controllers.safeguard import SafeguardSettings
from cpbc.errors import ScenarioError
from cpbc.model import RobotModel
from cpbc.model.collision_geoms import mjcf_collision_geoms
from cpbc.model.gravity_load import GravityLoad
from cpbc.reference.paths import Path as RefPath
from cpbc.results.metrics import SettleCriteria
from cpbc.scenario import schema as s
from cpbc.scenario.arm_setup import (
    CaseEntry,
    ControllerEntry,
    ObstacleGeom,
    ScenarioSetup,
    check_disturbances,
    coordinate_names,
    load_robot,
)
from cpbc.scenario.constraint_build import (
    check_distinct,
    energy_under_declared_error,
    scenario_constraints,
    scene_obstacles,
)
from cpbc.scenario.controller_build import build_controllers, check_starts
from cpbc.scenario.goal_build import GoalPlan, goal_of, plan
from cpbc.scenario.loop_setup import loop_settings, undeclared_efforts
from cpbc.scenario.preflight import check_gravity
from cpbc.scenario.reference import reference_goal, reference_setup
from cpbc.scenario.schema.kinds import KINDS, Kinds
from cpbc.scenario.state_checks import (
    check_admissible,
    check_in_range,
    check_stoppable,
    initial_states,
    joint_ranges,
)
from cpbc.simulation import PlantSettings
from cpbc.taskspace.posture import admissible_turns, continuous_mask

__all__ = [
    "CaseEntry",
    "ControllerEntry",
    "ObstacleGeom",
    "ScenarioSetup",
    "build",
    "joint_ranges",
    "undeclared_efforts",
]


def _goal(scenario: s.Scenario, model: RobotModel, scene: dict[str, Obstacle],
          monitor: ConstraintSet, cases: list[CaseEntry], ranges: tuple[Array, Array],
          scenario_file: Path, periodic: Array | None) -> tuple[RefPath | None, GoalPlan] | None:
    """A goal scenario's goal, preflight (from the first case's start, then the middle of the
    joint ranges and four seeded draws in them) and posture (turned on the ``periodic``
    joints to the equivalent nearest that start); a reference scenario's path and the goal at
    its first sample; None for a joint target."""
    if scenario.goal is None and scenario.reference is None:
        return None
    lo, hi = (np.clip(r, -np.pi, np.pi) for r in ranges)
    rng = np.random.default_rng(0)
    seeds = [0.5 * (lo + hi)] + [rng.uniform(lo, hi) for _ in range(4)]

    def check(x: Array, field: str) -> None:
        check_in_range(x, model, ranges, field, "")
        check_admissible(monitor, x, np.zeros(model.n), "goal posture", field)

    if scenario.reference is not None:
        return reference_goal(scenario.reference, model, scene, monitor, scenario_file,
                              [c.position for c in cases], seeds, check, periodic)
    assert scenario.goal is not None
    goal = goal_of(scenario.goal, model, scene, monitor)
    return None, plan(scenario.goal, goal, model, monitor, cases[0].position, seeds, check,
                      periodic)


def _case_targets(target: Array, cases: list[CaseEntry], periodic: Array | None,
                  monitor: ConstraintSet) -> dict[str, Array]:
    """The set point of each case whose start is wound by whole turns of a continuous joint
    away from ``target``: the equivalent nearest its start (cpbc.taskspace.posture)."""
    config = ConstraintSet(len(target), monitor.configuration)
    turned = {c.name: admissible_turns(target, c.position, periodic, config) for c in cases}
    return {name: x for name, x in turned.items() if not np.array_equal(x, target)}


def build(scenario: s.Scenario, scenario_file: Path, kinds: Kinds = KINDS) -> ScenarioSetup:
    """Check a scenario against its robot and build every object it describes, each
    constraint and controller by its kind in ``kinds`` (cpbc.scenario.schema.kinds)."""
    runs = len(scenario.cases) * len(scenario.controllers)
    if runs > s.MAX_RUNS:
        raise ScenarioError("cases", f"{len(scenario.cases)} cases × {len(scenario.controllers)} "
                            f"controllers make {runs} runs, more than the {s.MAX_RUNS} a "
                            "scenario may hold; split it into several scenarios")
    arm, path, model, plant = load_robot(scenario, scenario_file)
    names = coordinate_names(scenario.robot, model)
    sim = scenario.simulation
    loop = loop_settings(sim, model)
    obstacles, scene = scene_obstacles(scenario.obstacles)
    collision = None if arm is not None else partial(mjcf_collision_geoms, plant, model.model)
    built, rate_bounds = scenario_constraints(scenario, model, names, arm, scene, obstacles,
                                              kinds, collision)
    check_distinct(built, [c.name for c in scenario.constraints])
    monitor = ConstraintSet(
        model.n,
        [c for c in built.values() if isinstance(c, ConfigurationConstraint)],
        [c for c in built.values() if isinstance(c, VelocityConstraint)],
    )
    ranges = joint_ranges(model, plant)
    target, cases = initial_states(scenario, model, monitor, ranges)
    periodic = continuous_mask(model, arm.continuous_joints if arm is not None else ())
    planned = _goal(scenario, model, scene, monitor, cases, ranges, scenario_file, periodic)
    ref_path, goal = planned if planned is not None else (None, None)
    if goal is not None:
        target = goal.posture
    if ref_path is not None and sim.backend != "mujoco":
        raise ScenarioError("simulation.backend", "a reference runs in the sampled-data loop "
                            "only (its governor counts control periods): use backend: mujoco")
    case_targets = _case_targets(target, cases, periodic, monitor)
    gravity_on_path: dict[str, GravityLoad] = {}
    outside_v: dict[str, str] = {}
    if loop.bounds.torque is not None:
        for case in cases:
            gravity_on_path.update(check_gravity(model, case_targets.get(case.name, target),
                                                 [(case.name, case.position)],
                                                 loop.bounds.torque))
        outside_v = check_stoppable(cases, monitor, model, loop.bounds.torque,
                                    loop.bounds.period, loop.bounds.rate)
    # a declared inertia error e: the laws keep the model's energy below Ω/(1 + e)
    laws_keep = energy_under_declared_error(built, loop.declared_error)
    controllers = build_controllers(scenario, model, target, cases, laws_keep, names, loop, goal,
                                    kinds)
    case_controllers = {
        c.name: build_controllers(scenario, model, case_targets[c.name], [c], laws_keep, names,
                                  loop, None if goal is None else replace(
                                      goal, posture=case_targets[c.name]), kinds)
        for c in cases if c.name in case_targets}
    check_starts(controllers, scenario.controllers, cases, loop, names, sim.safeguard, kinds)
    for wound in cases:
        if wound.name in case_controllers:
            check_starts(case_controllers[wound.name], scenario.controllers, [wound], loop,
                         names, sim.safeguard, kinds)
    for i, c in enumerate(scenario.controllers):
        for key in ("on_infeasible", "reference_speed"):
            if getattr(c, key) is not None and scenario.reference is None:
                raise ScenarioError(f"controllers[{i}].{key}", "belongs to a reference: give "
                                    "reference: or drop it")
    reference = None
    if ref_path is not None and scenario.reference is not None and goal is not None:
        reference = reference_setup(scenario.reference, ref_path, goal,
                                    {c.name: (c.controller, spec) for c, spec in
                                     zip(controllers, scenario.controllers, strict=True)},
                                    loop.bounds.period)
    setup = ScenarioSetup(
        scenario, path, model, monitor, controllers, cases, target,
        PlantSettings(sim.timestep, sim.integrator),
        loop, SettleCriteria(sim.position_tolerance, sim.velocity_tolerance), rate_bounds,
        obstacles, names, scenario_file, arm,
        safeguard=SafeguardSettings(velocity_cushion=sim.safeguard_velocity_cushion,
                                    hold_correction=sim.safeguard_hold_correction,
                                    rescue_budget=sim.safeguard_rescue_budget,
                                    test_budget=sim.safeguard_test_budget,
                                    time_budget=sim.safeguard_time_budget,
                                    plant_step=plant_step(sim.integrator, sim.timestep))
        if sim.safeguard else None,
        also_keep=monitor.configuration if sim.safeguard and sim.safeguard_monitored else (),
        gravity_on_path=gravity_on_path, outside_braking_set=outside_v, goal=goal,
        reference=reference,
        case_targets=case_targets, case_controllers=case_controllers,
    )
    check_disturbances(scenario, plant, model.n)
    return setup
