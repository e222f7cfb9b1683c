"""Task-space targets of an arm scenario: ``goal:`` (a pose) and ``reference:`` (a path)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    Field,
    model_validator,
)

from cpbc.scenario.schema.common import NonNegative, Number, Positive, Strict, Vector


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
            "the band of tracked at the path's end; a start farther than it from the first "
            "sample is approached first (the run says so)"))
    feedforward: Literal["none", "velocity"] = Field(
        default="velocity", description=(
            "velocity: the task damping reads the applied reference's velocity; none: zero"))
    governor: GovernorSpec = Field(
        default=GovernorSpec(), description="the reference governor on the path time")
