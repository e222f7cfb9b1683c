"""The set-up a scenario builds into (ScenarioSetup and its entries), and the robot
it runs: the model file, coordinates, the controller's model and the MuJoCo plant."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.constraints import (
    ConfigurationConstraint,
    ConstraintSet,
)
from cpbc.constraints.geometry import SceneGeom
from cpbc.controllers import Controller
from cpbc.controllers.safeguard import SafeguardSettings, guarded
from cpbc.errors import CpbcError, ScenarioError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.actuators import apply_actuator_efforts
from cpbc.model.arms import ARMS
from cpbc.model.collision_geoms import obstacle_contacts_only
from cpbc.model.gravity_load import GravityLoad
from cpbc.model.joint_dynamics import JointDynamics
from cpbc.model.loading import LoadedArm, finish_mujoco_model
from cpbc.model.mjcf_arm import check_mjcf_arm
from cpbc.resources import builtin_models
from cpbc.results.metrics import SettleCriteria
from cpbc.scenario import robots
from cpbc.scenario import schema as s
from cpbc.scenario.goal_build import GoalPlan
from cpbc.scenario.joint_dynamics_setup import friction_spec, joint_dynamics
from cpbc.scenario.reference import ReferenceSetup
from cpbc.simulation import LoopSettings, MujocoPlant, PlantSettings
from cpbc.simulation.disturbances import PlantMismatch


@dataclass(frozen=True)
class ControllerEntry:
    """A scenario's law by name; ``friction_compensation``: the width ε_c [rad] of the
    potential that beats the joints' Coulomb friction, when the law has it
    (cpbc.controllers.potentials.friction), else None."""

    name: str
    controller: Controller
    friction_compensation: float | None = None


@dataclass(frozen=True)
class CaseEntry:
    name: str
    position: Array
    velocity: Array


@dataclass(frozen=True)
class ObstacleGeom:
    """An obstacle placed in the MuJoCo scene (and drawn by the viewer): a sphere of
    ``radius`` at ``centre``, or ``geom`` (a capsule, cylinder, box or plane)."""

    name: str
    centre: Array
    radius: float
    collides: bool
    geom: SceneGeom | None = None


@dataclass
class ScenarioSetup:
    """Everything needed to run a scenario; each layer stays usable on its own."""

    scenario: s.Scenario
    model_path: Path
    model: RobotModel
    monitor: ConstraintSet
    controllers: list[ControllerEntry]
    cases: list[CaseEntry]
    target: Array
    plant_settings: PlantSettings
    loop_settings: LoopSettings
    criteria: SettleCriteria
    rate_bounds: list[float | None]
    obstacles: list[ObstacleGeom]
    coordinate_names: tuple[str, ...]
    source: Path  # the scenario file, so worker processes can rebuild the setup
    arm: LoadedArm | None = None  # a URDF robot (None for an MJCF model)
    # the sampled-data safeguard around every constrained law (None: the bare laws), and the
    # configuration constraints it keeps besides each law's own (the monitored ones)
    safeguard: SafeguardSettings | None = None
    also_keep: tuple[ConfigurationConstraint, ...] = ()
    # per case, the load on its path to the target that leaves a motor no room to brake
    # over gravity (cpbc.scenario.preflight): a warning before the run, a cause after it
    gravity_on_path: dict[str, GravityLoad] = dataclasses.field(default_factory=dict)
    # per case that starts outside the safeguard's braking set V although a rescue brake
    # stops it (cpbc.scenario.state_checks.check_stoppable): a note before the run
    outside_braking_set: dict[str, str] = dataclasses.field(default_factory=dict)
    # a goal scenario's goal, preflight and posture (``target`` is then the posture x_n)
    goal: GoalPlan | None = None
    # a reference scenario's path, governor and plans (``goal`` is then its first sample)
    reference: ReferenceSetup | None = None
    # per case whose start is wound by whole turns of a continuous joint away from ``target``:
    # its set point (the equivalent nearest its start, cpbc.taskspace.posture) and the laws
    # built for it; the other cases run the laws of ``controllers``
    case_targets: dict[str, Array] = dataclasses.field(default_factory=dict)
    case_controllers: dict[str, list[ControllerEntry]] = dataclasses.field(
        default_factory=dict)

    @property
    def joint_dynamics(self) -> JointDynamics:
        """The joints' rotor inertia and friction, in the controller's model and the plant
        alike (``robot.armature``, ``robot.friction``)."""
        return model_joint_dynamics(self.model)

    def for_case(self, case: CaseEntry, entry: ControllerEntry) -> ControllerEntry:
        """The entry's law for a case: built for the case's own set point when its start is
        wound (``case_targets``), else the entry itself."""
        laws = self.case_controllers.get(case.name)
        if laws is None:
            return entry
        return next(e for e in laws if e.name == entry.name)

    def controller(self, entry: ControllerEntry, case: CaseEntry | None = None) -> Controller:
        """The entry's law as the scenario runs it in the sampled-data loop: wrapped in the
        safeguard at the loop's control period and torque limit, when it has one; with a
        reference, inside a fresh tracker (cpbc.reference.tracker) for one run. With a
        ``case``, the law of ``for_case`` (and its posture path turned likewise)."""
        if case is not None:
            entry = self.for_case(case, entry)
        loop = self.loop_settings
        run = guarded(entry.controller, loop.bounds, self.safeguard, self.also_keep,
                      loop.model_error, loop.declared_error)
        if self.reference is None:
            return run
        turned = None if case is None else self.case_targets.get(case.name)
        return self.reference.tracker(entry.name, entry.controller, run, loop.bounds.period,
                                      turns=None if turned is None else turned - self.target)

    def make_plant(self) -> MujocoPlant:
        """A fresh MuJoCo plant of the scenario's robot with its obstacles in the scene."""
        if self.arm is not None:
            spec = self.arm.mujoco_spec()
        else:
            spec = mujoco.MjSpec.from_file(str(self.model_path))
        for ob in self.obstacles:
            if ob.geom is not None:
                robots.add_scene_geom(spec, ob.name, ob.geom, ob.collides,
                                      [0.85, 0.25, 0.2, 0.5])
                continue
            g = spec.worldbody.add_geom()
            g.name = ob.name
            g.type = mujoco.mjtGeom.mjGEOM_SPHERE
            g.size = [ob.radius, 0.0, 0.0]
            g.pos = ob.centre.tolist()
            g.rgba = [0.85, 0.25, 0.2, 0.5]
            g.contype = 1 if ob.collides else 0
            g.conaffinity = 1 if ob.collides else 0
        model = spec.compile()
        if self.arm is not None:
            finish_mujoco_model(model, self.arm.joint_names)
        else:
            obstacle_contacts_only(model)
        self.joint_dynamics.on_mujoco(model)  # what the controller's model has
        mismatch = _mismatch(self.scenario.robot.plant)
        if mismatch is not None:
            mismatch.apply(model)  # the plant only: the controller's model stays nominal
        return MujocoPlant(model, self.plant_settings)

    def make_reference_plant(self) -> RobotModel:
        """A Pinocchio model of the plant, separate from the controller's model."""
        return _robot_model(self.model_path, self.scenario.robot, self.arm)


def _mismatch(spec: s.PlantMismatchSpec | None) -> PlantMismatch | None:
    if spec is None:
        return None

    def value(v: float | list[float]) -> float | tuple[float, ...]:
        return tuple(v) if isinstance(v, list) else v

    return PlantMismatch(
        value(spec.mass_scale), value(spec.inertia_scale), value(spec.damping),
        value(spec.armature), value(spec.frictionloss),
    )


def _per_entry(value: float | list[float], k: int, field: str, what: str) -> None:
    """A number, or a list of k entries (one per ``what``)."""
    if isinstance(value, list) and len(value) != k:
        raise ScenarioError(field, f"needs 1 or {k} entries (one per {what}), got {len(value)}")


def check_disturbances(scenario: s.Scenario, plant: mujoco.MjModel, n: int) -> None:
    """Sizes of the plant overrides and of the noise, against the compiled models."""
    mismatch = scenario.robot.plant
    if mismatch is not None:
        for key in ("mass_scale", "inertia_scale"):
            _per_entry(getattr(mismatch, key), plant.nbody - 1, f"robot.plant.{key}",
                       "body below the world")
        for key in ("damping", "armature", "frictionloss"):
            _per_entry(getattr(mismatch, key), plant.nv, f"robot.plant.{key}", "joint")
    noise = scenario.simulation.noise
    if noise is not None:
        for key in ("position", "velocity"):
            _per_entry(getattr(noise, key), n, f"simulation.noise.{key}", "coordinate")


def _model_path(robot: s.RobotSpec, base: Path) -> Path:
    models = builtin_models()
    if robot.model in models:
        return models[robot.model]
    p = Path(robot.model)
    p = p if p.is_absolute() else (base / p)
    if p.is_file():
        return p
    raise ScenarioError(
        "robot.model",
        f"'{robot.model}' is neither a built-in robot ({', '.join(models)}), an "
        f"example-robot-data arm ({', '.join(sorted(ARMS))}) nor an existing model file "
        f"(looked for {p})",
    )


def _coordinates(robot: s.RobotSpec, n: int) -> LinearCoordinates:
    try:
        if robot.coordinates == "joint":
            return LinearCoordinates.identity(n)
        if robot.coordinates == "absolute":
            return LinearCoordinates.absolute_link_angles(n)
        return LinearCoordinates(np.array(robot.coordinates, dtype=float))
    except (CpbcError, ValueError) as exc:
        raise ScenarioError("robot.coordinates", str(exc)) from None


def _robot_model(
    path: Path, robot: s.RobotSpec, arm: LoadedArm | None = None,
    plant: mujoco.MjModel | None = None,
) -> RobotModel:
    if arm is not None:  # a copy: the reference plant must not share the controller's model
        probe = RobotModel(pin.Model(arm.model), name=arm.name)
    else:
        probe = RobotModel.from_mjcf(path)
        if plant is not None:  # an MJCF declares its efforts on its actuators
            apply_actuator_efforts(probe.model, plant)
    coords = _coordinates(robot, probe.n)
    joints = joint_dynamics(robot, probe.model, None if arm is None else arm.urdf_text,
                            None if arm is None else arm.declared_dynamics)
    rates = None if arm is None else arm.torque_rate_limits
    return RobotModel(joints.on_pinocchio(probe.model), coords, joints.viscous,
                      name=probe.name, coulomb_friction=joints.coulomb,
                      friction_smoothing=friction_spec(robot).smoothing,
                      torque_rate_limits=rates)


def model_joint_dynamics(model: RobotModel) -> JointDynamics:
    """The rotor inertia and the joints' friction of a controller's model (joint
    coordinates): its Pinocchio model's armature, F_d's diagonal and F_c."""
    t = model.coordinates.matrix
    return JointDynamics(model.armature, np.diag(t.T @ model.viscous_friction @ t).copy(),
                         model.coulomb_friction)


def coordinate_names(robot: s.RobotSpec, model: RobotModel) -> tuple[str, ...]:
    if robot.coordinates == "joint":
        return model.joint_names
    if robot.coordinates == "absolute":
        return tuple(f"theta{i + 1}" for i in range(model.n))
    return tuple(f"x{i + 1}" for i in range(model.n))


def load_robot(scenario: s.Scenario, scenario_file: Path) -> tuple[
        LoadedArm | None, Path, RobotModel, mujoco.MjModel]:
    """The arm, its file, the controller's model and the plant's MuJoCo model — compiled
    here, so that what only MuJoCo refuses (unreadable meshes, unphysical inertias) is bad
    input now rather than a traceback in a worker."""
    arm = robots.load_scenario_arm(scenario.robot, scenario_file.parent)
    path = arm.urdf_path if arm is not None else _model_path(scenario.robot, scenario_file.parent)
    try:
        if arm is None and path.is_file():  # MuJoCo first: it tells why Pinocchio sees no arm
            check_mjcf_arm(path, mujoco.MjModel.from_xml_path(str(path)))
        plant = (arm.mujoco_model() if arm is not None
                 else mujoco.MjModel.from_xml_path(str(path)))
        model = _robot_model(path, scenario.robot, arm=arm, plant=plant)
    except ScenarioError:
        raise
    except (CpbcError, ValueError) as exc:
        raise ScenarioError("robot.model", str(exc)) from None
    return arm, path, model, plant
