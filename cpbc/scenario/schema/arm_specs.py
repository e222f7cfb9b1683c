"""An arm scenario: robot, simulation, cases, and the whole ``Scenario``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field, create_model, model_validator

from cpbc.constraints.constraint_kind import ConstraintEntrySpec
from cpbc.controllers.law_specs import LawSpec
from cpbc.controllers.potentials.friction import FRICTION_COMPENSATION_WIDTH
from cpbc.controllers.safeguard.settings import RESCUE_BUDGET
from cpbc.model.coulomb import FRICTION_SMOOTHING
from cpbc.scenario.schema.common import (
    MAX_CASES,
    CaseName,
    NonNegative,
    Number,
    Positive,
    SafeName,
    Strict,
    Vector,
)
from cpbc.scenario.schema.kinds import KINDS, Kinds
from cpbc.scenario.schema.obstacle_specs import ObstacleSpec
from cpbc.scenario.schema.taskspace_specs import GoalSpec, ReferenceSpec

# A ``constraints:`` item and a ``controllers:`` item: the registered kinds' specs,
# discriminated by ``type``. A type checker sees their common bases: what is particular to a
# kind is read through the kind (cpbc.scenario.schema.kinds), not by the code around it.
if TYPE_CHECKING:
    ConstraintSpec = ConstraintEntrySpec
    ControllerSpec = LawSpec
else:
    ConstraintSpec = KINDS.constraint_spec()
    ControllerSpec = KINDS.law_spec()


class PlantMismatchSpec(Strict):
    """How the MuJoCo plant differs from the controller's model (the plant only): factors on
    each body's mass and inertia (one number, or one per body below the world), and joint
    damping, armature and dry friction added to the plant (one number, or one per joint)."""

    mass_scale: Positive | list[Positive] = Field(
        default=1.0, description=(
            "factor on each body's mass in the MuJoCo plant: one number, or one per body "
            "below the world"))
    inertia_scale: Positive | list[Positive] = Field(
        default=1.0, description=(
            "factor on each body's rotational inertia in the plant: one number, or one per "
            "body"))
    damping: NonNegative | list[NonNegative] = Field(
        default=0.0, description=(
            "joint damping added to the plant [N·m·s/rad]: one number, or one per joint"))
    armature: NonNegative | list[NonNegative] = Field(
        default=0.0, description=(
            "armature (rotor inertia) added to the plant [kg·m²]: one number, or one per "
            "joint"))
    frictionloss: NonNegative | list[NonNegative] = Field(
        default=0.0, description=(
            "dry friction added to the plant [N·m]: one number, or one per joint"))


class FrictionSpec(Strict):
    """Each joint's friction, in the controller's model (f of eq. 6.1) and the MuJoCo plant
    (``dof_damping``, ``dof_frictionloss``): Coulomb and viscous levels, each one number,
    one per joint, or ``from_model`` (what the model file declares), and the law's
    compensation of the Coulomb friction (cpbc.controllers.potentials.friction)."""

    coulomb: NonNegative | list[NonNegative] | Literal["from_model"] = Field(
        default=0.0, description=(
            "Coulomb (dry) friction F_c [N·m or N]: one number, one per joint, or from_model "
            "(an MJCF joint's frictionloss, a URDF's <dynamics friction>)"))
    viscous: NonNegative | list[NonNegative] | Literal["from_model"] = Field(
        default=0.0, description=(
            "viscous friction F_d [N·m·s/rad]: one number, one per joint, or from_model (an "
            "MJCF joint's damping, a URDF's <dynamics damping>)"))
    smoothing: Positive = Field(
        default=FRICTION_SMOOTHING, description=(
            "ε of the model's Coulomb friction F_c tanh(q̇/ε) [rad/s]"))
    compensate: Annotated[bool, Field(strict=True)] = Field(
        default=True, description=(
            "joint-target laws add Σ F_c ε_c ln cosh(q̃/ε_c) to their potential, which beats "
            "the Coulomb friction near the target and keeps the constraint guarantee"))
    compensation_width: Positive = Field(
        default=FRICTION_COMPENSATION_WIDTH, description=(
            "ε_c of the compensation [rad]: the error below which its force fades"))


class RobotSpec(Strict):
    """The arm. ``model`` is a built-in name (see cpbc.resources), an example-robot-data arm
    (``panda``, ``ur5``, … see cpbc.model.arms.ARMS) or a path to an MJCF (.xml) or URDF
    (.urdf) file, relative to the scenario file. ``coordinates`` are the controller's:
    ``joint`` (the model's own), ``absolute`` (absolute link angles θ = T q of a planar chain)
    or a matrix T. ``armature`` and ``friction`` are the joints' rotor inertia and friction in
    both engines (``from_model``: as the model file, or a named arm that declares its own,
    declares them; ``auto``, the default: a named arm's own — the fr3's —, else none);
    ``viscous_friction`` is the older name of ``friction.viscous``. URDF arms only:
    ``locked_joints`` freezes joints at values (a named arm's gripper is locked by default),
    ``package_dirs`` are extra folders for ``package://``."""

    model: str = Field(
        default="planar_2link", description=(
            "a built-in model (planar_2link), an example-robot-data arm (panda, ur5, …) or a "
            "path to an MJCF (.xml) or URDF (.urdf) file, relative to the scenario file"))
    coordinates: Literal["joint", "absolute"] | list[Vector] = Field(
        default="joint", description=(
            "the controller's coordinates: joint (the model's own), absolute (absolute link "
            "angles θ = T q of a planar chain) or a matrix T"))
    viscous_friction: NonNegative | list[NonNegative] = Field(
        default=0.0, description=(
            "F_d, diagonal viscous friction in joint coordinates, in plant and model: one "
            "number or one per joint (the older name of friction.viscous: give one of them)"))
    armature: NonNegative | list[NonNegative] | Literal["from_model", "auto", "none"] = Field(
        default="auto", description=(
            "each joint's rotor inertia in D and the plant [kg·m²]: one number, one per "
            "joint, from_model (an MJCF joint's armature, a URDF's <dynamics armature>, a "
            "named arm's own), auto (from_model for a named arm that declares its own, the "
            "fr3; else none) or none"))
    friction: FrictionSpec | Literal["from_model", "auto", "none"] = Field(
        default="auto", description=(
            "each joint's Coulomb and viscous friction in the model and the plant: "
            "{coulomb, viscous, ...}, from_model (both as the model file or a named arm "
            "declares), auto (from_model for a named arm that declares its own, the fr3; "
            "else none) or none"))
    locked_joints: dict[str, Number] = Field(
        default={}, description=(
            "URDF arms: joints frozen at these values in both engines (a named arm's gripper "
            "is locked by default)"))
    package_dirs: list[str] = Field(
        default=[], description=(
            "URDF arms: extra folders searched for package:// meshes; NAME=FOLDER maps "
            "package://NAME/ to FOLDER (a package in a folder of another name)"))
    plant: PlantMismatchSpec | None = Field(
        default=None, description=(
            "how the MuJoCo plant differs from the controller's model (the plant only)"))


class NoiseSpec(Strict):
    """Gaussian noise on the state the controller sees (controller coordinates), seeded."""

    position: NonNegative | list[NonNegative] = Field(
        default=0.0, description=(
            "standard deviation of the noise on the positions the controller sees [rad or m]:"
            " one number or one per coordinate"))
    velocity: NonNegative | list[NonNegative] = Field(
        default=0.0, description=(
            "standard deviation of the noise on the rates the controller sees [rad/s or m/s]:"
            " one number or one per coordinate"))
    seed: Annotated[int, Field(ge=0, strict=True)] = Field(
        default=0, description=(
            "seed of the noise generator"))


DECLARED = ("acceleration", "inertia", "armature", "damping", "friction", "position",
            "velocity")


class ModelErrorSpec(Strict):
    """What the controller's model and its measurements may get wrong, which the safeguard
    holds as a disturbance (cpbc.controllers.safeguard.model_error): at least one field."""

    acceleration: NonNegative | list[NonNegative] | None = Field(
        default=None, description=(
            "ā: |a − â| ≤ ā per joint [rad/s² or m/s²], one number or one per joint: what "
            "the model's error (masses, friction, payload) can do to the acceleration"))
    inertia: Annotated[float, Field(ge=0, lt=1)] | None = Field(
        default=None, description=(
            "e: every link's mass and rotational inertia may be off by up to this share "
            "(0.2: ±20 %); the safeguard holds the acceleration error it makes at each step "
            "and the laws keep the kinetic energy below Ω/(1 + e) of the model's"))
    armature: NonNegative | list[NonNegative] | None = Field(
        default=None, description=(
            "rotor inertia the plant may have beyond the model's, up to this per joint "
            "[kg·m² or kg]: one number or one per joint"))
    damping: NonNegative | list[NonNegative] | None = Field(
        default=None, description=(
            "viscous damping the plant may have beyond the model's, up to this per joint "
            "[N·m·s/rad]: one number or one per joint"))
    friction: NonNegative | list[NonNegative] | None = Field(
        default=None, description=(
            "dry friction the plant may have beyond the model's, up to this per joint "
            "[N·m]: one number or one per joint"))
    position: NonNegative | list[NonNegative] | None = Field(
        default=None, description=(
            "a bound on the error of each measured position [rad or m], one number or one "
            "per coordinate: the safeguard keeps the margins it could hide"))
    velocity: NonNegative | list[NonNegative] | None = Field(
        default=None, description=(
            "a bound on the error of each measured rate [rad/s or m/s], one number or one "
            "per coordinate: the safeguard keeps the margins it could hide"))

    @model_validator(mode="after")
    def _something(self) -> ModelErrorSpec:
        if all(getattr(self, k) is None for k in DECLARED):
            raise ValueError(f"give at least one of {', '.join(DECLARED)}")
        return self


class SimulationSpec(Strict):
    duration: Positive = Field(description="simulated time of each run [s]")
    timestep: Positive = Field(default=0.001, description="MuJoCo's physics timestep [s]")
    control_period: Positive | None = Field(
        default=None, description=(
            "control period [s], a whole multiple of the timestep (zero-order hold); the "
            "timestep when omitted"))
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = Field(
        default="RK4", description=(
            "MuJoCo's integrator"))
    backend: Literal["mujoco", "reference"] = Field(
        default="mujoco", description=(
            "mujoco (sampled-data loop) or reference (SciPy solve_ivp on Pinocchio's forward "
            "dynamics, continuous-time control)"))
    # symmetric actuator limits; "from_model": the model's effort limits (a URDF's effort
    # tags, an MJCF's actuators: cpbc.model.actuators) (× torque_limit_scale);
    # "auto" (the default): the same when the model declares them for every joint, else none;
    # "none" (or null): no limit. The default is a value, not "left out", so that a scenario
    # rebuilt from its JSON dump (a worker process) gets the same limits.
    torque_limit: Positive | list[Positive] | Literal["auto", "from_model", "none"] | None = Field(
        default="auto", description=(
            "symmetric joint torque limits: auto (the model's effort limits if it declares "
            "them for every joint, else none), from_model, none, one number or one per joint "
            "[N·m]"))
    torque_limit_scale: Positive = Field(
        default=1.0, description=(
            "factor on the model's effort limits (from_model and auto)"))
    # the motors' torque-rate limit: the plant clips a command beyond it (as a motor would)
    # and the safeguard chooses only within it; None: unlimited
    torque_rate_limit: Positive | list[Positive] | Literal["from_model", "none"] | None = Field(
        default=None, description=(
            "joint torque-rate limits |dτ/dt| ≤ ρ [N·m/s]: one number, one per joint, "
            "from_model (a built-in arm that declares one), or none. The plant applies it "
            "and the safeguard chooses only within it; the first command ramps from the "
            "gravity torque at the start (at most the torque limit)"))
    log_every: Annotated[int, Field(ge=1)] = Field(
        default=1, description=(
            "keep every k-th control sample in the log"))
    max_log_samples: Annotated[int, Field(ge=2)] = Field(
        default=100_000, description=(
            "most samples a run's log keeps; a long run halves its log rate when full"))
    # the sampled-data safeguard
    safeguard: Annotated[bool, Field(strict=True)] = Field(
        default=True, description=(
            "the sampled-data safeguard around each constrained law (braking when a margin "
            "would shrink too fast over a period)"))
    # ... which also keeps the configuration constraints a law only monitors (obstacles it
    # does not know of, joint ranges): it brakes before the arm reaches them
    safeguard_monitored: Annotated[bool, Field(strict=True)] = Field(
        default=True, description=(
            "the safeguard also keeps the configuration constraints a law only monitors "
            "(obstacles or joint ranges it does not know of)"))
    # the safeguard's cushion on the velocity margins, as a share of each margin at the target
    # per 10 ms of control period (default: as the configuration margins', 0.001)
    safeguard_velocity_cushion: Annotated[float, Field(gt=0, lt=1)] | None = Field(
        default=None, description=(
            "the safeguard's cushion on velocity margins, as a share of each margin at the "
            "target per 10 ms of control period (default: as the configuration margins', "
            "0.001)"))
    # the guard holds the law's acceleration over the period, not its torque (first order,
    # cpbc.controllers.hold; by the share of the drift the plant has, from its integrator and
    # timestep); false: the law's torque as the bare law would hold it
    safeguard_hold_correction: Annotated[bool, Field(strict=True)] = Field(
        default=True, description=(
            "the safeguard holds the law's acceleration over the period, not its torque (τ − "
            "s D Δa with the plant's share s); false holds the law's torque"))
    # the model's declared error: a bound on the acceleration it gets wrong, held by the
    # safeguard as a disturbance; None: the model is taken as exact
    model_error: ModelErrorSpec | None = Field(
        default=None, description=(
            "a declared bound on the model's error (acceleration, inertia, armature, damping, "
            "friction) and the measurement's (position, velocity), that the safeguard holds "
            "as a disturbance (python -m cpbc.verify --disturb draws plants inside the "
            "acceleration bound)"))
    # how many periods of the model the rescue may hold its brakes for in one control period
    # (cpbc.controllers.rescue): a bound on the guard's worst step, at a cost where a brake
    # needs longer to stop the arm; null (the default): no bound
    safeguard_rescue_budget: Annotated[int, Field(strict=True, ge=1)] | None = Field(
        default=RESCUE_BUDGET, description=(
            "periods of the model the safeguard's rescue may check its brakes for in one "
            "control period (a bound on the worst step; the search from the motion's first "
            "state still runs until rest, and a later one holds only a brake whose check "
            "ended within it, else the fallback); null for no bound, the default in "
            "simulation (python -m cpbc.hardware bounds it to 8 on a robot unless given)"))
    # how many candidate torques one safeguard step may test (step_budget.py): with the
    # rescue's budget, a bound on the step's time; null (the default): no bound
    safeguard_test_budget: Annotated[int, Field(strict=True, ge=1)] | None = Field(
        default=None, description=(
            "candidate torques one safeguard step may test, each a prediction of the period "
            "(a bound on the step's time: past it the step holds the last torque that passed, "
            "else the uniform brake); null for no bound, the default in simulation "
            "(python -m cpbc.hardware bounds it on a robot unless given)"))
    # how long one safeguard step may test torques for [s] (step_budget.py): a robot's
    # clock, so a run under it depends on the machine; null (the default): no bound
    safeguard_time_budget: Positive | None = Field(
        default=None, description=(
            "seconds one safeguard step may test torques for, the law's torque always tested "
            "(past it the step holds the last torque that passed, else the uniform brake); "
            "it reads the clock, so a run under it depends on the machine: 1e-9 tests the "
            "law's torque alone on every step, the tightest budget; null for no bound, the "
            "default in simulation (python -m cpbc.hardware sets 15 % of --deadline-ms "
            "unless given)"))
    noise: NoiseSpec | None = Field(
        default=None, description=(
            "Gaussian noise on the state the controller sees (MuJoCo backend)"))
    position_tolerance: Positive = Field(
        default=0.01, description=(
            'the "on target" band used to judge convergence [rad]'))
    velocity_tolerance: Positive = Field(
        default=0.005, description=(
            'the "at rest" band used to judge convergence [rad/s]'))
    # physics steps per run above which the run is refused (raise it to run longer)
    max_steps: Annotated[int, Field(ge=1, strict=True)] = Field(
        default=10_000_000, description=(
            "physics steps per run (duration / timestep) above which the scenario is refused;"
            " raise it to mean it"))
    # refuse gains whose zero-order-hold loop is unstable at control_period
    # (cpbc.scenario.gain_check); false lets a deliberately unstable run go ahead
    check_gains: Annotated[bool, Field(strict=True)] = Field(
        default=True, description=(
            "refuse gains whose zero-order-hold loop is unstable at the control period (false"
            " runs them anyway)"))

    @property
    def period(self) -> float:
        """The control period h [s]: ``control_period``, or one timestep when omitted."""
        return self.control_period or self.timestep


class CaseSpec(Strict):
    name: CaseName = Field(description="the case's name (a folder name of the output)")
    position: Vector = Field(
        description=(
            "initial position, controller coordinates; numbers may be expressions of pi"))
    velocity: Vector | None = Field(
        default=None, description=(
            "initial velocity, controller coordinates; zero when omitted"))


class Scenario(Strict):
    """A whole scenario: robot, simulation, target or goal, cases, constraints, controllers."""

    name: SafeName = Field(description="the scenario's name: letters, digits, _ . + -")
    description: str = Field(default="", description="free text")
    robot: RobotSpec = Field(default=RobotSpec(), description="the arm")
    simulation: SimulationSpec = Field(description="the simulation and the loop")
    target: Vector | None = Field(
        default=None, description=(
            "the joint target x_d in controller coordinates; numbers may be expressions of pi"
            " (give target or goal); on a continuous joint each case takes the equivalent"
            " nearest its start (x_d + 2πk)"))
    goal: GoalSpec | None = Field(
        default=None, description="a frame's goal pose instead of a joint target")
    reference: ReferenceSpec | None = Field(
        default=None, description=(
            "a frame's moving reference instead of a joint target or a goal"))
    cases: Annotated[list[CaseSpec], Field(min_length=1, max_length=MAX_CASES)] = Field(
        description=(
            "initial states; every controller runs on every case"))
    obstacles: list[ObstacleSpec] = Field(
        default=[], description=(
            "bodies in the scene, kept clear of by clearance constraints"))
    constraints: list[ConstraintSpec] = Field(
        default=[], description=(
            "the admissible set S; each item has a unique name"))
    controllers: Annotated[list[ControllerSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared; every controller runs on every case"))


def scenario_model(kinds: Kinds) -> type[Scenario]:
    """The Scenario model whose ``constraints:`` and ``controllers:`` take the kinds of
    ``kinds`` (Scenario itself for the default registry)."""
    if kinds == KINDS:
        return Scenario
    fields = Scenario.model_fields
    return create_model(
        "Scenario", __base__=Scenario, __doc__=Scenario.__doc__,
        constraints=(list[kinds.constraint_spec()], fields["constraints"]),  # type: ignore[arg-type,misc]
        controllers=(list[kinds.law_spec()], fields["controllers"]),  # type: ignore[arg-type,misc]
    )
