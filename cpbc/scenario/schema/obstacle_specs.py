"""The obstacles of an arm scenario: the ``obstacles:`` items."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from cpbc.scenario.schema.common import Positive, SafeName, Strict, Vector


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
