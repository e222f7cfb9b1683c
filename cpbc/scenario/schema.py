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
                        "governor.png",
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


class RobotSpec(Strict):
    """The arm. ``model`` is a built-in name (see cpbc.resources), an example-robot-data arm
    (``panda``, ``ur5``, … see cpbc.model.arms.ARMS) or a path to an MJCF (.xml) or URDF
    (.urdf) file, relative to the scenario file. ``coordinates`` are the controller's:
    ``joint`` (the model's own), ``absolute`` (absolute link angles θ = T q of a planar chain)
    or a matrix T. ``viscous_friction`` is F_d (diagonal, joint coordinates) in the plant and
    the model. URDF arms only: ``locked_joints`` freezes joints at values (a named arm's
    gripper is locked by default), ``package_dirs`` are extra folders for ``package://``."""

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
            "number or one per joint"))
    locked_joints: dict[str, Number] = Field(
        default={}, description=(
            "URDF arms: joints frozen at these values in both engines (a named arm's gripper "
            "is locked by default)"))
    package_dirs: list[str] = Field(
        default=[], description=(
            "URDF arms: extra folders searched for package:// meshes"))
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
    # symmetric actuator limits; "from_model": the URDF's effort limits (× torque_limit_scale);
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
    # (cpbc.scenario.gains); false lets a deliberately unstable run go ahead
    check_gains: Annotated[bool, Field(strict=True)] = Field(
        default=True, description=(
            "refuse gains whose zero-order-hold loop is unstable at the control period (false"
            " runs them anyway)"))


class CaseSpec(Strict):
    name: CaseName = Field(description="the case's name (a folder name of the output)")
    position: Vector = Field(
        description=(
            "initial position, controller coordinates; numbers may be expressions of pi"))
    velocity: Vector | None = Field(
        default=None, description=(
            "initial velocity, controller coordinates; zero when omitted"))


# -- constraints --------------------------------------------------------------------------
FromModel = Literal["from_model"]  # a limit read from the robot's URDF/MJCF


class JointPositionLimitSpec(Strict):
    type: Literal["joint_position_limit"] = Field(
        description=(
            "lower < x_i < upper on coordinates, φ = (x − l)(u − x)"))
    name: str = Field(
        default="joint_position_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    joints: list[str] | None = Field(
        default=None, description=(
            "the constrained coordinates by joint name; all when omitted"))
    lower: Vector | FromModel = Field(
        description=(
            "lower bounds [rad or m], or from_model (the model's joint ranges)"))
    upper: Vector | FromModel = Field(
        description=(
            "upper bounds [rad or m], or from_model (the model's joint ranges)"))


class LinearLimitSpec(Strict):
    type: Literal["linear_limit"] = Field(
        description=(
            "lower < aᵀx < upper for each row a (the thesis's |θ2 − θ1| < 17π/18)"))
    name: str = Field(
        default="linear_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    coefficients: list[Vector] = Field(description="the rows a, one per limit")
    lower: Vector = Field(description="lower bound per row")
    upper: Vector = Field(description="upper bound per row")


class PointOutsideSphereSpec(Strict):
    type: Literal["point_outside_sphere"] = Field(
        description=(
            "‖p − c‖² − r² > 0 for a frame's point p (the thesis's end-point obstacle)"))
    name: str = Field(
        default="obstacle", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    frame: str = Field(description="the model frame carrying the point")
    offset: Vector | None = Field(
        default=None, description=(
            "the point in the frame [m]; the frame's origin when omitted"))
    centre: Vector = Field(description="the sphere's centre in the world [m]")
    radius: Positive = Field(description="the sphere's radius [m]")
    # the thesis's obstacle is not a physical body
    collides: bool = Field(
        default=False, description=(
            "make the sphere a physical body in MuJoCo (the thesis's obstacle is not)"))


class JointRateLimitSpec(Strict):
    type: Literal["joint_rate_limit"] = Field(description="|ẋ_i| < B_i on coordinates")
    name: str = Field(
        default="joint_rate_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    joints: list[str] | None = Field(
        default=None, description=(
            "the constrained coordinates by joint name; all when omitted"))
    bounds: list[Positive] | FromModel = Field(
        description=(
            "the rate bounds B_i [rad/s or m/s], or from_model (the URDF's velocity limits)"))
    # multiplies the bounds (e.g. 0.5 of the URDF's velocity limits)
    scale: Positive = Field(
        default=1.0, description=(
            "factor on the bounds (0.5: half the URDF's velocity limits)"))


class RateLimitSpec(Strict):
    type: Literal["rate_limit"] = Field(description="|aᵀẋ| < B for each row a")
    name: str = Field(
        default="rate_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    coefficients: list[Vector] = Field(description="the rows a, one per bound")
    bounds: list[Positive] = Field(description="the bound B per row")


class KineticEnergyLimitSpec(Strict):
    type: Literal["kinetic_energy_limit"] = Field(description="½ẋᵀDẋ < Ω")
    name: str = Field(
        default="kinetic_energy", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    limit: Positive = Field(description="Ω [J]")


class PrimitiveSpec(Strict):
    """A sphere (``centre``) or capsule (``start``, ``end``) fixed in a link's frame [m]."""

    link: str = Field(description="the link carrying the primitive")
    name: str | None = Field(
        default=None, description=(
            "the primitive's name in the summary; derived from the link when omitted"))
    centre: Vector | None = Field(
        default=None, description="a sphere's centre in the link's frame [m]")
    start: Vector | None = Field(
        default=None, description="a capsule's first end in the link's frame [m]")
    end: Vector | None = Field(
        default=None, description="a capsule's second end in the link's frame [m]")
    radius: Positive = Field(description="radius [m]")


class ClearanceSpec(Strict):
    """Every link (covered by spheres or capsules) against obstacles, and link pairs.

    ``links``: links covered automatically from their collision meshes (all moving links
    with collision geometry when omitted, none with []); ``primitives`` are declared and
    replace the automatic cover of their links. φ = distance − ``margin`` > 0 per
    (link, obstacle) pair; pairs farther than ``influence`` exert no force (null: the plain
    barrier of every pair, see cpbc.constraints.clearance)."""

    type: Literal["clearance"] = Field(
        description=(
            "distance − margin > 0 between each covered link and each obstacle (and declared "
            "link pairs)"))
    name: str = Field(
        default="clearance", description=(
            "unique name prefix of the (link, obstacle) constraints"))
    obstacles: list[str] | None = Field(
        default=None, description=(
            "the scenario obstacles kept clear of, by name; all when omitted"))
    links: list[str] | None = Field(
        default=None, description=(
            "links covered automatically from their collision meshes; all moving links with "
            "collision geometry when omitted, none with []"))
    cover: Literal["spheres", "capsules"] = Field(
        default="spheres", description=(
            "cover each link with spheres or capsules (capsules cost about 5.5× per step)"))
    cover_tolerance: Positive = Field(
        default=0.01, description=(
            "how far the fitted cover may fall short of the mesh [m]"))
    padding: NonNegative = Field(
        default=0.0, description="added to every cover primitive's radius [m]")
    primitives: list[PrimitiveSpec] | None = Field(
        default=None, description=(
            "declared spheres or capsules; they replace the automatic cover of their links"))
    margin: NonNegative = Field(default=0.0, description="φ = distance − margin [m]")
    influence: Positive | None = Field(
        default=0.1, description=(
            "pairs farther apart than this exert no force [m]; null: the plain barrier of "
            "every pair"))
    self_collision: list[Annotated[list[str], Field(min_length=2, max_length=2)]] = Field(
        default=[], description=(
            "link pairs kept apart from each other"))


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
    type: Literal["sphere"] = Field(description="a ball")
    name: SafeName = Field(description="unique obstacle name")
    centre: Vector = Field(description="centre in the world [m]")
    radius: Positive = Field(description="radius [m]")
    collides: bool = Field(
        default=True, description=(
            "a physical body in the MuJoCo scene (false: only the constraint sees it)"))


class CapsuleObstacleSpec(Strict):
    """A pole from ``start`` to ``end``; a cylinder's clearance uses its capsule."""

    type: Literal["capsule", "cylinder"] = Field(
        description=(
            "a pole; a cylinder's clearance uses its capsule"))
    name: SafeName = Field(description="unique obstacle name")
    start: Vector = Field(description="axis start in the world [m]")
    end: Vector = Field(description="axis end in the world [m]")
    radius: Positive = Field(description="radius [m]")
    collides: bool = Field(
        default=True, description=(
            "a physical body in the MuJoCo scene (false: only the constraint sees it)"))


class BoxObstacleSpec(Strict):
    type: Literal["box"] = Field(description="a box")
    name: SafeName = Field(description="unique obstacle name")
    centre: Vector = Field(description="centre in the world [m]")
    half_extents: list[Positive] = Field(description="half sizes along the box's axes [m]")
    rpy: Vector = Field(
        default=[0.0, 0.0, 0.0], description="orientation as roll, pitch, yaw [rad]")
    collides: bool = Field(
        default=True, description=(
            "a physical body in the MuJoCo scene (false: only the constraint sees it)"))


class PlaneObstacleSpec(Strict):
    """A floor or table top: the half-space below the plane through ``point``."""

    type: Literal["plane"] = Field(
        description=(
            "a floor or table top: the half-space below the plane"))
    name: SafeName = Field(description="unique obstacle name")
    point: Vector = Field(default=[0.0, 0.0, 0.0], description="a point of the plane [m]")
    normal: Vector = Field(
        default=[0.0, 0.0, 1.0], description=(
            "the plane's normal, pointing to the free side"))
    collides: bool = Field(
        default=True, description=(
            "a physical body in the MuJoCo scene (false: only the constraint sees it)"))


ObstacleSpec = Annotated[
    SphereObstacleSpec | CapsuleObstacleSpec | BoxObstacleSpec | PlaneObstacleSpec,
    Field(discriminator="type"),
]


# -- controllers --------------------------------------------------------------------------
class IdentityShapingSpec(Strict):
    type: Literal["identity"] = Field(description="s(x) = x: V = L/(ΦΨ)")


class PowerShapingSpec(Strict):
    type: Literal["power"] = Field(description="s(x) = x^α")
    alpha: Positive = Field(description="α, the barrier's exponent (smaller: a weaker barrier)")


class TanhShapingSpec(Strict):
    type: Literal["tanh"] = Field(description="s(x) = tanh(σx)")
    sigma: Positive = Field(description="σ [1/unit of ΦΨ]")


ShapingSpec = Annotated[
    IdentityShapingSpec | PowerShapingSpec | TanhShapingSpec, Field(discriminator="type")
]


class TaskGainsSpec(Strict):
    """A goal's task gains in physical units, scaled by the arm's task-space inertia Λ at the
    posture (cpbc.taskspace.gains): K_p = ω_n² Λ, D_x = 2 ζ ω_n Λ; the orientation spring
    at ``rotation_omega_n`` (ω_n when omitted). The bounded laws (bpbc, bpbc_ke) saturate the
    position spring beyond 1/``xi`` [m] and the task damping beyond 1/``gamma`` [m/s]."""

    omega_n: Positive = Field(
        default=8.0, description=(
            "natural frequency of the position spring [rad/s]: K_p = ω_n² Λ"))
    zeta: Positive = Field(
        default=1.0, description="damping ratio of the task damping: D_x = 2 ζ ω_n Λ")
    rotation_omega_n: Positive | None = Field(
        default=None, description=(
            "natural frequency of the orientation spring [rad/s]; omega_n when omitted"))
    xi: Positive = Field(
        default=10.0, description=(
            "bpbc, bpbc_ke: the position spring saturates beyond 1/xi [1/m]"))
    gamma: Positive = Field(
        default=10.0, description=(
            "bpbc, bpbc_ke: the task damping saturates beyond 1/gamma [s/m]"))


class PostureGainsSpec(Strict):
    """A goal's posture spring and joint damping: K_n = ω_n² D_ii, K_D = 2 ζ ω_n D_ii at the
    posture. Never off (it keeps the law's V a barrier on the boundary of S)."""

    omega_n: Positive = Field(
        default=2.0, description=(
            "natural frequency of the posture spring [rad/s]: K_n = ω_n² D_ii"))
    zeta: Positive = Field(
        default=1.0, description=(
            "damping ratio of the joint damping: K_D = 2 ζ ω_n D_ii"))


class GainsSpec(Strict):
    """K_P, K_D directly (``kp``, ``kd``), or in physical terms: a natural frequency
    ``omega_n`` [rad/s] and damping ratio ``zeta`` per coordinate (or one for all), scaled by
    the arm's inertia at the target: K_P,i = D_ii(x_d) ω_n,i², K_D,i = 2 ζ_i ω_n,i D_ii(x_d)
    (see cpbc.scenario.gains)."""

    # omega_n and zeta come first so that kp's and kd's checks see them (info.data)
    omega_n: Gain | None = Field(
        default=None, description=(
            "natural frequency per coordinate, or one for all [rad/s]: K_P,i = D_ii(x_d) "
            "ω_n,i²"))
    zeta: Gain | None = Field(
        default=None, description=(
            "damping ratio per coordinate, or one for all: K_D,i = 2 ζ_i ω_n,i D_ii(x_d)"))
    kp: Gain | None = Field(
        default=None, description=(
            "K_P: one number or one per coordinate (instead of omega_n, zeta)"))
    kd: Gain | None = Field(
        default=None, description=(
            "K_D: one number or one per coordinate (instead of omega_n, zeta)"))
    # with a scenario goal: the task and posture gains in place of kp, kd
    task: TaskGainsSpec | None = Field(
        default=None, description=(
            "with a scenario goal: the task gains in place of kp, kd"))
    posture: PostureGainsSpec | None = Field(
        default=None, description=(
            "with a scenario goal: the posture gains in place of kp, kd"))
    on_infeasible: Literal["stop", "rejoin"] | None = Field(
        default=None, description=(
            "with a scenario reference: this law's governor policy in place of "
            "reference.governor.on_infeasible (to compare stop and rejoin in one scenario)"))
    reference_speed: Positive | None = Field(
        default=None, description=(
            "with a scenario reference: this law's path runs this many times its nominal "
            "speed (to compare speeds in one scenario); 1 when omitted"))

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
    type: Literal["pd", "pd_gravity"] = Field(
        description=(
            "pd: −K_P x̃ − K_D ẋ (the thesis's baseline); pd_gravity: g − K_P x̃ − K_D ẋ "
            "(6.10). Constraints are only monitored"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))


class CPBCSpec(GainsSpec):
    type: Literal["cpbc", "cpbc_ke"] = Field(
        description=(
            "cpbc: Theorem 6.9, any configuration and velocity constraints; cpbc_ke: "
            "Corollary 6.11, configuration constraints and one kinetic_energy_limit"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    shaping: ShapingSpec | None = Field(
        default=None, description=(
            "the barrier's shaping s: identity, power (α) or tanh (σ)"))
    # names of scenario constraints; all when omitted
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


class RecentredSpec(GainsSpec):
    type: Literal["recentred"] = Field(
        description=(
            "the re-centred barrier (Cases 2–3, eqs. 6.53–6.65): joint_position_limit and "
            "velocity constraints"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


class BPBCSpec(GainsSpec):
    type: Literal["bpbc", "bpbc_ke"] = Field(
        description=(
            "bpbc: Theorem 7.7, bounded torque, a joint_rate_limit on every joint; bpbc_ke: "
            "Corollary 7.8, one kinetic_energy_limit"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    xi: Gain = Field(
        default=1.0, description=(
            "Ξ of the ln cosh potential: one number or one per coordinate"))
    gamma: Gain = Field(
        default=1.0, description=(
            "Γ of the K_D tanh(Γẋ) damping: one number or one per coordinate"))
    shaping: ShapingSpec | None = Field(
        default=None, description=(
            "the barrier's shaping s: identity, power (α) or tanh (σ)"))
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


class CBFQPSpec(GainsSpec):
    """The CBF-QP peer (cpbc.peers.cbf_qp): PD + gravity filtered by a QP."""

    type: Literal["cbf_qp"] = Field(
        description=(
            "the torque-level CBF-QP safety filter around PD + gravity (needs the peers "
            "extra)"))
    name: RunName | None = Field(
        default=None, description=(
            "the controller's name in the output; the type when omitted"))
    # cpbc.peers.cbf_rows
    variant: Literal["braking", "exponential"] = Field(
        default="braking", description=(
            "braking (default) or exponential: the earlier filter"))
    # k [1/s]: α'(0) of the braking rows, or the exponential poles
    gain: Positive = Field(
        default=20.0, description=(
            "k [1/s]: α'(0) of the braking rows, or the exponential variant's double pole"))
    # γ of the first-order rows [1/s]; 1/(2h) when omitted
    rate_gain: Positive | None = Field(
        default=None, description=(
            "γ of the first-order rows [1/s]; 1/(2h) when omitted"))
    # β: share of the box's deceleration
    braking_share: float = Field(
        default=0.5, gt=0, le=1, description=(
            "β ∈ (0, 1]: the share of the torque box's deceleration a braking row counts on"))
    # c on rate rows; 2e-3 (h/1 ms)^1.7
    rate_cushion: float | None = Field(
        default=None, ge=0, description=(
            "c on rate rows [rad/s]; 2e-3 (h / 1 ms)^1.7 when omitted"))
    constraints: list[str] | None = Field(
        default=None, description=(
            "the scenario constraints it enforces, by name; all when omitted"))


ControllerSpec = Annotated[
    PDSpec | CPBCSpec | RecentredSpec | BPBCSpec | CBFQPSpec, Field(discriminator="type")
]


class AxisSpec(Strict):
    """The tool axis ``tool`` (frame axes) along the world axis ``world``; yaw about it free."""

    tool: Vector = Field(description="the tool axis, in the frame's axes")
    world: Vector = Field(description="the world axis the tool axis points along")


class OrientationSpec(Strict):
    """A goal orientation: exactly one of ``rpy`` [rad], ``quat`` (w, x, y, z) or ``axis``."""

    rpy: Vector | None = Field(default=None, description="roll, pitch, yaw [rad]")
    quat: Vector | None = Field(default=None, description="quaternion (w, x, y, z)")
    axis: AxisSpec | None = Field(
        default=None, description=(
            "a tool axis along a world axis, yaw about it free"))


class ToleranceSpec(Strict):
    """The band of ``reached``: position [m] and angle [rad]."""

    position: Positive = Field(default=0.002, description="position band of reached [m]")
    angle: Positive = Field(default=0.02, description="angle band of reached [rad]")


class GoalSpec(Strict):
    """A frame's goal pose instead of a joint target (cpbc.taskspace)."""

    frame: str = Field(description="the model frame sent to the goal")
    offset: Vector | None = Field(
        default=None, description=(
            "the point in the frame [m] (a TCP); the frame's origin when omitted"))
    position: Vector = Field(description="the goal position in the world [m]")
    orientation: OrientationSpec | None = Field(
        default=None, description=(
            "the goal orientation: one of rpy, quat or axis; none: position only"))
    tolerance: ToleranceSpec = Field(default=ToleranceSpec(), description="the band of reached")
    posture: Literal["ik", "start"] | Vector = Field(
        default="ik", description=(
            "the posture spring's rest: ik (an IK solution, the default), start (the case's "
            "start) or joint values"))


class WaypointSpec(Strict):
    """One waypoint of a reference: its path time and position."""

    time: NonNegative = Field(description="the path time of the waypoint [s], the first 0")
    position: Vector = Field(description="the frame point's position in the world [m]")


class WaypointsPathSpec(Strict):
    """Through waypoints at their times, interpolated per segment."""

    points: Annotated[list[WaypointSpec], Field(min_length=2)] = Field(
        description="the waypoints, at strictly increasing times starting at 0")
    interpolation: Literal["min_jerk", "linear", "cubic"] = Field(
        default="min_jerk", description=(
            "min_jerk (at rest at every waypoint), linear, or cubic (a C² spline)"))


class CirclePathSpec(Strict):
    """A circle at constant speed."""

    centre: Vector = Field(description="the circle's centre in the world [m]")
    radius: Positive = Field(description="the radius [m]")
    normal: Vector = Field(default=[0.0, 0.0, 1.0], description="the plane's normal")
    speed: Positive = Field(description="the nominal speed along the circle [m/s]")
    laps: Positive = Field(default=1.0, description="how many laps")
    phase: Number = Field(default=0.0, description="the start angle from start_axis [rad]")
    start_axis: Vector | None = Field(
        default=None, description=(
            "the direction of the start point from the centre (projected into the plane); "
            "the world axis least aligned with the normal when omitted"))


class LissajousPathSpec(Strict):
    """p_i = c_i + A_i sin(2π f_i s / T + φ_i) (a figure-8: frequency [1, 2, 0])."""

    centre: Vector = Field(description="the centre in the world [m]")
    amplitude: Vector = Field(description="the amplitude per world axis [m]")
    frequency: Vector = Field(description="the frequency per axis, in periods of T")
    period: Positive = Field(description="T, the nominal period [s]")
    phase: Vector | None = Field(default=None, description="φ per axis [rad]; 0 when omitted")
    laps: Positive = Field(default=1.0, description="how many periods")


class PathSpec(Strict):
    """The reference path: exactly one of waypoints, circle, lissajous or csv."""

    waypoints: WaypointsPathSpec | None = Field(default=None, description="through waypoints")
    circle: CirclePathSpec | None = Field(default=None, description="a circle")
    lissajous: LissajousPathSpec | None = Field(default=None, description="a Lissajous curve")
    csv: str | None = Field(
        default=None, description=(
            "a CSV file (header t,x,y,z; t from 0, strictly increasing), relative to the "
            "scenario file; linear between rows"))

    @model_validator(mode="after")
    def _exactly_one(self) -> PathSpec:
        given = [k for k in ("waypoints", "circle", "lissajous", "csv")
                 if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of waypoints, circle, lissajous or csv, got "
                             f"{given or 'none'}")
        return self


class GovernorSpec(Strict):
    """The reference governor on the path time (cpbc.reference.governor)."""

    budget: Positive = Field(
        default=1.0, description="Γ: the budget of the law's normalised V̄ [J]")
    gain: Positive = Field(default=20.0, description="κ: the progress gain [1/s]")
    catch_up: Annotated[Number, Field(ge=1)] = Field(
        default=1.5, description="ρ_max: the path clock's rate while behind (≥ 1)")
    max_speed: Positive = Field(
        default=1.0, description="v_max: the applied reference's speed cap [m/s]")
    margin: NonNegative = Field(
        default=0.03, description=(
            "δ: the posture path's least configuration margin; samples below it are "
            "inadmissible"))
    on_infeasible: Literal["stop", "rejoin"] = Field(
        default="stop", description=(
            "at an inadmissible stretch: stop (stay before it) or rejoin (wait until the "
            "path is past it, then carry on from its end)"))


class ReferenceSpec(Strict):
    """A frame's moving reference instead of a joint target or a goal (cpbc.reference)."""

    frame: str = Field(description="the model frame that follows the path")
    offset: Vector | None = Field(
        default=None, description=(
            "the point in the frame [m] (a TCP); the frame's origin when omitted"))
    path: PathSpec = Field(description="the path of the frame's point")
    orientation: OrientationSpec | None = Field(
        default=None, description=(
            "the orientation held along the path: one of rpy, quat or axis; none: position "
            "only"))
    tolerance: ToleranceSpec = Field(
        default=ToleranceSpec(), description=(
            "the band of tracked at the path's end, and the most the start may be from the "
            "first sample"))
    feedforward: Literal["none", "velocity"] = Field(
        default="velocity", description=(
            "velocity: the task damping reads the applied reference's velocity; none: zero"))
    governor: GovernorSpec = Field(
        default=GovernorSpec(), description="the reference governor on the path time")


class Scenario(Strict):
    """A whole scenario: robot, simulation, target or goal, cases, constraints, controllers."""

    name: SafeName = Field(description="the scenario's name: letters, digits, _ . + -")
    description: str = Field(default="", description="free text")
    robot: RobotSpec = Field(default=RobotSpec(), description="the arm")
    simulation: SimulationSpec = Field(description="the simulation and the loop")
    target: Vector | None = Field(
        default=None, description=(
            "the joint target x_d in controller coordinates; numbers may be expressions of pi"
            " (give target or goal)"))
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


# -- Part I systems (a ``system:`` block in place of ``robot:``) ---------------------------
StrictBool = Annotated[bool, Field(strict=True)]


class SuspensionGainsSpec(Strict):
    """The design constants of §3.3.3 (Theorem 3.6), under the thesis's names."""

    k1: Positive = Field(default=3.5, description="k1 of §3.3.3 (Theorem 3.6)")
    k2: Positive = Field(default=0.051, description="k2 of §3.3.3 (Theorem 3.6)")
    k3: Positive = Field(default=0.07, description="k3 of §3.3.3 (Theorem 3.6)")
    k4: Positive = Field(default=50.0, description="k4 of §3.3.3 (Theorem 3.6)")
    c1: Positive = Field(default=0.049, description="c1 of §3.3.3 (Theorem 3.6)")
    c2: Positive = Field(default=300.0, description="c2 of §3.3.3 (Theorem 3.6)")
    c3: Positive = Field(default=500.0, description="c3 of §3.3.3 (Theorem 3.6)")


class SuspensionLawSpec(Strict):
    """The law (3.88); ``barrier: false`` is the same law with ½k3 z1² in place of the log
    barrier (no travel guarantee), the unconstrained comparison."""

    name: RunName = Field(description="the law's name in the output")
    barrier: StrictBool = Field(
        default=True, description=(
            "the log barrier on the travel; false: ½k3 z1² in its place (no travel guarantee)"))
    gains: SuspensionGainsSpec = Field(
        default=SuspensionGainsSpec(), description="the design constants")


class QuarterCarSpec(Strict):
    """The active quarter car of §3.3 over a haversine bump (its height is per case).
    ω and ρ are the built-in MJCF's (§3.3.3)."""

    type: Literal["quarter_car"] = Field(
        description=(
            "the active quarter car of §3.3 over a haversine bump"))
    # Ξ [m]
    travel_limit: Positive = Field(default=0.1, description="Ξ, the suspension travel limit [m]")
    # l [m]
    bump_length: Positive = Field(default=2.0, description="l, the bump's length [m]")
    # v [m/s]
    speed: Positive = Field(default=25.0, description="v, the car's speed [m/s]")
    laws: Annotated[list[SuspensionLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


class WheelPendulumGainsSpec(Strict):
    """The design constants of §3.5.3 (Proposition 3.11), under the thesis's names."""

    k1: Positive = Field(default=57.5e-3, description="k1 of §3.5.3 (Proposition 3.11)")
    k2: Positive = Field(default=2.225, description="k2 of §3.5.3 (Proposition 3.11)")
    k3: Positive = Field(default=0.25, description="k3 of §3.5.3 (Proposition 3.11)")
    k4: Positive = Field(default=0.501, description="k4 of §3.5.3 (Proposition 3.11)")
    c1: Positive = Field(default=0.5, description="c1 of §3.5.3 (Proposition 3.11)")
    c2: Positive = Field(default=1.0, description="c2 of §3.5.3 (Proposition 3.11)")


class WheelPendulumLawSpec(Strict):
    name: RunName = Field(description="the law's name in the output")
    gains: WheelPendulumGainsSpec = Field(
        default=WheelPendulumGainsSpec(), description=(
            "the design constants"))


class ReactionWheelSpec(Strict):
    """The reaction wheel pendulum of §3.5 (the built-in MJCF's d's, §3.5.3)."""

    type: Literal["reaction_wheel_pendulum"] = Field(
        description=(
            "the reaction wheel pendulum of §3.5"))
    # on |q̇1| [rad/s]
    rate_limit: Positive = Field(
        default=1.0, description="bound on the pendulum's rate |q̇1| [rad/s]")
    # on |τ| [N m]
    torque_limit: Positive = Field(default=0.4, description="bound on the wheel torque |τ| [N·m]")
    laws: Annotated[list[WheelPendulumLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


class ChainGainsSpec(Strict):
    """The design constants of §4.4 (Theorem 4.12, manual tuning), under the thesis's names,
    read as PART1 Ch. 4 §2.6 reading H1 (see cpbc.backstepping.integrator_chain)."""

    c1: Positive = Field(
        default=0.5 / math.pi, description="c1 of §4.4 (Theorem 4.12, manual tuning)")
    c2: Positive = Field(default=1.0, description="c2 of §4.4 (Theorem 4.12, manual tuning)")
    c3: Positive = Field(default=50.0, description="c3 of §4.4 (Theorem 4.12, manual tuning)")
    c4: Positive = Field(default=1.0, description="c4 of §4.4 (Theorem 4.12, manual tuning)")
    k1: Positive = Field(default=1.0, description="k1 of §4.4 (Theorem 4.12, manual tuning)")
    k2: Positive = Field(default=2.0, description="k2 of §4.4 (Theorem 4.12, manual tuning)")
    k3: Positive = Field(default=3.0, description="k3 of §4.4 (Theorem 4.12, manual tuning)")
    k4: Positive = Field(default=5.61, description="k4 of §4.4 (Theorem 4.12, manual tuning)")
    k5: Positive = Field(default=1.0, description="k5 of §4.4 (Theorem 4.12, manual tuning)")
    k6: Positive = Field(default=354.5, description="k6 of §4.4 (Theorem 4.12, manual tuning)")
    k7: Positive = Field(default=10.0, description="k7 of §4.4 (Theorem 4.12, manual tuning)")


class ChainLawSpec(Strict):
    name: RunName = Field(description="the law's name in the output")
    gains: ChainGainsSpec = Field(default=ChainGainsSpec(), description="the design constants")


class IntegratorChainSpec(Strict):
    """The 4th-order integrator chain of §4.4 (4.92): an ODE, no MuJoCo model; ``limits``
    are Ξ on |ξ2|, |ξ3|, |ξ4| (4.93), ξ1 is unconstrained."""

    type: Literal["integrator_chain"] = Field(
        description=(
            "the 4th-order integrator chain of §4.4 (4.92), an ODE"))
    limits: Annotated[list[Positive], Field(min_length=3, max_length=3)] = Field(
        default=[2.5, 12.0, 700.0], description=(
            "Ξ2, Ξ3, Ξ4 on |ξ2|, |ξ3|, |ξ4| (4.93)"))
    laws: Annotated[list[ChainLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


class TraditionalAltitudeGainsSpec(Strict):
    """c1 … c4 of §5.3.1 (the law (5.30))."""

    c1: Positive = Field(default=1.5, description="c1 of §5.3.1 (the law 5.30)")
    c2: Positive = Field(default=10.0, description="c2 of §5.3.1 (the law 5.30)")
    c3: Positive = Field(default=5.0, description="c3 of §5.3.1 (the law 5.30)")
    c4: Positive = Field(default=0.1, description="c4 of §5.3.1 (the law 5.30)")


class ConstrainedAltitudeGainsSpec(Strict):
    """c1 … c4, k1 … k3 of §5.4.3 (the law (5.61)); k2 + c1 must not exceed the climb-rate
    limit B, and k2 > c1 (Theorem 5.5)."""

    c1: Positive = Field(default=1.5, description="c1 of §5.4.3 (the law 5.61)")
    c2: Positive = Field(default=1.0, description="c2 of §5.4.3 (the law 5.61)")
    c3: Positive = Field(default=5.0, description="c3 of §5.4.3 (the law 5.61)")
    c4: Positive = Field(default=10.0, description="c4 of §5.4.3 (the law 5.61)")
    k1: Positive = Field(default=1.5, description="k1 of §5.4.3 (the law 5.61)")
    k2: Positive = Field(default=2.0, description="k2 of §5.4.3 (the law 5.61)")
    k3: Positive = Field(default=0.5, description="k3 of §5.4.3 (the law 5.61)")


class TraditionalAltitudeLawSpec(Strict):
    """§5.3's traditional backstepping law: nothing bounds the climb rate."""

    type: Literal["traditional"] = Field(description="§5.3's traditional backstepping law")
    name: RunName = Field(description="the law's name in the output")
    gains: TraditionalAltitudeGainsSpec = Field(
        default=TraditionalAltitudeGainsSpec(), description=(
            "the design constants"))


class ConstrainedAltitudeLawSpec(Strict):
    """§5.4's law with the log barrier on the climb-rate error: |v_z| < k2 + c1."""

    type: Literal["constrained"] = Field(
        description=(
            "§5.4's law with the log barrier on the climb rate"))
    name: RunName = Field(description="the law's name in the output")
    gains: ConstrainedAltitudeGainsSpec = Field(
        default=ConstrainedAltitudeGainsSpec(), description=(
            "the design constants"))


AltitudeLawSpec = Annotated[TraditionalAltitudeLawSpec | ConstrainedAltitudeLawSpec,
                            Field(discriminator="type")]


class AerosondeSpec(Strict):
    """The Aerosonde UAV of Chapter 5 (AeroSim's longitudinal model, an ODE plant: the
    reference backend only). ``air_density`` and ``mass`` are what the laws' design model
    assumes and the aircraft's mass (the thesis gives neither); ``air_density`` defaults to
    ISA at each case's start altitude. Each case's ``state`` is [altitude [m], climb rate
    [m/s]]: level trim at ``airspeed`` with the velocity turned to that climb rate."""

    type: Literal["aerosonde"] = Field(
        description=(
            "the Aerosonde UAV of Chapter 5 (AeroSim's longitudinal model; reference backend "
            "only)"))
    # v_T [m/s], held by the airspeed loop on thrust
    airspeed: Positive = Field(
        default=23.0, description="v_T, held by the airspeed loop on thrust [m/s]")
    # B [m/s]
    climb_rate_limit: Positive = Field(default=3.5, description="B, the bound on |v_z| [m/s]")
    # [rad] (57.3°)
    elevator_limit: Positive = Field(default=1.0, description="the elevator's travel [rad]")
    # ρ of the design model [kg/m³]
    air_density: Positive | None = Field(
        default=None, description=(
            "ρ of the laws' design model [kg/m³]; ISA at each case's start altitude when "
            "omitted"))
    # [kg] (AeroSim gross; 8.5 empty)
    mass: Positive = Field(
        default=13.5, description="the aircraft's mass [kg] (AeroSim gross; 8.5 empty)")
    laws: Annotated[list[AltitudeLawSpec], Field(min_length=1)] = Field(
        description=(
            "the laws compared"))


SystemSpec = Annotated[QuarterCarSpec | ReactionWheelSpec | IntegratorChainSpec | AerosondeSpec,
                       Field(discriminator="type")]


class SystemSimulationSpec(Strict):
    """``control_period`` defaults to the timestep; ``tolerance`` judges convergence on the
    components the system names (the pendulum, not its wheel)."""

    duration: Positive = Field(description="simulated time of each run [s]")
    timestep: Positive = Field(default=0.001, description="physics or output timestep [s]")
    control_period: Positive | None = Field(
        default=None, description=(
            "control period [s]; the timestep when omitted"))
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = Field(
        default="RK4", description=(
            "MuJoCo's integrator"))
    backend: Literal["mujoco", "reference"] = Field(
        default="mujoco", description=(
            "mujoco or reference (solve_ivp on the system's ODE)"))
    tolerance: Positive = Field(
        default=0.01, description=(
            "convergence band on the components the system names"))
    max_steps: Annotated[int, Field(ge=1, strict=True)] = Field(
        default=10_000_000, description=(
            "steps per run above which the scenario is refused"))


class AltitudeCommandSpec(Strict):
    """A step of the altitude command: h_d = ``altitude`` [m] from ``time`` [s] on."""

    time: NonNegative = Field(description="when the command starts [s]")
    altitude: Number = Field(description="h_d from then on [m]")


class SystemCaseSpec(Strict):
    """An initial state x(0) in the system's own state (see cpbc.systems); the quarter car's
    cases give the bump height A [m], the Aerosonde's the altitude commands (h_d is the
    start altitude until the first)."""

    name: CaseName = Field(description="the case's name (a folder name of the output)")
    state: Vector = Field(
        description=(
            "the initial state x(0) in the system's own coordinates (see cpbc.systems)"))
    bump_height: NonNegative | None = Field(
        default=None, description="quarter car: the bump height A [m]")
    commands: list[AltitudeCommandSpec] | None = Field(
        default=None, description=(
            "Aerosonde: the altitude command steps (h_d is the start altitude until the "
            "first)"))


class SystemScenario(Strict):
    """A Part I scenario: a system with its laws, simulation and cases."""

    name: SafeName = Field(description="the scenario's name: letters, digits, _ . + -")
    description: str = Field(default="", description="free text")
    system: SystemSpec = Field(description="the Part I system and its laws")
    simulation: SystemSimulationSpec = Field(description="the simulation")
    cases: Annotated[list[SystemCaseSpec], Field(min_length=1, max_length=MAX_CASES)] = Field(
        description=(
            "initial states; every law runs on every case"))
