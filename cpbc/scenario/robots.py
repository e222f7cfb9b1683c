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
from cpbc.model.urdf_text import package_dir
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


def package_entry(entry: str, base: Path) -> str:
    """An entry of ``robot.package_dirs`` (a folder, or NAME=FOLDER) with its folder taken
    relative to ``base`` (the scenario's folder) unless absolute."""
    name, folder = package_dir(entry)
    path = folder if folder.is_absolute() else base / folder
    return str(path) if name is None else f"{name}={path}"


def load_scenario_arm(robot: s.RobotSpec, base: Path) -> LoadedArm | None:
    """The URDF arm of a scenario, or None when its robot is an MJCF model."""
    if not is_urdf_robot(robot, base):
        if robot.locked_joints:
            raise ScenarioError(
                "robot.locked_joints", "locking joints needs a URDF robot (a name or .urdf path)"
            )
        return None
    dirs = [package_entry(p, base) for p in robot.package_dirs]
    try:
        if robot.model in ARMS:
            return load_arm(robot.model, robot.locked_joints, dirs)
        path = Path(robot.model)
        return load_urdf(path if path.is_absolute() else base / path, robot.locked_joints,
                         package_dirs=dirs)
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)
        raise ScenarioError(f"robot.{parameter or 'model'}", str(exc)) from None


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
