"""The YAML scenario format, validated with pydantic. Every error names its field."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field

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
# Names become folder names of the output: one path component, no "." or "..".
SafeName = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class RobotSpec(Strict):
    """The arm. ``model`` is a built-in name (see cpbc.resources) or a path to an MJCF file,
    relative to the scenario file. ``coordinates`` are the controller's: ``joint`` (the
    model's own), ``absolute`` (absolute link angles θ = T q of a planar chain) or a matrix T.
    ``viscous_friction`` is F_d (diagonal, joint coordinates) in the plant and the model."""

    model: str = "planar_2link"
    coordinates: Literal["joint", "absolute"] | list[Vector] = "joint"
    viscous_friction: NonNegative | list[NonNegative] = 0.0


class SimulationSpec(Strict):
    duration: Positive
    timestep: Positive = 0.001
    control_period: Positive | None = None
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = "RK4"
    backend: Literal["mujoco", "reference"] = "mujoco"
    torque_limit: Positive | list[Positive] | None = None
    log_every: Annotated[int, Field(ge=1)] = 1
    position_tolerance: Positive = 0.01
    velocity_tolerance: Positive = 0.005


class CaseSpec(Strict):
    name: SafeName
    position: Vector
    velocity: Vector | None = None


# -- constraints --------------------------------------------------------------------------
class JointPositionLimitSpec(Strict):
    type: Literal["joint_position_limit"]
    name: str = "joint_position_limit"
    joints: list[str] | None = None
    lower: Vector
    upper: Vector


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
    bounds: list[Positive]


class RateLimitSpec(Strict):
    type: Literal["rate_limit"]
    name: str = "rate_limit"
    coefficients: list[Vector]
    bounds: list[Positive]


class KineticEnergyLimitSpec(Strict):
    type: Literal["kinetic_energy_limit"]
    name: str = "kinetic_energy"
    limit: Positive


ConstraintSpec = Annotated[
    JointPositionLimitSpec
    | LinearLimitSpec
    | PointOutsideSphereSpec
    | JointRateLimitSpec
    | RateLimitSpec
    | KineticEnergyLimitSpec,
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


class PDSpec(Strict):
    type: Literal["pd", "pd_gravity"]
    name: SafeName | None = None
    kp: Gain
    kd: Gain


class CPBCSpec(Strict):
    type: Literal["cpbc", "cpbc_ke"]
    name: SafeName | None = None
    kp: Gain
    kd: Gain
    shaping: ShapingSpec | None = None
    constraints: list[str] | None = None  # names of scenario constraints; all when omitted


class RecentredSpec(Strict):
    type: Literal["recentred"]
    name: SafeName | None = None
    kp: Gain
    kd: Gain
    constraints: list[str] | None = None


class BPBCSpec(Strict):
    type: Literal["bpbc", "bpbc_ke"]
    name: SafeName | None = None
    kp: Gain
    kd: Gain
    xi: Gain = 1.0
    gamma: Gain = 1.0
    shaping: ShapingSpec | None = None
    constraints: list[str] | None = None


ControllerSpec = Annotated[
    PDSpec | CPBCSpec | RecentredSpec | BPBCSpec, Field(discriminator="type")
]


class Scenario(Strict):
    """A whole scenario: robot, simulation, target, cases, constraints, controllers."""

    name: SafeName
    description: str = ""
    robot: RobotSpec = RobotSpec()
    simulation: SimulationSpec
    target: Vector
    cases: Annotated[list[CaseSpec], Field(min_length=1)]
    constraints: list[ConstraintSpec] = []
    controllers: Annotated[list[ControllerSpec], Field(min_length=1)]
