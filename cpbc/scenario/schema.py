"""The YAML scenario format, validated with pydantic. Every error names its field."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Annotated, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from cpbc.scenario.expressions import parse_number


def _finite(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError("must be a finite number")
    return v


Number = Annotated[float, BeforeValidator(parse_number), AfterValidator(_finite)]
Positive = Annotated[Number, Field(gt=0)]
NonNegative = Annotated[Number, Field(ge=0)]
Vector = list[Number]
Gain = Positive | list[Positive]
# Names become folder names of the output: one path component, no "." or "..", short
# enough for any file system (a name is at most 255 bytes).
SafeName = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$", max_length=100)]
#: What a run writes at the top of its output folder (cpbc.results.io, cpbc.results.saved_run,
#: cpbc.viewer) and into each case's folder (the figures of cpbc.results.plots and
#: cpbc.scenario.system_runner): a case, or a controller, of one of these names would collide.
RUN_FILES = frozenset({"summary.json", "summary.csv", "scene.mjb", "scene.mjb.gz",
                       "scene.json", "view.html"})
CASE_FILES = frozenset({"positions.png", "rates.png", "torques.png", "lyapunov.png",
                        "margins.png", "path.png", "timeseries.png", "task_error.png",
                        "view.html"})


def _not_in(reserved: frozenset[str], what: str) -> Callable[[str], str]:
    def check(name: str) -> str:
        if name in reserved:
            raise ValueError(f"'{name}' is the name of a file the run writes {what}; "
                             "rename it")
        return name

    return check


CaseName = Annotated[SafeName, AfterValidator(_not_in(RUN_FILES, "into the output folder"))]
RunName = Annotated[SafeName, AfterValidator(_not_in(CASE_FILES, "into each case's folder"))]


#: The most cases a scenario holds, and the most runs (cases × controllers): each case
#: draws its figures and each run logs its trajectory and joins the page; more is a
#: campaign, for cpbc.reliability, or several scenarios.
MAX_CASES = 500
MAX_RUNS = 1000


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PlantMismatchSpec(Strict):
    """How the MuJoCo plant differs from the controller's model (the plant only): factors on
    each body's mass and inertia (one number, or one per body below the world), and joint
    damping, armature and dry friction added to the plant (one number, or one per joint)."""

    mass_scale: Positive | list[Positive] = 1.0
    inertia_scale: Positive | list[Positive] = 1.0
    damping: NonNegative | list[NonNegative] = 0.0
    armature: NonNegative | list[NonNegative] = 0.0
    frictionloss: NonNegative | list[NonNegative] = 0.0


class RobotSpec(Strict):
    """The arm. ``model`` is a built-in name (see cpbc.resources), an example-robot-data arm
    (``panda``, ``ur5``, … see cpbc.model.arms.ARMS) or a path to an MJCF (.xml) or URDF
    (.urdf) file, relative to the scenario file. ``coordinates`` are the controller's:
    ``joint`` (the model's own), ``absolute`` (absolute link angles θ = T q of a planar chain)
    or a matrix T. ``viscous_friction`` is F_d (diagonal, joint coordinates) in the plant and
    the model. URDF arms only: ``locked_joints`` freezes joints at values (a named arm's
    gripper is locked by default), ``package_dirs`` are extra folders for ``package://``."""

    model: str = "planar_2link"
    coordinates: Literal["joint", "absolute"] | list[Vector] = "joint"
    viscous_friction: NonNegative | list[NonNegative] = 0.0
    locked_joints: dict[str, Number] = {}
    package_dirs: list[str] = []
    plant: PlantMismatchSpec | None = None


class NoiseSpec(Strict):
    """Gaussian noise on the state the controller sees (controller coordinates), seeded."""

    position: NonNegative | list[NonNegative] = 0.0
    velocity: NonNegative | list[NonNegative] = 0.0
    seed: Annotated[int, Field(ge=0, strict=True)] = 0


class SimulationSpec(Strict):
    duration: Positive
    timestep: Positive = 0.001
    control_period: Positive | None = None
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = "RK4"
    backend: Literal["mujoco", "reference"] = "mujoco"
    # symmetric actuator limits; "from_model": the URDF's effort limits (× torque_limit_scale);
    # "auto" (the default): the same when the model declares them for every joint, else none;
    # "none" (or null): no limit. The default is a value, not "left out", so that a scenario
    # rebuilt from its JSON dump (a worker process) gets the same limits.
    torque_limit: Positive | list[Positive] | Literal["auto", "from_model", "none"] | None = "auto"
    torque_limit_scale: Positive = 1.0
    log_every: Annotated[int, Field(ge=1)] = 1
    max_log_samples: Annotated[int, Field(ge=2)] = 100_000
    safeguard: Annotated[bool, Field(strict=True)] = True  # the sampled-data safeguard
    # ... which also keeps the configuration constraints a law only monitors (obstacles it
    # does not know of, joint ranges): it brakes before the arm reaches them
    safeguard_monitored: Annotated[bool, Field(strict=True)] = True
    # the safeguard's cushion on the velocity margins, as a share of each margin at the target
    # per 10 ms of control period (default: as the configuration margins', 0.001)
    safeguard_velocity_cushion: Annotated[float, Field(gt=0, lt=1)] | None = None
    # the guard holds the law's acceleration over the period, not its torque (first order,
    # cpbc.controllers.hold; by the share of the drift the plant has, from its integrator and
    # timestep); false: the law's torque as the bare law would hold it
    safeguard_hold_correction: Annotated[bool, Field(strict=True)] = True
    noise: NoiseSpec | None = None
    position_tolerance: Positive = 0.01
    velocity_tolerance: Positive = 0.005
    # physics steps per run above which the run is refused (raise it to run longer)
    max_steps: Annotated[int, Field(ge=1, strict=True)] = 10_000_000
    # refuse gains whose zero-order-hold loop is unstable at control_period
    # (cpbc.scenario.gains); false lets a deliberately unstable run go ahead
    check_gains: Annotated[bool, Field(strict=True)] = True


class CaseSpec(Strict):
    name: CaseName
    position: Vector
    velocity: Vector | None = None


# -- constraints --------------------------------------------------------------------------
FromModel = Literal["from_model"]  # a limit read from the robot's URDF/MJCF


class JointPositionLimitSpec(Strict):
    type: Literal["joint_position_limit"]
    name: str = "joint_position_limit"
    joints: list[str] | None = None
    lower: Vector | FromModel
    upper: Vector | FromModel


class LinearLimitSpec(Strict):
    type: Literal["linear_limit"]
    name: str = "linear_limit"
    coefficients: list[Vector]
    lower: Vector
    upper: Vector


class PointOutsideSphereSpec(Strict):
    type: Literal["point_outside_sphere"]
    name: str = "obstacle"
    frame: str
    offset: Vector | None = None
    centre: Vector
    radius: Positive
    collides: bool = False  # the thesis's obstacle is not a physical body


class JointRateLimitSpec(Strict):
    type: Literal["joint_rate_limit"]
    name: str = "joint_rate_limit"
    joints: list[str] | None = None
    bounds: list[Positive] | FromModel
    scale: Positive = 1.0  # multiplies the bounds (e.g. 0.5 of the URDF's velocity limits)


class RateLimitSpec(Strict):
    type: Literal["rate_limit"]
    name: str = "rate_limit"
    coefficients: list[Vector]
    bounds: list[Positive]


class KineticEnergyLimitSpec(Strict):
    type: Literal["kinetic_energy_limit"]
    name: str = "kinetic_energy"
    limit: Positive


class PrimitiveSpec(Strict):
    """A sphere (``centre``) or capsule (``start``, ``end``) fixed in a link's frame [m]."""

    link: str
    name: str | None = None
    centre: Vector | None = None
    start: Vector | None = None
    end: Vector | None = None
    radius: Positive


class ClearanceSpec(Strict):
    """Every link (covered by spheres or capsules) against obstacles, and link pairs.

    ``links``: links covered automatically from their collision meshes (all moving links
    with collision geometry when omitted, none with []); ``primitives`` are declared and
    replace the automatic cover of their links. φ = distance − ``margin`` > 0 per
    (link, obstacle) pair; pairs farther than ``influence`` exert no force (null: the plain
    barrier of every pair, see cpbc.constraints.clearance)."""

    type: Literal["clearance"]
    name: str = "clearance"
    obstacles: list[str] | None = None
    links: list[str] | None = None
    cover: Literal["spheres", "capsules"] = "spheres"
    cover_tolerance: Positive = 0.01
    padding: NonNegative = 0.0
    primitives: list[PrimitiveSpec] | None = None
    margin: NonNegative = 0.0
    influence: Positive | None = 0.1
    self_collision: list[Annotated[list[str], Field(min_length=2, max_length=2)]] = []


ConstraintSpec = Annotated[
    JointPositionLimitSpec
    | LinearLimitSpec
    | PointOutsideSphereSpec
    | JointRateLimitSpec
    | RateLimitSpec
    | KineticEnergyLimitSpec
    | ClearanceSpec,
    Field(discriminator="type"),
]


# -- obstacles ----------------------------------------------------------------------------
class SphereObstacleSpec(Strict):
    type: Literal["sphere"]
    name: SafeName
    centre: Vector
    radius: Positive
    collides: bool = True


class CapsuleObstacleSpec(Strict):
    """A pole from ``start`` to ``end``; a cylinder's clearance uses its capsule."""

    type: Literal["capsule", "cylinder"]
    name: SafeName
    start: Vector
    end: Vector
    radius: Positive
    collides: bool = True


class BoxObstacleSpec(Strict):
    type: Literal["box"]
    name: SafeName
    centre: Vector
    half_extents: list[Positive]
    rpy: Vector = [0.0, 0.0, 0.0]
    collides: bool = True


class PlaneObstacleSpec(Strict):
    """A floor or table top: the half-space below the plane through ``point``."""

    type: Literal["plane"]
    name: SafeName
    point: Vector = [0.0, 0.0, 0.0]
    normal: Vector = [0.0, 0.0, 1.0]
    collides: bool = True


ObstacleSpec = Annotated[
    SphereObstacleSpec | CapsuleObstacleSpec | BoxObstacleSpec | PlaneObstacleSpec,
    Field(discriminator="type"),
]


# -- controllers --------------------------------------------------------------------------
class IdentityShapingSpec(Strict):
    type: Literal["identity"]


class PowerShapingSpec(Strict):
    type: Literal["power"]
    alpha: Positive


class TanhShapingSpec(Strict):
    type: Literal["tanh"]
    sigma: Positive


ShapingSpec = Annotated[
    IdentityShapingSpec | PowerShapingSpec | TanhShapingSpec, Field(discriminator="type")
]


class TaskGainsSpec(Strict):
    """A goal's task gains in physical units, scaled by the arm's task-space inertia Λ at the
    posture (cpbc.taskspace.gains): K_p = ω_n² Λ, D_x = 2 ζ ω_n Λ; the orientation spring
    at ``rotation_omega_n`` (ω_n when omitted). The bounded laws (bpbc, bpbc_ke) saturate the
    position spring beyond 1/``xi`` [m] and the task damping beyond 1/``gamma`` [m/s]."""

    omega_n: Positive = 8.0
    zeta: Positive = 1.0
    rotation_omega_n: Positive | None = None
    xi: Positive = 10.0
    gamma: Positive = 10.0


class PostureGainsSpec(Strict):
    """A goal's posture spring and joint damping: K_n = ω_n² D_ii, K_D = 2 ζ ω_n D_ii at the
    posture. Never off (it keeps the law's V a barrier on the boundary of S)."""

    omega_n: Positive = 2.0
    zeta: Positive = 1.0


class GainsSpec(Strict):
    """K_P, K_D directly (``kp``, ``kd``), or in physical terms: a natural frequency
    ``omega_n`` [rad/s] and damping ratio ``zeta`` per coordinate (or one for all), scaled by
    the arm's inertia at the target: K_P,i = D_ii(x_d) ω_n,i², K_D,i = 2 ζ_i ω_n,i D_ii(x_d)
    (see cpbc.scenario.gains)."""

    # omega_n and zeta come first so that kp's and kd's checks see them (info.data)
    omega_n: Gain | None = None
    zeta: Gain | None = None
    kp: Gain | None = None
    kd: Gain | None = None
    # with a scenario goal: the task and posture gains in place of kp, kd
    task: TaskGainsSpec | None = None
    posture: PostureGainsSpec | None = None

    @field_validator("kp", "kd", mode="before")
    @classmethod
    def _not_null(cls, v: object, info: ValidationInfo) -> object:
        # kp: null is a slip, unless the gains are given as omega_n, zeta (as a dumped
        # scenario has them)
        if v is None and info.data.get("omega_n") is None and info.data.get("task") is None:
            raise ValueError("must be a number or a list of numbers, not null")
        return v

    @model_validator(mode="after")
    def _one_form(self) -> GainsSpec:
        given = {k for k in ("kp", "kd", "omega_n", "zeta") if getattr(self, k) is not None}
        if self.task is not None or self.posture is not None:
            if given:
                raise ValueError(f"give task and posture gains, or {', '.join(sorted(given))}"
                                 ", not both (a goal's law takes task: and posture:)")
            return self
        if given & {"kp", "kd"} and given & {"omega_n", "zeta"}:
            raise ValueError("give either kp and kd, or omega_n and zeta, not both")
        if given not in ({"kp", "kd"}, {"omega_n", "zeta"}):
            missing = ({"kp", "kd"} - given) if given & {"kp", "kd"} else (
                {"omega_n", "zeta"} - given if given else {"kp", "kd"})
            raise ValueError(f"{' and '.join(sorted(missing))} missing: give kp and kd, or "
                             "omega_n [rad/s] and zeta")
        return self


class PDSpec(GainsSpec):
    type: Literal["pd", "pd_gravity"]
    name: RunName | None = None


class CPBCSpec(GainsSpec):
    type: Literal["cpbc", "cpbc_ke"]
    name: RunName | None = None
    shaping: ShapingSpec | None = None
    constraints: list[str] | None = None  # names of scenario constraints; all when omitted


class RecentredSpec(GainsSpec):
    type: Literal["recentred"]
    name: RunName | None = None
    constraints: list[str] | None = None


class BPBCSpec(GainsSpec):
    type: Literal["bpbc", "bpbc_ke"]
    name: RunName | None = None
    xi: Gain = 1.0
    gamma: Gain = 1.0
    shaping: ShapingSpec | None = None
    constraints: list[str] | None = None


class CBFQPSpec(GainsSpec):
    """The CBF-QP peer (cpbc.peers.cbf_qp): PD + gravity filtered by a QP."""

    type: Literal["cbf_qp"]
    name: RunName | None = None
    variant: Literal["braking", "exponential"] = "braking"  # cpbc.peers.cbf_rows
    gain: Positive = 20.0  # k [1/s]: α'(0) of the braking rows, or the exponential poles
    rate_gain: Positive | None = None  # γ of the first-order rows [1/s]; 1/(2h) when omitted
    braking_share: float = Field(0.5, gt=0, le=1)  # β: share of the box's deceleration
    rate_cushion: float | None = Field(None, ge=0)  # c on rate rows; 2e-3 (h/1 ms)^1.7
    constraints: list[str] | None = None


ControllerSpec = Annotated[
    PDSpec | CPBCSpec | RecentredSpec | BPBCSpec | CBFQPSpec, Field(discriminator="type")
]


class AxisSpec(Strict):
    """The tool axis ``tool`` (frame axes) along the world axis ``world``; yaw about it free."""

    tool: Vector
    world: Vector


class OrientationSpec(Strict):
    """A goal orientation: exactly one of ``rpy`` [rad], ``quat`` (w, x, y, z) or ``axis``."""

    rpy: Vector | None = None
    quat: Vector | None = None
    axis: AxisSpec | None = None


class ToleranceSpec(Strict):
    """The band of ``reached``: position [m] and angle [rad]."""

    position: Positive = 0.002
    angle: Positive = 0.02


class GoalSpec(Strict):
    """A frame's goal pose instead of a joint target (cpbc.taskspace)."""

    frame: str
    offset: Vector | None = None
    position: Vector
    orientation: OrientationSpec | None = None
    tolerance: ToleranceSpec = ToleranceSpec()
    posture: Literal["ik", "start"] | Vector = "ik"


class Scenario(Strict):
    """A whole scenario: robot, simulation, target or goal, cases, constraints, controllers."""

    name: SafeName
    description: str = ""
    robot: RobotSpec = RobotSpec()
    simulation: SimulationSpec
    target: Vector | None = None
    goal: GoalSpec | None = None
    cases: Annotated[list[CaseSpec], Field(min_length=1, max_length=MAX_CASES)]
    obstacles: list[ObstacleSpec] = []
    constraints: list[ConstraintSpec] = []
    controllers: Annotated[list[ControllerSpec], Field(min_length=1)]


# -- Part I systems (a ``system:`` block in place of ``robot:``) ---------------------------
StrictBool = Annotated[bool, Field(strict=True)]


class SuspensionGainsSpec(Strict):
    """The design constants of §3.3.3 (Theorem 3.6), under the thesis's names."""

    k1: Positive = 3.5
    k2: Positive = 0.051
    k3: Positive = 0.07
    k4: Positive = 50.0
    c1: Positive = 0.049
    c2: Positive = 300.0
    c3: Positive = 500.0


class SuspensionLawSpec(Strict):
    """The law (3.88); ``barrier: false`` is the same law with ½k3 z1² in place of the log
    barrier (no travel guarantee), the unconstrained comparison."""

    name: RunName
    barrier: StrictBool = True
    gains: SuspensionGainsSpec = SuspensionGainsSpec()


class QuarterCarSpec(Strict):
    """The active quarter car of §3.3 over a haversine bump (its height is per case).
    ω and ρ are the built-in MJCF's (§3.3.3)."""

    type: Literal["quarter_car"]
    travel_limit: Positive = 0.1  # Ξ [m]
    bump_length: Positive = 2.0  # l [m]
    speed: Positive = 25.0  # v [m/s]
    laws: Annotated[list[SuspensionLawSpec], Field(min_length=1)]


class WheelPendulumGainsSpec(Strict):
    """The design constants of §3.5.3 (Proposition 3.11), under the thesis's names."""

    k1: Positive = 57.5e-3
    k2: Positive = 2.225
    k3: Positive = 0.25
    k4: Positive = 0.501
    c1: Positive = 0.5
    c2: Positive = 1.0


class WheelPendulumLawSpec(Strict):
    name: RunName
    gains: WheelPendulumGainsSpec = WheelPendulumGainsSpec()


class ReactionWheelSpec(Strict):
    """The reaction wheel pendulum of §3.5 (the built-in MJCF's d's, §3.5.3)."""

    type: Literal["reaction_wheel_pendulum"]
    rate_limit: Positive = 1.0  # on |q̇1| [rad/s]
    torque_limit: Positive = 0.4  # on |τ| [N m]
    laws: Annotated[list[WheelPendulumLawSpec], Field(min_length=1)]


class ChainGainsSpec(Strict):
    """The design constants of §4.4 (Theorem 4.12, manual tuning), under the thesis's names,
    read as PART1 Ch. 4 §2.6 reading H1 (see cpbc.backstepping.integrator_chain)."""

    c1: Positive = 0.5 / math.pi
    c2: Positive = 1.0
    c3: Positive = 50.0
    c4: Positive = 1.0
    k1: Positive = 1.0
    k2: Positive = 2.0
    k3: Positive = 3.0
    k4: Positive = 5.61
    k5: Positive = 1.0
    k6: Positive = 354.5
    k7: Positive = 10.0


class ChainLawSpec(Strict):
    name: RunName
    gains: ChainGainsSpec = ChainGainsSpec()


class IntegratorChainSpec(Strict):
    """The 4th-order integrator chain of §4.4 (4.92): an ODE, no MuJoCo model; ``limits``
    are Ξ on |ξ2|, |ξ3|, |ξ4| (4.93), ξ1 is unconstrained."""

    type: Literal["integrator_chain"]
    limits: Annotated[list[Positive], Field(min_length=3, max_length=3)] = [2.5, 12.0, 700.0]
    laws: Annotated[list[ChainLawSpec], Field(min_length=1)]


class TraditionalAltitudeGainsSpec(Strict):
    """c1 … c4 of §5.3.1 (the law (5.30))."""

    c1: Positive = 1.5
    c2: Positive = 10.0
    c3: Positive = 5.0
    c4: Positive = 0.1


class ConstrainedAltitudeGainsSpec(Strict):
    """c1 … c4, k1 … k3 of §5.4.3 (the law (5.61)); k2 + c1 must not exceed the climb-rate
    limit B, and k2 > c1 (Theorem 5.5)."""

    c1: Positive = 1.5
    c2: Positive = 1.0
    c3: Positive = 5.0
    c4: Positive = 10.0
    k1: Positive = 1.5
    k2: Positive = 2.0
    k3: Positive = 0.5


class TraditionalAltitudeLawSpec(Strict):
    """§5.3's traditional backstepping law: nothing bounds the climb rate."""

    type: Literal["traditional"]
    name: RunName
    gains: TraditionalAltitudeGainsSpec = TraditionalAltitudeGainsSpec()


class ConstrainedAltitudeLawSpec(Strict):
    """§5.4's law with the log barrier on the climb-rate error: |v_z| < k2 + c1."""

    type: Literal["constrained"]
    name: RunName
    gains: ConstrainedAltitudeGainsSpec = ConstrainedAltitudeGainsSpec()


AltitudeLawSpec = Annotated[TraditionalAltitudeLawSpec | ConstrainedAltitudeLawSpec,
                            Field(discriminator="type")]


class AerosondeSpec(Strict):
    """The Aerosonde UAV of Chapter 5 (AeroSim's longitudinal model, an ODE plant: the
    reference backend only). ``air_density`` and ``mass`` are what the laws' design model
    assumes and the aircraft's mass (the thesis gives neither); ``air_density`` defaults to
    ISA at each case's start altitude. Each case's ``state`` is [altitude [m], climb rate
    [m/s]]: level trim at ``airspeed`` with the velocity turned to that climb rate."""

    type: Literal["aerosonde"]
    airspeed: Positive = 23.0  # v_T [m/s], held by the airspeed loop on thrust
    climb_rate_limit: Positive = 3.5  # B [m/s]
    elevator_limit: Positive = 1.0  # [rad] (57.3°)
    air_density: Positive | None = None  # ρ of the design model [kg/m³]
    mass: Positive = 13.5  # [kg] (AeroSim gross; 8.5 empty)
    laws: Annotated[list[AltitudeLawSpec], Field(min_length=1)]


SystemSpec = Annotated[QuarterCarSpec | ReactionWheelSpec | IntegratorChainSpec | AerosondeSpec,
                       Field(discriminator="type")]


class SystemSimulationSpec(Strict):
    """``control_period`` defaults to the timestep; ``tolerance`` judges convergence on the
    components the system names (the pendulum, not its wheel)."""

    duration: Positive
    timestep: Positive = 0.001
    control_period: Positive | None = None
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = "RK4"
    backend: Literal["mujoco", "reference"] = "mujoco"
    tolerance: Positive = 0.01
    max_steps: Annotated[int, Field(ge=1, strict=True)] = 10_000_000


class AltitudeCommandSpec(Strict):
    """A step of the altitude command: h_d = ``altitude`` [m] from ``time`` [s] on."""

    time: NonNegative
    altitude: Number


class SystemCaseSpec(Strict):
    """An initial state x(0) in the system's own state (see cpbc.systems); the quarter car's
    cases give the bump height A [m], the Aerosonde's the altitude commands (h_d is the
    start altitude until the first)."""

    name: CaseName
    state: Vector
    bump_height: NonNegative | None = None
    commands: list[AltitudeCommandSpec] | None = None


class SystemScenario(Strict):
    """A Part I scenario: a system with its laws, simulation and cases."""

    name: SafeName
    description: str = ""
    system: SystemSpec
    simulation: SystemSimulationSpec
    cases: Annotated[list[SystemCaseSpec], Field(min_length=1, max_length=MAX_CASES)]
