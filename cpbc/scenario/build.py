"""From a validated Scenario to runnable objects: model, plant, constraints, controllers."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.constraints import (
    ConfigurationConstraint,
    ConstraintSet,
    KineticEnergyLimit,
    LinearLimit,
    PointOutsideSphere,
    RateLimit,
    VelocityConstraint,
    joint_position_limit,
    joint_rate_limit,
)
from cpbc.constraints.geometry import Obstacle, SceneGeom
from cpbc.constraints.stopping import Braking, stopping_margins
from cpbc.controllers import CONTROLLERS, Controller, Identity, Power, RecentredBarrier, Tanh
from cpbc.controllers.hold import ONE_STAGE
from cpbc.controllers.safeguard import SafeguardSettings, guarded
from cpbc.controllers.shaping import Shaping
from cpbc.errors import CpbcError, InadmissibleStateError, ScenarioError
from cpbc.model import LinearCoordinates, RobotModel
from cpbc.model.arms import ARMS
from cpbc.model.bounds import ModelBounds, estimate_bounds
from cpbc.model.gravity_load import GravityLoad
from cpbc.model.loading import LoadedArm, finish_mujoco_model
from cpbc.reference.paths import Path as RefPath
from cpbc.resources import builtin_models
from cpbc.results.metrics import SettleCriteria
from cpbc.scenario import robots
from cpbc.scenario import schema as s
from cpbc.scenario.gains import physical_gains, unstable_loop
from cpbc.scenario.goal import GoalPlan, goal_of, law_terms, linear_gains, plan
from cpbc.scenario.preflight import check_gravity
from cpbc.scenario.reference import ReferenceSetup, reference_goal, reference_setup
from cpbc.simulation import LoopSettings, MujocoPlant, PlantSettings, substeps_per_control
from cpbc.simulation.disturbances import MeasurementNoise, PlantMismatch


@dataclass(frozen=True)
class ControllerEntry:
    name: str
    controller: Controller


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
    # a goal scenario's goal, preflight and posture (``target`` is then the posture x_n)
    goal: GoalPlan | None = None
    # a reference scenario's path, governor and plans (``goal`` is then its first sample)
    reference: ReferenceSetup | None = None

    def controller(self, entry: ControllerEntry) -> Controller:
        """The entry's law as the scenario runs it in the sampled-data loop: wrapped in the
        safeguard at the loop's control period and torque limit, when it has one; with a
        reference, inside a fresh tracker (cpbc.reference.tracker) for one run."""
        loop = self.loop_settings
        run = guarded(entry.controller, loop.control_period, self.safeguard,
                      loop.torque_limit, self.also_keep)
        if self.reference is None:
            return run
        return self.reference.tracker(entry.name, entry.controller, run, loop.control_period)

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
        if self.model.viscous_friction.any():
            fd = np.diag(
                self.model.coordinates.matrix.T
                @ self.model.viscous_friction
                @ self.model.coordinates.matrix
            )
            model.dof_damping[:] = fd
        mismatch = _mismatch(self.scenario.robot.plant)
        if mismatch is not None:
            mismatch.apply(model)  # the plant only: the controller's model stays nominal
        return MujocoPlant(model, self.plant_settings)

    def make_reference_plant(self) -> RobotModel:
        """A Pinocchio model of the plant, separate from the controller's model."""
        return _robot_model(self.model_path, self.scenario.robot, self.model.n, self.arm)


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


def _check_disturbances(scenario: s.Scenario, plant: mujoco.MjModel, n: int) -> None:
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
    path: Path, robot: s.RobotSpec, n_expected: int | None = None, arm: LoadedArm | None = None
) -> RobotModel:
    if arm is not None:  # a copy: the reference plant must not share the controller's model
        probe = RobotModel(pin.Model(arm.model), name=arm.name)
    else:
        probe = RobotModel.from_mjcf(path)
    coords = _coordinates(robot, probe.n)
    fd = np.asarray(robot.viscous_friction, dtype=float)
    if fd.ndim == 0:
        fd = np.full(probe.n, float(fd))
    if fd.shape != (probe.n,):
        raise ScenarioError(
            "robot.viscous_friction", f"needs 1 or {probe.n} entries, got {fd.size}"
        )
    return RobotModel(probe.model, coords, fd, name=probe.name)


def _vector(value: list[float] | None, n: int, field: str, default: float | None = None) -> Array:
    if value is None and default is not None:
        return np.full(n, default)
    a = np.asarray(value, dtype=float)
    if a.shape != (n,):
        raise ScenarioError(field, f"needs {n} entries (one per coordinate), got {a.size}")
    return a


def _coordinate_names(robot: s.RobotSpec, model: RobotModel) -> tuple[str, ...]:
    if robot.coordinates == "joint":
        return model.joint_names
    if robot.coordinates == "absolute":
        return tuple(f"theta{i + 1}" for i in range(model.n))
    return tuple(f"x{i + 1}" for i in range(model.n))


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
    return _vector(value, k, field)


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
            _vector(spec.lower, k, f"{field}.lower"),
            _vector(spec.upper, k, f"{field}.upper"),
            labels,
        )
    if isinstance(spec, s.PointOutsideSphereSpec):
        centre = np.zeros(3)
        if len(spec.centre) not in (2, 3):
            raise ScenarioError(f"{field}.centre", "needs 2 (planar) or 3 coordinates")
        centre[: len(spec.centre)] = spec.centre
        offset = None if spec.offset is None else _vector(spec.offset, 3, f"{field}.offset")
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
        return RateLimit(rows, _vector(spec.bounds, k, f"{field}.bounds"), labels)
    if isinstance(spec, s.KineticEnergyLimitSpec):
        return KineticEnergyLimit(model, spec.limit, spec.name)
    raise ScenarioError(field, f"unsupported constraint type {spec.type}")  # pragma: no cover


def _shaping(spec: s.ShapingSpec | None) -> Shaping:
    if spec is None or isinstance(spec, s.IdentityShapingSpec):
        return Identity()
    if isinstance(spec, s.PowerShapingSpec):
        return Power(spec.alpha)
    return Tanh(spec.sigma)


def _gain_vector(value: float | list[float], n: int, field: str) -> Array:
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise ScenarioError(field, f"needs 1 or {n} entries (one per coordinate), got {a.size}")
    return a


@dataclass(frozen=True)
class _Gains:
    """K_P, K_D of a law, and its linear stiffness and damping near the target."""

    kp: Array
    kd: Array
    stiffness: Array
    damping: Array


def _gains(spec: s.ControllerSpec, model: RobotModel, target: Array, field: str) -> _Gains:
    """K_P, K_D as given, or from ω_n and ζ with D_ii at the target (cpbc.scenario.gains)."""
    n = model.n
    xi = gamma = np.ones(n)
    if isinstance(spec, s.BPBCSpec):  # K_P tanh(Ξx̃), K_D tanh(Γẋ): slopes K_P Ξ, K_D Γ
        xi = _gain_vector(spec.xi, n, f"{field}.xi")
        gamma = _gain_vector(spec.gamma, n, f"{field}.gamma")
    if spec.kp is not None and spec.kd is not None:
        kp, kd = _gain_vector(spec.kp, n, f"{field}.kp"), _gain_vector(spec.kd, n, f"{field}.kd")
    else:
        omega = _gain_vector(spec.omega_n, n, f"{field}.omega_n")  # type: ignore[arg-type]
        zeta = _gain_vector(spec.zeta, n, f"{field}.zeta")  # type: ignore[arg-type]
        kp, kd = physical_gains(omega, zeta, np.diag(model.inertia(target)))
        kp, kd = kp / xi, kd / gamma
    return _Gains(kp, kd, kp * xi, kd * gamma)


def _check_zoh(
    gains: _Gains, model: RobotModel, states: list[Array], sim: s.SimulationSpec,
    names: tuple[str, ...], field: str,
) -> None:
    """Refuse gains whose held loop is unstable at the control period (cpbc.scenario.gains)."""
    euler_step = 0.0 if sim.integrator == "RK4" else sim.timestep
    bad = unstable_loop(gains.stiffness, gains.damping, [model.inertia(x) for x in states],
                        sim.control_period or sim.timestep, names, euler_step)
    if bad is not None:
        raise ScenarioError(field, bad.advice() + "; simulation.check_gains: false runs it "
                            "anyway")


def _controller_constraints(
    spec: s.CPBCSpec | s.RecentredSpec | s.BPBCSpec | s.CBFQPSpec, n: int,
    constraints: dict[str, ConfigurationConstraint | VelocityConstraint], field: str,
) -> ConstraintSet:
    chosen = list(constraints) if spec.constraints is None else spec.constraints
    unknown = [c for c in chosen if c not in constraints]
    if unknown:
        raise ScenarioError(
            f"{field}.constraints",
            f"unknown constraint names {unknown}; the scenario defines {list(constraints)}",
        )
    objs = [constraints[c] for c in chosen]
    return ConstraintSet(
        n,
        [o for o in objs if isinstance(o, ConfigurationConstraint)],
        [o for o in objs if isinstance(o, VelocityConstraint)],
    )


def _build_controller(
    spec: s.PDSpec | s.CPBCSpec | s.RecentredSpec | s.BPBCSpec,
    model: RobotModel,
    target: Array,
    gains: _Gains,
    constraints: dict[str, ConfigurationConstraint | VelocityConstraint],
    model_bounds: Callable[[], ModelBounds],
    field: str,
    terms: dict[str, object] | None = None,
) -> Controller:
    cls = CONTROLLERS[spec.type]
    kwargs: dict[str, object] = terms or {"kp": gains.kp, "kd": gains.kd}
    if not isinstance(spec, s.PDSpec):
        kwargs["constraints"] = _controller_constraints(spec, model.n, constraints, field)
        if not isinstance(spec, s.RecentredSpec):
            kwargs["shaping"] = _shaping(spec.shaping)
    if isinstance(spec, s.BPBCSpec):
        kwargs.update(xi=spec.xi, gamma=spec.gamma, model_bounds=model_bounds())
    try:
        return cls(model, target, **kwargs)  # type: ignore[arg-type]
    except InadmissibleStateError:
        raise
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)  # set by a ParameterError
        where = f"{field}.{parameter}" if parameter in type(spec).model_fields else field
        raise ScenarioError(where, str(exc)) from None


def _build_peer(
    spec: s.CBFQPSpec, model: RobotModel, target: Array, gains: _Gains,
    constraints: dict[str, ConfigurationConstraint | VelocityConstraint], loop: LoopSettings,
    field: str,
) -> Controller:
    """The CBF-QP peer (cpbc.peers, imported only here, when a scenario asks for it) on the
    same constraint objects as the laws, the loop's control period and torque box."""
    from cpbc.peers import CBFQP, PeerUnavailable

    cons = _controller_constraints(spec, model.n, constraints, field)
    try:
        return CBFQP(model, target, cons, gains.kp, gains.kd, spec.gain, spec.rate_gain,
                     loop.control_period, loop.torque_limit, spec.variant,
                     spec.braking_share, spec.rate_cushion)
    except PeerUnavailable as exc:
        raise ScenarioError(f"{field}.type", str(exc)) from None
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)
        raise ScenarioError(f"{field}.{parameter}" if parameter else field, str(exc)) from None


def _load_robot(scenario: s.Scenario, scenario_file: Path) -> tuple[
        LoadedArm | None, Path, RobotModel, mujoco.MjModel]:
    """The arm, its file, the controller's model and the plant's MuJoCo model — compiled
    here, so that what only MuJoCo refuses (unreadable meshes, unphysical inertias) is bad
    input now rather than a traceback in a worker."""
    arm = robots.load_scenario_arm(scenario.robot, scenario_file.parent)
    path = arm.urdf_path if arm is not None else _model_path(scenario.robot, scenario_file.parent)
    try:
        model = _robot_model(path, scenario.robot, arm=arm)
        plant = (arm.mujoco_model() if arm is not None
                 else mujoco.MjModel.from_xml_path(str(path)))
    except ScenarioError:
        raise
    except (CpbcError, ValueError) as exc:
        raise ScenarioError("robot.model", str(exc)) from None
    return arm, path, model, plant


def _check_length(sim: s.SimulationSpec, control_period: float) -> None:
    """At least one control period, and no more physics steps than ``max_steps``."""
    period_key = "control_period" if sim.control_period else "timestep"
    if sim.duration < control_period * (1 - 1e-9):
        raise ScenarioError(
            "simulation.duration",
            f"{sim.duration:g} s is shorter than one control period (simulation.{period_key} "
            f"= {control_period:g} s): lengthen the duration or shorten the period",
        )
    try:
        substeps_per_control(control_period, sim.timestep)
    except CpbcError as exc:
        raise ScenarioError("simulation.control_period", str(exc)) from None
    steps = sim.duration / sim.timestep
    if steps > sim.max_steps:
        raise ScenarioError(
            "simulation.duration",
            f"{sim.duration:g} s at a timestep of {sim.timestep:g} s is {steps:.3g} physics "
            f"steps per run, more than simulation.max_steps = {sim.max_steps:,}: shorten the "
            "duration, lengthen the timestep, or raise simulation.max_steps if you mean it",
        )


def _declared_efforts(model: RobotModel) -> Array | None:
    """The effort limits the model declares (a URDF arm), in joint coordinates, inf for a joint
    that declares none; None when no joint declares one (the built-in MJCF arm)."""
    effort = np.array(model.model.effortLimit, dtype=float)
    declared = np.isfinite(effort) & (effort > 0)
    if not model.coordinates.is_identity or effort.size != model.n or not np.any(declared):
        return None
    return np.where(declared, effort, np.inf)


def undeclared_efforts(setup: ScenarioSetup) -> tuple[str, ...]:
    """The joints that run without a torque limit beside joints that have one (the model
    declares effort limits for some joints only; ``simulation.torque_limit: auto``)."""
    limit = setup.loop_settings.torque_limit
    if limit is None:
        return ()
    return tuple(n for n, v in zip(setup.model.joint_names, limit, strict=True)
                 if not np.isfinite(v))


def _loop_settings(sim: s.SimulationSpec, model: RobotModel) -> LoopSettings:
    n = model.n
    control_period = sim.control_period or sim.timestep
    _check_length(sim, control_period)
    limit = None
    if sim.torque_limit == "from_model":
        limit = sim.torque_limit_scale * robots.model_limits(
            model, "effort", "simulation.torque_limit")[1]
    elif sim.torque_limit == "auto":  # real arms have real motors
        limit = _declared_efforts(model)
        limit = None if limit is None else sim.torque_limit_scale * limit
    elif isinstance(sim.torque_limit, (float, list)):
        limit = sim.torque_limit_scale * _vector(
            sim.torque_limit if isinstance(sim.torque_limit, list) else [sim.torque_limit] * n,
            n,
            "simulation.torque_limit",
        )
    noise = None
    if sim.noise is not None:
        noise = MeasurementNoise(
            tuple(sim.noise.position) if isinstance(sim.noise.position, list)
            else sim.noise.position,
            tuple(sim.noise.velocity) if isinstance(sim.noise.velocity, list)
            else sim.noise.velocity,
            sim.noise.seed,
        )
    return LoopSettings(
        sim.duration, control_period, limit, sim.log_every,
        noise=noise,
        max_log_samples=sim.max_log_samples,
    )


def _obstacles(specs: list[s.ObstacleSpec]) -> tuple[list[ObstacleGeom], dict[str, Obstacle]]:
    obstacles: list[ObstacleGeom] = []
    scene: dict[str, Obstacle] = {}
    for i, ospec in enumerate(specs):
        if ospec.name in scene:
            raise ScenarioError(f"obstacles[{i}].name", f"duplicate obstacle name '{ospec.name}'")
        ob = scene[ospec.name] = robots.obstacle(ospec, f"obstacles[{i}]")
        geom = ob.scene_geom()
        obstacles.append(ObstacleGeom(ob.name, geom.pos, float(geom.size[0]), ob.collides, geom))
    return obstacles, scene


def _constraints(
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


def joint_ranges(model: RobotModel, plant: mujoco.MjModel) -> tuple[Array, Array]:
    """The position ranges the plant enforces (MuJoCo's joint stops), in joint coordinates;
    ±inf where a joint has none."""
    n = model.n
    limited = plant.jnt_limited[:n].astype(bool)
    return (np.where(limited, plant.jnt_range[:n, 0], -np.inf),
            np.where(limited, plant.jnt_range[:n, 1], np.inf))


def _check_in_range(
    x: Array, model: RobotModel, ranges: tuple[Array, Array], field: str, what: str
) -> None:
    """A state the joint stops would refuse is bad input, limits declared or not (``what``
    prefixes the message)."""
    q = x if model.coordinates.is_identity else np.linalg.solve(model.coordinates.matrix, x)
    lo, hi = ranges
    for i in np.nonzero((q < lo) | (q > hi))[0]:
        raise ScenarioError(
            field,
            f"{what}joint '{model.joint_names[i]}' = {q[i]:.6g} is outside its range "
            f"[{lo[i]:.6g}, {hi[i]:.6g}] (the model's joint limits, where the plant has a hard "
            "stop): move it inside the range",
        )


def _check_admissible(monitor: ConstraintSet, x: Array, dx: Array, what: str,
                      field: str) -> None:
    try:
        monitor.check_admissible(x, dx, what)
    except InadmissibleStateError as exc:
        exc.field = field  # the scenario entry, for callers that map errors to the file
        raise


def _states(
    scenario: s.Scenario, model: RobotModel, monitor: ConstraintSet,
    ranges: tuple[Array, Array],
) -> tuple[Array, list[CaseEntry]]:
    """The target and the initial states: the right size, inside the joint ranges and S."""
    n = model.n
    given = [k for k in ("target", "goal", "reference") if getattr(scenario, k) is not None]
    if len(given) != 1:
        raise ScenarioError(given[-1] if given else "target",
                            "give one of target: (a joint set point), goal: (a frame's pose) "
                            f"or reference: (a frame's path), not both {' and '.join(given)}"
                            if given else "missing: give target (a joint set point), goal "
                            "(a frame's pose) or reference (a frame's path)")
    target = np.zeros(n)
    if scenario.target is not None:
        target = _vector(scenario.target, n, "target")
        _check_in_range(target, model, ranges, "target", "")
        _check_admissible(monitor, target, np.zeros(n), "target", "target")
    cases = []
    for i, case in enumerate(scenario.cases):
        x0 = _vector(case.position, n, f"cases[{i}].position")
        dx0 = _vector(case.velocity, n, f"cases[{i}].velocity", default=0.0)
        _check_in_range(x0, model, ranges, f"cases[{i}].position", f"case '{case.name}': ")
        _check_admissible(monitor, x0, dx0, f"initial state of case '{case.name}' (cases[{i}])",
                          f"cases[{i}]")
        cases.append(CaseEntry(case.name, x0, dx0))
    if len({c.name for c in cases}) != len(cases):
        raise ScenarioError("cases", "case names must be unique")
    return target, cases


def _check_stoppable(cases: list[CaseEntry], monitor: ConstraintSet, model: RobotModel,
                     limit: Array) -> None:
    """Refuse an initial state outside the braking set V: the safeguard's brake, within the
    torque limits, would stop the arm past a configuration boundary
    (cpbc.constraints.stopping.Braking); say whether any torque in the box could."""
    braking = Braking.of(model, limit)
    for i, case in enumerate(cases):
        sigma, travel = braking.margins(monitor, model, case.position, case.velocity)
        if not sigma.size or np.all(sigma > 0):
            continue
        k = int(np.argmin(sigma))
        speed = float(np.linalg.norm(case.velocity))
        lost, _, _ = stopping_margins(monitor, model, case.position, case.velocity, limit)
        verdict = ("no torque within the limits can stop it in time either" if lost[k] <= 0
                   else "a brake aimed at that constraint alone might, but the safeguard's "
                   "brake must slow every joint at once")
        raise ScenarioError(
            f"cases[{i}].velocity",
            f"case '{case.name}' is outside the braking set: at {speed:.4g} rad/s the "
            f"actuators' torque limits leave a brake that slows every joint together "
            f"{travel:.4g} rad of travel to stop, which ends past '{monitor.names[k]}' "
            f"(margin {sigma[k]:.4g} there; cpbc.constraints.stopping.Braking); {verdict}. "
            "Start slower or farther from that boundary, or raise simulation.torque_limit",
        )


def _controllers(
    scenario: s.Scenario, model: RobotModel, target: Array, cases: list[CaseEntry],
    built: dict[str, ConfigurationConstraint | VelocityConstraint], names: tuple[str, ...],
    loop: LoopSettings, goal: GoalPlan | None = None,
) -> list[ControllerEntry]:
    bounds_cache: list[ModelBounds] = []

    def model_bounds() -> ModelBounds:
        if not bounds_cache:
            bounds_cache.append(estimate_bounds(model))
        return bounds_cache[0]

    sim = scenario.simulation
    check = sim.check_gains and sim.backend == "mujoco"  # the reference holds nothing
    states = [target] + [c.position for c in cases]
    controllers = []
    for i, cspec in enumerate(scenario.controllers):
        field = f"controllers[{i}]"
        terms = None
        if goal is not None:
            terms, task = law_terms(cspec, model, goal, field)
            stiffness, damping = linear_gains(model, goal, task)
            gains = _Gains(terms["kp"], terms["kd"], stiffness, damping)  # type: ignore[arg-type]
        elif cspec.task is not None or cspec.posture is not None:
            raise ScenarioError(f"{field}.task", "task and posture gains need a goal: give "
                                "goal: {frame, position, ...} in place of target:, or kp, kd")
        else:
            gains = _gains(cspec, model, target, field)
        if check:
            _check_zoh(gains, model, states, sim, names, field)
        if isinstance(cspec, s.CBFQPSpec):
            ctrl = _build_peer(cspec, model, target, gains, built, loop, field)
        else:
            ctrl = _build_controller(cspec, model, target, gains, built, model_bounds, field,
                                     terms)
        controllers.append(ControllerEntry(cspec.name or cspec.type, ctrl))
    if len({c.name for c in controllers}) != len(controllers):
        raise ScenarioError("controllers", "controller names must be unique; set 'name' on each")
    return controllers


def _check_recentred(controllers: list[ControllerEntry], cases: list[CaseEntry],
                     model: RobotModel, loop: LoopSettings, names: tuple[str, ...],
                     guarded_loop: bool) -> None:
    """Refuse a ``recentred`` law that cannot be run from a case's start
    (RecentredBarrier.start_problem: the torque limit; without the safeguard, the first
    held period against its velocity constraints)."""
    period = None if guarded_loop else loop.control_period
    for i, entry in enumerate(controllers):
        law = entry.controller
        if not isinstance(law, RecentredBarrier):
            continue
        for case in cases:
            state = law.state(case.position, case.velocity)
            problem = law.start_problem(state, names, loop.torque_limit, period)
            if problem is not None:
                raise ScenarioError(f"controllers[{i}]",
                                    f"'{entry.name}' (recentred), case '{case.name}': {problem}")


def _goal(scenario: s.Scenario, model: RobotModel, scene: dict[str, Obstacle],
          monitor: ConstraintSet, cases: list[CaseEntry], ranges: tuple[Array, Array],
          scenario_file: Path) -> tuple[RefPath | None, GoalPlan] | None:
    """A goal scenario's goal, preflight (from the first case's start, then the middle of the
    joint ranges and four seeded draws in them) and posture; a reference scenario's path and
    the goal at its first sample; None for a joint target."""
    if scenario.goal is None and scenario.reference is None:
        return None
    lo, hi = (np.clip(r, -np.pi, np.pi) for r in ranges)
    rng = np.random.default_rng(0)
    seeds = [0.5 * (lo + hi)] + [rng.uniform(lo, hi) for _ in range(4)]

    def check(x: Array, field: str) -> None:
        _check_in_range(x, model, ranges, field, "")
        _check_admissible(monitor, x, np.zeros(model.n), "goal posture", field)

    if scenario.reference is not None:
        return reference_goal(scenario.reference, model, scene, monitor, scenario_file,
                              [c.position for c in cases], seeds, check)
    assert scenario.goal is not None
    goal = goal_of(scenario.goal, model, scene, monitor)
    return None, plan(scenario.goal, goal, model, monitor, cases[0].position, seeds, check)


def _check_distinct(built: dict[str, ConfigurationConstraint | VelocityConstraint],
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


def build(scenario: s.Scenario, scenario_file: Path) -> ScenarioSetup:
    """Check a scenario against its robot and build every object it describes."""
    runs = len(scenario.cases) * len(scenario.controllers)
    if runs > s.MAX_RUNS:
        raise ScenarioError("cases", f"{len(scenario.cases)} cases × {len(scenario.controllers)} "
                            f"controllers make {runs} runs, more than the {s.MAX_RUNS} a "
                            "scenario may hold; split it into several scenarios")
    arm, path, model, plant = _load_robot(scenario, scenario_file)
    names = _coordinate_names(scenario.robot, model)
    sim = scenario.simulation
    loop = _loop_settings(sim, model)
    obstacles, scene = _obstacles(scenario.obstacles)
    built, rate_bounds = _constraints(scenario, model, names, arm, scene, obstacles)
    _check_distinct(built, [c.name for c in scenario.constraints])
    monitor = ConstraintSet(
        model.n,
        [c for c in built.values() if isinstance(c, ConfigurationConstraint)],
        [c for c in built.values() if isinstance(c, VelocityConstraint)],
    )
    ranges = joint_ranges(model, plant)
    target, cases = _states(scenario, model, monitor, ranges)
    planned = _goal(scenario, model, scene, monitor, cases, ranges, scenario_file)
    ref_path, goal = planned if planned is not None else (None, None)
    if goal is not None:
        target = goal.posture
    if ref_path is not None and sim.backend != "mujoco":
        raise ScenarioError("simulation.backend", "a reference runs in the sampled-data loop "
                            "only (its governor counts control periods): use backend: mujoco")
    gravity_on_path: dict[str, GravityLoad] = {}
    if loop.torque_limit is not None:
        gravity_on_path = check_gravity(model, target, [(c.name, c.position) for c in cases],
                                        loop.torque_limit)
        _check_stoppable(cases, monitor, model, loop.torque_limit)
    controllers = _controllers(scenario, model, target, cases, built, names, loop, goal)
    _check_recentred(controllers, cases, model, loop, names, sim.safeguard)
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
                                    loop.control_period)
    setup = ScenarioSetup(
        scenario, path, model, monitor, controllers, cases, target,
        PlantSettings(sim.timestep, sim.integrator),
        loop, SettleCriteria(sim.position_tolerance, sim.velocity_tolerance), rate_bounds,
        obstacles, names, scenario_file, arm,
        safeguard=SafeguardSettings(velocity_cushion=sim.safeguard_velocity_cushion,
                                    hold_correction=sim.safeguard_hold_correction,
                                    plant_step=sim.timestep if sim.integrator in ONE_STAGE
                                    else None)
        if sim.safeguard else None,
        also_keep=monitor.configuration if sim.safeguard and sim.safeguard_monitored else (),
        gravity_on_path=gravity_on_path, goal=goal, reference=reference,
    )
    _check_disturbances(scenario, plant, model.n)
    return setup
