"""The obstacles and constraints of an arm scenario, built against its robot."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints import (
    ConfigurationConstraint,
    KineticEnergyLimit,
    LinearLimit,
    PointOutsideSphere,
    RateLimit,
    VelocityConstraint,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.constraints.geometry import Obstacle
from cpbc.errors import CpbcError, ScenarioError
from cpbc.model import RobotModel
from cpbc.model.loading import LoadedArm
from cpbc.scenario import robots
from cpbc.scenario import schema as s
from cpbc.scenario.arm_setup import ObstacleGeom, vector


def _indices(joints: list[str] | None, names: tuple[str, ...], field: str) -> list[int] | None:
    if joints is None:
        return None
    missing = [j for j in joints if j not in names]
    if missing:
        raise ScenarioError(field, f"unknown coordinates {missing}; the robot has {list(names)}")
    return [names.index(j) for j in joints]


def _rows(coefficients: list[list[float]], n: int, field: str) -> Array:
    rows = np.asarray(coefficients, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != n:
        raise ScenarioError(field, f"needs rows of {n} coefficients, got shape {rows.shape}")
    return rows


def _limit(
    value: list[float] | str, model: RobotModel, kind: str, side: int, idx: list[int] | None,
    k: int, field: str,
) -> Array:
    """A limit vector as given, or ``from_model`` (side 0 lower, 1 upper) on joints idx."""
    if isinstance(value, str):
        limits = robots.model_limits(model, kind, field, idx)[side]
        return limits if idx is None else limits[idx]
    return vector(value, k, field)


def _build_constraint(
    spec: s.ConstraintSpec,
    model: RobotModel,
    names: tuple[str, ...],
    field: str,
    arm: LoadedArm | None = None,
    obstacles: dict[str, Obstacle] | None = None,
) -> ConfigurationConstraint | VelocityConstraint:
    n = model.n
    if isinstance(spec, s.JointPositionLimitSpec):
        idx = _indices(spec.joints, names, f"{field}.joints")
        k = n if idx is None else len(idx)
        c = joint_position_limit(
            _limit(spec.lower, model, "position", 0, idx, k, f"{field}.lower"),
            _limit(spec.upper, model, "position", 1, idx, k, f"{field}.upper"),
            names,
            idx,
        )
        return c
    if isinstance(spec, s.ClearanceSpec):
        return robots.clearance(spec, model, arm, obstacles or {}, field)
    if isinstance(spec, s.LinearLimitSpec):
        rows = _rows(spec.coefficients, n, f"{field}.coefficients")
        k = rows.shape[0]
        labels = [spec.name] if k == 1 else [f"{spec.name}[{i}]" for i in range(k)]
        return LinearLimit(
            rows,
            vector(spec.lower, k, f"{field}.lower"),
            vector(spec.upper, k, f"{field}.upper"),
            labels,
        )
    if isinstance(spec, s.PointOutsideSphereSpec):
        centre = np.zeros(3)
        if len(spec.centre) not in (2, 3):
            raise ScenarioError(f"{field}.centre", "needs 2 (planar) or 3 coordinates")
        centre[: len(spec.centre)] = spec.centre
        offset = None if spec.offset is None else vector(spec.offset, 3, f"{field}.offset")
        return PointOutsideSphere(model, spec.frame, centre, spec.radius, offset, spec.name)
    if isinstance(spec, s.JointRateLimitSpec):
        idx = _indices(spec.joints, names, f"{field}.joints")
        k = n if idx is None else len(idx)
        bounds = _limit(spec.bounds, model, "velocity", 1, idx, k, f"{field}.bounds")
        return joint_rate_limit(spec.scale * bounds, names, idx)
    if isinstance(spec, s.RateLimitSpec):
        rows = _rows(spec.coefficients, n, f"{field}.coefficients")
        k = rows.shape[0]
        labels = [spec.name] if k == 1 else [f"{spec.name}[{i}]" for i in range(k)]
        return RateLimit(rows, vector(spec.bounds, k, f"{field}.bounds"), labels)
    if isinstance(spec, s.KineticEnergyLimitSpec):
        return KineticEnergyLimit(model, spec.limit, spec.name)
    raise ScenarioError(field, f"unsupported constraint type {spec.type}")  # pragma: no cover


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


def scenario_constraints(
    scenario: s.Scenario, model: RobotModel, names: tuple[str, ...], arm: LoadedArm | None,
    scene: dict[str, Obstacle], obstacles: list[ObstacleGeom],
) -> tuple[dict[str, ConfigurationConstraint | VelocityConstraint], list[float | None]]:
    """Every scenario constraint by name, and the per-coordinate rate bounds (for the table);
    point obstacles are appended to ``obstacles``."""
    built: dict[str, ConfigurationConstraint | VelocityConstraint] = {}
    rate_bounds: list[float | None] = [None] * model.n
    for i, cs in enumerate(scenario.constraints):
        field = f"constraints[{i}]"
        if cs.name in built:
            raise ScenarioError(f"{field}.name", f"duplicate constraint name '{cs.name}'")
        try:
            c = built[cs.name] = _build_constraint(cs, model, names, field, arm, scene)
        except ScenarioError:
            raise
        except CpbcError as exc:
            parameter = getattr(exc, "parameter", None)
            raise ScenarioError(f"{field}.{parameter}" if parameter else field,
                                str(exc)) from None
        if isinstance(c, RateLimit) and c.joint_index is not None:
            for j, b in zip(c.joint_index, c.bounds, strict=True):
                rate_bounds[int(j)] = float(b)
        if isinstance(cs, s.PointOutsideSphereSpec):
            obstacles.append(
                ObstacleGeom(cs.name, c.centre, cs.radius, cs.collides)  # type: ignore[union-attr]
            )
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
