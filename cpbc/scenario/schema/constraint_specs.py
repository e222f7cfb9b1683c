"""The constraints of an arm scenario: the ``constraints:`` items."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from cpbc.scenario.schema.common import NonNegative, Positive, Strict, Vector

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
