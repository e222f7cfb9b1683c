"""Automatic covers: every point of a link's collision geometry lies inside its primitives."""

from __future__ import annotations

from functools import cache

import coal
import numpy as np
import pinocchio as pin
import pytest

from cpbc.constraints.covering import (
    LinkPrimitive,
    cover_links,
    fit_capsule,
    geometry_points,
    link_points,
    sphere_chain,
)
from cpbc.errors import CpbcError, ModelError
from cpbc.model.loading import LoadedArm, load_arm


@cache
def _arm(name: str) -> LoadedArm:
    return load_arm(name)


def _inside(points: np.ndarray, prims: list[LinkPrimitive], frame: str) -> np.ndarray:
    """Largest (distance to the union of primitives on ``frame``) over the points."""
    mine = [p for p in prims if p.frame == frame]
    gaps = np.min([p.distance_to_points(points) - p.radius for p in mine], axis=0)
    return gaps


def test_fit_capsule_contains_points_and_is_tight(rng: np.random.Generator) -> None:
    # points filling a known capsule along a tilted axis
    axis = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    t = rng.uniform(0, 0.4, 3000)
    radial = rng.normal(size=(3000, 3))
    radial -= (radial @ axis)[:, None] * axis
    radial *= (0.05 * np.sqrt(rng.uniform(0, 1, 3000)) / np.linalg.norm(radial, axis=1))[:, None]
    pts = t[:, None] * axis + radial + np.array([0.1, -0.2, 0.3])
    start, end, radius = fit_capsule(pts)
    prim = LinkPrimitive("p", "f", start, end, radius)
    assert np.all(prim.distance_to_points(pts) <= radius * (1 + 1e-9))
    true_volume = np.pi * 0.05**2 * 0.4 + 4 / 3 * np.pi * 0.05**3
    assert prim.volume < 1.15 * true_volume


def test_a_blob_gets_a_sphere(rng: np.random.Generator) -> None:
    pts = rng.normal(size=(500, 3))
    pts /= np.linalg.norm(pts, axis=1)[:, None]
    start, end, radius = fit_capsule(0.1 * pts)
    assert np.linalg.norm(end - start) < 0.02
    assert radius == pytest.approx(0.1, rel=0.05)


@pytest.mark.parametrize("kind", ["spheres", "capsules"])
@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_cover_contains_every_collision_point(name: str, kind: str) -> None:
    arm = _arm(name)
    prims = cover_links(arm.model, arm.collision_model, kind=kind)
    points = link_points(arm.model, arm.collision_model)
    covered = {p.frame for p in prims}
    moving = {f.name for f in arm.model.frames if f.parentJoint > 0}
    assert covered == {f for f in points if f in moving}  # every moving link, no fixed one
    for frame in covered:
        assert np.all(_inside(points[frame], prims, frame) <= 1e-9), frame
    if kind == "spheres":
        assert all(p.kind == "sphere" for p in prims)


def test_sphere_chain_covers_its_capsule(rng: np.random.Generator) -> None:
    a, b, r = np.array([0.0, 0, 0]), np.array([0.3, 0.1, 0.0]), 0.05
    chain = sphere_chain(a, b, r, tolerance=0.01)
    assert all(rad <= r + 0.01 + 1e-12 for _, rad in chain)
    # points on the capsule's surface
    t = rng.uniform(0, 1, 4000)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    pts = a + t[:, None] * (b - a) + r * d
    gaps = np.min([np.linalg.norm(pts - c, axis=1) - rad for c, rad in chain], axis=0)
    assert np.all(gaps <= 1e-12)
    with pytest.raises(CpbcError, match="tolerance"):
        sphere_chain(a, b, r, tolerance=0.0)


def test_primitive_shapes_are_enclosed() -> None:
    box = pin.GeometryObject("box", 0, pin.SE3.Identity(), coal.Box(0.2, 0.4, 0.6))
    np.testing.assert_allclose(np.abs(geometry_points(box)).max(axis=0), [0.1, 0.2, 0.3])
    for shape in (coal.Cylinder(0.1, 0.4), coal.Sphere(0.1), coal.Capsule(0.1, 0.4)):
        pts = geometry_points(pin.GeometryObject("g", 0, pin.SE3.Identity(), shape))
        start, end, radius = fit_capsule(pts)
        prim = LinkPrimitive("p", "f", start, end, radius)
        # the true shape's extreme points must be inside the fitted cover
        probe = np.array([[0.1, 0, 0.2], [0, 0.1, -0.2], [0.0707, 0.0707, 0.2]])
        if isinstance(shape, coal.Sphere):
            probe = np.array([[0.1, 0, 0], [0, 0, -0.1], [0.0577, 0.0577, 0.0577]])
        if isinstance(shape, coal.Capsule):
            probe = np.array([[0, 0, 0.3], [0.1, 0, 0.2], [0, 0, -0.3]])
        assert np.all(prim.distance_to_points(probe) <= radius + 1e-9), type(shape)


def test_cover_errors() -> None:
    arm = _arm("panda")
    with pytest.raises(ModelError, match="no collision geometry"):
        cover_links(arm.model, arm.collision_model, links=["panda_hand_tcp"])
    with pytest.raises(CpbcError, match="padding"):
        cover_links(arm.model, arm.collision_model, padding=-0.1)
    with pytest.raises(CpbcError, match="cover kind"):
        cover_links(arm.model, arm.collision_model, kind="boxes")
    with pytest.raises(CpbcError, match="radius must be > 0"):
        LinkPrimitive("p", "f", np.zeros(3), np.zeros(3), 0.0)
