"""The scenario's ``type: clearance``: every link, covered by spheres or capsules, kept clear of
the scene's obstacles (and declared link pairs of each other): a Clearance. The package
exports its ``KINDS`` (cpbc.constraints.constraint_kind)."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from cpbc.arrays import Array
from cpbc.constraints.clearance.constraint import Clearance
from cpbc.constraints.clearance.unclearable import unclearable
from cpbc.constraints.constraint_kind import ConstraintEntrySpec, ConstraintInputs, ConstraintKind
from cpbc.constraints.cover_cache import cached_cover, cached_point_cover
from cpbc.constraints.covering import (
    LinkPrimitive,
    geoms_points,
    link_points,
    moving_frames,
    surface_points,
    uncovered,
)
from cpbc.errors import CpbcError, ScenarioError
from cpbc.model.robot_model import RobotModel
from cpbc.spec.fields import NonNegative, Positive, Strict, Vector


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


class ClearanceSpec(ConstraintEntrySpec):
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
            "collision geometry when omitted (less the cover primitives no configuration "
            "takes 1 cm clear of an obstacle, as at a floor the arm stands on: the run says "
            "which), none with []"))
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


def _declared(spec: ClearanceSpec, model: RobotModel, field: str) -> list[LinkPrimitive]:
    declared = []
    per_link: dict[str, int] = {}
    for p in spec.primitives or []:
        per_link[p.link] = per_link.get(p.link, 0) + 1
    for i, p in enumerate(spec.primitives or []):
        f = f"{field}.primitives[{i}]"
        if p.link not in {fr.name for fr in model.model.frames}:
            frames = [fr.name for fr in model.model.frames if fr.parentJoint > 0]
            raise ScenarioError(f"{f}.link", f"the robot has no link '{p.link}'; links: {frames}")
        start = p.centre if p.centre is not None else p.start
        end = p.centre if p.centre is not None else p.end
        if start is None or end is None:
            raise ScenarioError(f, "give 'centre' (a sphere) or 'start' and 'end' (a capsule)")
        try:
            label = p.name or (p.link if per_link[p.link] == 1 else f"{p.link}#{i}")
            declared.append(LinkPrimitive(label, p.link, np.asarray(start, dtype=float),
                                          np.asarray(end, dtype=float), p.radius))
        except CpbcError as exc:
            raise ScenarioError(f, str(exc)) from None
    return declared


#: How far a link's collision geometry may reach outside its declared primitives before the
#: run warns [m].
UNCOVERED_SLACK = 0.001


def _collision_points(given: ConstraintInputs) -> dict[str, Array]:
    """Each link's collision points in its frame: a URDF arm's meshes and shapes, or an
    MJCF's colliding geoms."""
    if given.arm is not None:
        return link_points(given.arm.model, given.arm.collision_model)
    return geoms_points(given.collision() if given.collision is not None else ())


def _uncovered(declared: list[LinkPrimitive], given: ConstraintInputs
               ) -> tuple[tuple[str, float], ...]:
    """The declared links whose collision geometry reaches more than UNCOVERED_SLACK
    outside their primitives, and by how much."""
    if not declared:
        return ()
    try:
        points = _collision_points(given)
    except CpbcError:  # a geometry no cover holds: nothing to check the declared against
        return ()
    out = []
    for link in dict.fromkeys(p.frame for p in declared):
        if link in points:
            gap = uncovered(surface_points(points[link]), [p for p in declared
                                                           if p.frame == link])
            if gap > UNCOVERED_SLACK:
                out.append((link, gap))
    return tuple(out)


def _automatic(spec: ClearanceSpec, given: ConstraintInputs) -> list[LinkPrimitive]:
    """The cover of the links' collision geometry: a URDF arm's meshes and shapes, or an
    MJCF's colliding geoms."""
    arm = given.arm
    if arm is not None:
        return cached_cover(arm.model, arm.collision_model, spec.links, spec.padding,
                            spec.cover, spec.cover_tolerance)
    points = geoms_points(given.collision() if given.collision is not None else ())
    if not points and spec.links is None and not spec.primitives:
        raise CpbcError("no moving body of the model has a colliding geom (contype or "
                        "conaffinity non-zero) to cover; declare 'primitives'")
    return cached_point_cover(points, moving_frames(given.model.model), spec.links,
                              spec.padding, spec.cover, spec.cover_tolerance)


def _primitives(spec: ClearanceSpec, given: ConstraintInputs) -> list[LinkPrimitive]:
    declared = _declared(spec, given.model, given.field)
    if spec.links == []:
        return declared
    taken = {p.frame for p in declared}
    try:
        auto = _automatic(spec, given)
    except CpbcError as exc:
        raise ScenarioError(f"{given.field}.links", str(exc)) from None
    return declared + [p for p in auto if p.frame not in taken]


def build(spec: ClearanceSpec, given: ConstraintInputs) -> Clearance:
    """The clearance constraint of a scenario entry."""
    obstacles = given.obstacles or {}
    model, field = given.model, given.field
    names = list(obstacles) if spec.obstacles is None else spec.obstacles
    unknown = [o for o in names if o not in obstacles]
    if unknown:
        raise ScenarioError(f"{field}.obstacles",
                            f"unknown obstacles {unknown}; the scenario has {list(obstacles)}")
    prims = _primitives(spec, given)
    left_out: list[tuple[str, str]] = []
    if spec.links is None:  # the default: every covered link
        declared, auto = prims[:len(spec.primitives or [])], prims[len(spec.primitives or []):]
        left_out = unclearable(model.model, auto, [obstacles[o] for o in names], spec.margin)
        dropped = {name for name, _ in left_out}
        prims = declared + [p for p in auto if p.name not in dropped]
    covered = sorted({p.frame for p in prims})
    for i, (a, b) in enumerate(spec.self_collision):
        missing = [f for f in (a, b) if f not in covered]
        if missing or a == b:
            why = (f"no primitive on link '{missing[0]}'; links with primitives: {covered}"
                   if missing else "names one link twice")
            raise ScenarioError(f"{field}.self_collision[{i}]", f"pair ({a}, {b}): {why}")
    try:
        built = Clearance(model, prims, [obstacles[o] for o in names], spec.margin,
                          spec.influence, [(p[0], p[1]) for p in spec.self_collision],
                          spec.name)
        built.left_out = tuple(left_out)
        built.uncovered = _uncovered(prims[:len(spec.primitives or [])], given)
        return built
    except CpbcError as exc:
        parameter = getattr(exc, "parameter", None)
        raise ScenarioError(f"{field}.{parameter}" if parameter else field, str(exc)) from None


# The example covers the planar arm's second link by one declared sphere (it has no meshes).
KINDS = (ConstraintKind(ClearanceSpec, build, Clearance, {"clearance": {
    "links": [], "primitives": [{"link": "link2", "centre": [1, 0, 0], "radius": 0.05}]}}),)
