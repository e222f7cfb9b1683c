"""The obstacles and constraints of an arm scenario, built against its robot."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import ConfigurationConstraint, RateLimit, VelocityConstraint
from cpbc.constraints.constraint_kind import ConstraintEntrySpec, ConstraintInputs
from cpbc.constraints.geometry import Obstacle
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.linear_limit import JointPositionLimitSpec
from cpbc.controllers.safeguard.model_error import DeclaredError
from cpbc.errors import CpbcError, ScenarioError
from cpbc.model import RobotModel
from cpbc.model.collision_geoms import CollisionGeom
from cpbc.model.loading import LoadedArm
from cpbc.scenario import robots
from cpbc.scenario import schema as s
from cpbc.scenario.arm_setup import ObstacleGeom
from cpbc.scenario.schema.kinds import KINDS, ConstraintKind, Kinds


def _build_constraint(
    spec: ConstraintEntrySpec, kind: ConstraintKind[Any], given: ConstraintInputs,
) -> ConfigurationConstraint | VelocityConstraint:
    """The kind's constraint of an entry; the constraint's own errors name the entry's key
    they come from."""
    try:
        return kind.build(spec, given)
    except ScenarioError:
        raise
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)
        raise ScenarioError(given.at(parameter) if parameter else given.field,
                            str(exc)) from None


def scene_obstacles(specs: list[s.ObstacleSpec]) -> tuple[list[ObstacleGeom], dict[str, Obstacle]]:
    obstacles: list[ObstacleGeom] = []
    scene: dict[str, Obstacle] = {}
    for i, ospec in enumerate(specs):
        if ospec.name in scene:
            raise ScenarioError(f"obstacles[{i}].name", f"duplicate obstacle name '{ospec.name}'")
        ob = scene[ospec.name] = robots.obstacle(ospec, f"obstacles[{i}]")
        geom = ob.scene_geom()
        obstacles.append(ObstacleGeom(ob.name, geom.pos, float(geom.size[0]), ob.collides, geom))
    return obstacles, scene


def joint_range(scenario: s.Scenario, model: RobotModel, names: tuple[str, ...],
                arm: LoadedArm | None) -> tuple[Array, Array] | None:
    """The joint range the scenario keeps: the model's ranges narrowed by every
    ``joint_position_limit`` entry; None unless the arm's velocity limits depend on the
    joints' positions (what the range is for) and the controller's coordinates are the
    model's joints."""
    if arm is None or arm.velocity_limits is None or not model.coordinates.is_identity:
        return None
    lo = np.array(model.model.lowerPositionLimit, dtype=float)
    hi = np.array(model.model.upperPositionLimit, dtype=float)
    for i, cs in enumerate(scenario.constraints):
        if not isinstance(cs, JointPositionLimitSpec):
            continue
        given = ConstraintInputs(model, names, f"constraints[{i}]")
        idx = given.joints(cs.joints)
        chosen = list(range(model.n)) if idx is None else idx
        lo[chosen] = np.maximum(lo[chosen], given.limit(cs.lower, "position", 0, idx, "lower"))
        hi[chosen] = np.minimum(hi[chosen], given.limit(cs.upper, "position", 1, idx, "upper"))
    return lo, hi


def scenario_constraints(
    scenario: s.Scenario, model: RobotModel, names: tuple[str, ...], arm: LoadedArm | None,
    scene: dict[str, Obstacle], obstacles: list[ObstacleGeom], kinds: Kinds = KINDS,
    collision: Callable[[], tuple[CollisionGeom, ...]] | None = None,
) -> tuple[dict[str, ConfigurationConstraint | VelocityConstraint], list[float | None]]:
    """Every scenario constraint by name (built by its kind), and the per-coordinate rate
    bounds (for the table); the spheres the entries place in the scene are appended to
    ``obstacles``. ``collision`` reads an MJCF robot's collision geoms, for covers."""
    built: dict[str, ConfigurationConstraint | VelocityConstraint] = {}
    rate_bounds: list[float | None] = [None] * model.n
    kept = joint_range(scenario, model, names, arm)
    for i, cs in enumerate(scenario.constraints):
        field = f"constraints[{i}]"
        if cs.name in built:
            raise ScenarioError(f"{field}.name", f"duplicate constraint name '{cs.name}'")
        kind = kinds.constraint(cs.type)
        c = built[cs.name] = _build_constraint(
            cs, kind, ConstraintInputs(model, names, field, arm, scene, collision, kept))
        if isinstance(c, RateLimit) and c.joint_index is not None:
            for j, b in zip(c.joint_index, c.bounds, strict=True):
                rate_bounds[int(j)] = float(b)
        if kind.scene is not None:
            sphere = kind.scene(cs, c)
            obstacles.append(ObstacleGeom(sphere.name, sphere.centre, sphere.radius,
                                          sphere.collides))
    return built, rate_bounds


def check_distinct(built: dict[str, ConfigurationConstraint | VelocityConstraint],
                    entries: list[str]) -> None:
    """Refuse two constraint entries that make a row of the same name (two position limits
    on one joint, say): the second would shadow the first in every report."""
    owner: dict[str, tuple[int, str]] = {}
    for entry, c in built.items():
        i = entries.index(entry) if entry in entries else len(entries)
        for row in c.names:
            if row in owner:
                j, first = owner[row]
                raise ScenarioError(
                    f"constraints[{i}]", f"'{entry}' and '{first}' (constraints[{j}]) both "
                    f"make the constraint '{row}'; merge them into one entry or give them "
                    "different joints")
            owner[row] = (i, entry)


def energy_under_declared_error(
    built: dict[str, ConfigurationConstraint | VelocityConstraint],
    declared: DeclaredError | None,
) -> dict[str, ConfigurationConstraint | VelocityConstraint]:
    """The constraints the laws keep under a declared relative inertia error e: each
    kinetic-energy limit Ω lowered to Ω/(1 + e) (same name), since the arm's energy
    ½ẋᵀDẋ ≤ (1 + e) ½ẋᵀD̂ẋ when every link's mass and inertia is within ±e of the model's
    (D − D̂ is a sum of the links' pieces of D̂, each scaled by at most e); the scenario's
    monitor keeps Ω. ``built`` itself without a declared inertia error."""
    if declared is None or not declared.inertia:
        return built
    scale = 1.0 / (1.0 + declared.inertia)
    return {name: KineticEnergyLimit(c.model, c.limit * scale, c.names[0])
            if type(c) is KineticEnergyLimit else c for name, c in built.items()}
