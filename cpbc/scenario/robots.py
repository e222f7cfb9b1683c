"""Scenario support for URDF arms: loading by name or path, model limits, obstacles, clearance.

The scenario builder (cpbc.scenario.build) calls these; every error is a ScenarioError that
names the offending field.
"""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.clearance import Clearance
from cpbc.constraints.cover_cache import cached_cover
from cpbc.constraints.covering import LinkPrimitive
from cpbc.constraints.geometry import (
    BoxObstacle,
    CapsuleObstacle,
    Obstacle,
    PlaneObstacle,
    SceneGeom,
    SphereObstacle,
)
from cpbc.errors import CpbcError, ScenarioError
from cpbc.model.arms import ARMS
from cpbc.model.loading import LoadedArm, load_arm, load_urdf
from cpbc.model.robot_model import RobotModel
from cpbc.scenario import schema as s

GEOM_TYPES = {
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "plane": mujoco.mjtGeom.mjGEOM_PLANE,
}


def xml_root(path: Path) -> str | None:
    """The name of the XML root element of a file (None if it is no readable XML)."""
    try:
        for _, element in ElementTree.iterparse(path, events=("start",)):
            return element.tag
    except (ElementTree.ParseError, OSError):
        return None
    return None


def is_urdf_robot(robot: s.RobotSpec, base: Path | None = None) -> bool:
    """Whether the scenario's robot is an example-robot-data arm or a URDF file (by its
    suffix or, for any other existing file, by its ``<robot>`` root element).

    Raises:
        ScenarioError: the file is xacro source, which needs expanding first.
    """
    if robot.model in ARMS or robot.model.lower().endswith(".urdf"):
        return True
    path = Path(robot.model)
    path = path if path.is_absolute() or base is None else base / path
    if not path.is_file():
        return False
    if path.name.lower().endswith(".xacro"):
        raise ScenarioError("robot.model", f"{robot.model} is xacro source, not a URDF: expand "
                            "it first (xacro FILE > arm.urdf) and give the .urdf")
    return xml_root(path) == "robot"


def load_scenario_arm(robot: s.RobotSpec, base: Path) -> LoadedArm | None:
    """The URDF arm of a scenario, or None when its robot is an MJCF model."""
    if not is_urdf_robot(robot, base):
        if robot.locked_joints:
            raise ScenarioError(
                "robot.locked_joints", "locking joints needs a URDF robot (a name or .urdf path)"
            )
        return None
    dirs = [p if Path(p).is_absolute() else base / p for p in robot.package_dirs]
    try:
        if robot.model in ARMS:
            return load_arm(robot.model, robot.locked_joints, dirs)
        path = Path(robot.model)
        return load_urdf(path if path.is_absolute() else base / path, robot.locked_joints,
                         package_dirs=dirs)
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)
        raise ScenarioError(f"robot.{parameter or 'model'}", str(exc)) from None


def model_limits(
    model: RobotModel, kind: str, field: str, joints: list[int] | None = None
) -> tuple[Array, Array]:
    """Limits the robot's model declares: ``position`` (lower, upper), ``velocity`` or
    ``effort`` (−limit, limit), in joint coordinates, of every joint (or of ``joints``).
    ScenarioError if one of them has none or the controller does not use joint
    coordinates."""
    if not model.coordinates.is_identity:
        raise ScenarioError(field, "'from_model' limits need robot.coordinates: joint")
    pm = model.model
    if kind == "position":
        lo = np.array(pm.lowerPositionLimit, dtype=float)
        hi = np.array(pm.upperPositionLimit, dtype=float)
    else:
        hi = np.array(pm.velocityLimit if kind == "velocity" else pm.effortLimit, dtype=float)
        lo = -hi
    chosen = range(model.n) if joints is None else joints
    bad = [model.joint_names[i] for i in chosen
           if not (np.isfinite(lo[i]) and np.isfinite(hi[i]) and lo[i] < hi[i])]
    if bad:
        others = [model.joint_names[i] for i in chosen if model.joint_names[i] not in bad]
        hint = f", or list only the joints that have one ('joints': {others})" if others else ""
        raise ScenarioError(field, f"the model has no {kind} limit for joints {bad} "
                            f"(continuous or undeclared): give values{hint}")
    return lo, hi


def _vec(values: object) -> Array:
    """A list of numbers from the scenario as a float array."""
    return np.asarray(values, dtype=float)


def obstacle(spec: s.ObstacleSpec, field: str) -> Obstacle:
    """An obstacle from its scenario entry."""
    try:
        if isinstance(spec, s.SphereObstacleSpec):
            return SphereObstacle(spec.name, _vec(spec.centre), spec.radius, spec.collides)
        if isinstance(spec, s.CapsuleObstacleSpec):
            return CapsuleObstacle(spec.name, _vec(spec.start), _vec(spec.end), spec.radius,
                                   spec.collides, kind=spec.type)
        if isinstance(spec, s.BoxObstacleSpec):
            return BoxObstacle(spec.name, _vec(spec.centre), _vec(spec.half_extents),
                               _vec(spec.rpy), spec.collides)
        return PlaneObstacle(spec.name, _vec(spec.point), _vec(spec.normal), spec.collides)
    except CpbcError as exc:
        raise ScenarioError(field, str(exc)) from None


def add_scene_geom(
    spec: mujoco.MjSpec, name: str, geom: SceneGeom, collides: bool, colour: list[float]
) -> None:
    """Place an obstacle in a MuJoCo scene (colliding with the robot if ``collides``)."""
    g = spec.worldbody.add_geom()
    g.name = name
    g.type = GEOM_TYPES[geom.kind]
    size = np.zeros(3)
    size[: len(geom.size)] = geom.size
    if geom.kind == "plane":
        size = np.array([3.0, 3.0, 0.05])  # drawn extent; the plane itself is infinite
    g.size = size.tolist()
    g.pos = np.asarray(geom.pos, dtype=float).tolist()
    g.quat = np.asarray(geom.quat, dtype=float).tolist()
    g.rgba = colour
    g.contype = 1 if collides else 0
    g.conaffinity = 1 if collides else 0


def _primitives(spec: s.ClearanceSpec, arm: LoadedArm | None, model: RobotModel,
                field: str) -> list[LinkPrimitive]:
    declared = []
    per_link: dict[str, int] = {}
    for p in spec.primitives or []:
        per_link[p.link] = per_link.get(p.link, 0) + 1
    for i, p in enumerate(spec.primitives or []):
        f = f"{field}.primitives[{i}]"
        if p.link not in {fr.name for fr in model.model.frames}:
            frames = [fr.name for fr in model.model.frames if fr.parentJoint > 0]
            raise ScenarioError(f"{f}.link", f"the robot has no link '{p.link}'; links: {frames}")
        start = p.centre if p.centre is not None else p.start
        end = p.centre if p.centre is not None else p.end
        if start is None or end is None:
            raise ScenarioError(f, "give 'centre' (a sphere) or 'start' and 'end' (a capsule)")
        try:
            label = p.name or (p.link if per_link[p.link] == 1 else f"{p.link}#{i}")
            declared.append(LinkPrimitive(label, p.link, _vec(start), _vec(end), p.radius))
        except CpbcError as exc:
            raise ScenarioError(f, str(exc)) from None
    if spec.links == [] or (spec.links is None and spec.primitives and arm is None):
        return declared
    if arm is None:
        raise ScenarioError(f"{field}.links", "automatic covers need a URDF robot with "
                            "collision meshes; declare 'primitives' for an MJCF robot")
    links = spec.links
    taken = {p.frame for p in declared}
    try:
        auto = cached_cover(arm.model, arm.collision_model, links, spec.padding, spec.cover,
                           spec.cover_tolerance)
    except CpbcError as exc:
        raise ScenarioError(f"{field}.links", str(exc)) from None
    return declared + [p for p in auto if p.frame not in taken]


def clearance(
    spec: s.ClearanceSpec,
    model: RobotModel,
    arm: LoadedArm | None,
    obstacles: dict[str, Obstacle],
    field: str,
) -> Clearance:
    """The clearance constraint of a scenario entry."""
    names = list(obstacles) if spec.obstacles is None else spec.obstacles
    unknown = [o for o in names if o not in obstacles]
    if unknown:
        raise ScenarioError(f"{field}.obstacles",
                            f"unknown obstacles {unknown}; the scenario has {list(obstacles)}")
    prims = _primitives(spec, arm, model, field)
    covered = sorted({p.frame for p in prims})
    for i, (a, b) in enumerate(spec.self_collision):
        missing = [f for f in (a, b) if f not in covered]
        if missing or a == b:
            why = (f"no primitive on link '{missing[0]}'; links with primitives: {covered}"
                   if missing else "names one link twice")
            raise ScenarioError(f"{field}.self_collision[{i}]", f"pair ({a}, {b}): {why}")
    try:
        return Clearance(model, prims, [obstacles[o] for o in names], spec.margin,
                         spec.influence, [(p[0], p[1]) for p in spec.self_collision],
                         spec.name)
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)
        raise ScenarioError(f"{field}.{parameter}" if parameter else field, str(exc)) from None
