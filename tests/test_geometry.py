"""Exact distances between segments, points, boxes and rounded boxes, against brute force."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.constraints.geometry import (
    BoxObstacle,
    CapsuleObstacle,
    PlaneObstacle,
    SphereObstacle,
    matrix_to_quat,
    point_box,
    point_rounded_box,
    quat_to_matrix,
    rpy_matrix,
    segment_box,
    segment_point,
    segment_segment,
)
from cpbc.errors import CpbcError

T = np.linspace(0.0, 1.0, 401)


def _segments(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    a = rng.normal(size=(m, 3))
    b = a + rng.normal(size=(m, 3)) * rng.uniform(0, 1, (m, 1))
    b[: m // 10] = a[: m // 10]  # some points
    return a, b


def _sample(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, None, :] + T[None, :, None] * (b - a)[:, None, :]


def test_segment_point_is_exact(rng: np.random.Generator) -> None:
    a, b = _segments(rng, 300)
    c = rng.normal(size=(300, 3))
    d, p, n = segment_point(a, b, c)
    brute = np.linalg.norm(_sample(a, b) - c[:, None, :], axis=2).min(axis=1)
    assert np.all(d <= brute + 1e-12)
    assert np.all(d >= brute - 1e-4)  # the sampling's resolution
    np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), d, atol=1e-12)
    np.testing.assert_allclose(p - c, n * d[:, None], atol=1e-12)


def test_segment_segment_is_exact_including_parallel_and_points(
    rng: np.random.Generator,
) -> None:
    a, b = _segments(rng, 200)
    c, e = _segments(rng, 200)
    e[100:140] = c[100:140] + 0.7 * (b - a)[100:140]  # parallel pairs
    d, p, q, _ = segment_segment(a, b, c, e)
    pa, pc = _sample(a, b), _sample(c, e)
    brute = np.linalg.norm(pa[:, :, None, :] - pc[:, None, :, :], axis=3).min(axis=(1, 2))
    assert np.all(d <= brute + 1e-12)
    assert np.all(d >= brute - 1e-4)
    np.testing.assert_allclose(np.linalg.norm(p - q, axis=1), d, atol=1e-12)


def test_segment_box_is_exact_outside_and_negative_inside(rng: np.random.Generator) -> None:
    m = 400
    a, b = _segments(rng, m)
    centre = 0.5 * rng.normal(size=(m, 3))
    rot = np.array([rpy_matrix(r) for r in rng.uniform(-3, 3, (m, 3))])
    half = rng.uniform(0.05, 0.6, (m, 3))
    d, p, c, _ = segment_box(a, b, centre, rot, half)
    local = np.einsum("mji,mtj->mti", rot, _sample(a, b) - centre[:, None, :])
    brute = point_box(local, half[:, None, :])[0].min(axis=1)
    out = brute > 1e-3
    assert out.sum() > 100 and (~out).sum() > 5
    assert np.all(d[out] <= brute[out] + 1e-12)
    assert np.all(d[out] >= brute[out] - 1e-4)
    assert np.all(d[brute < 0] < 0)
    np.testing.assert_allclose(np.linalg.norm(p - c, axis=1)[out], d[out], atol=1e-12)


@pytest.mark.parametrize(
    "obstacle",
    [
        SphereObstacle("s", [0.3, -0.2, 0.5], 0.25),
        CapsuleObstacle("c", [0, 0, 0], [0.4, 0.3, 0.2], 0.1),
        CapsuleObstacle("cy", [0, 0, 0], [0, 0, 0.8], 0.05, kind="cylinder"),
        BoxObstacle("b", [0.2, 0, 0.1], [0.1, 0.3, 0.2], [0.3, -0.2, 1.0]),
        PlaneObstacle("p", [0, 0, 0.2], [0.1, 0.2, 1.0]),
    ],
    ids=lambda o: o.name,
)
def test_every_obstacle_is_a_rounded_box(obstacle, rng: np.random.Generator) -> None:
    pts = rng.normal(size=(200, 3))
    core = obstacle.core()
    u = (pts - core.centre) @ core.rotation
    d, _ = point_rounded_box(u, np.broadcast_to(core.half_extents, u.shape),
                             np.full(len(u), core.rounding))
    if isinstance(obstacle, SphereObstacle):
        ref = np.linalg.norm(pts - obstacle.centre, axis=1) - obstacle.radius
    elif isinstance(obstacle, CapsuleObstacle):
        m = len(pts)
        ref = segment_point(np.tile(obstacle.start, (m, 1)), np.tile(obstacle.end, (m, 1)),
                            pts)[0] - obstacle.radius
    elif isinstance(obstacle, BoxObstacle):
        ref = point_box((pts - obstacle.centre) @ obstacle.rotation, obstacle.half_extents)[0]
    else:
        ref = pts @ obstacle.normal - obstacle.offset
    np.testing.assert_allclose(d, ref, atol=1e-12)


def test_rounded_box_gradient_is_the_unit_normal(central_difference, rng) -> None:
    half, rho = np.array([0.1, 0.2, 0.3]), 0.05
    for _ in range(20):
        u = rng.normal(size=3)
        d, n = point_rounded_box(u[None], half[None], np.array([rho]))
        if d[0] <= 0:
            continue
        grad = central_difference(
            lambda v: point_rounded_box(v[None], half[None], np.array([rho]))[0][0], u)
        np.testing.assert_allclose(grad, n[0], atol=1e-7)


def test_rotations_round_trip(rng: np.random.Generator) -> None:
    for rpy in rng.uniform(-3, 3, (10, 3)):
        r = rpy_matrix(rpy)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(quat_to_matrix(matrix_to_quat(r)), r, atol=1e-12)


def test_scene_geoms_follow_mujoco_conventions() -> None:
    cap = CapsuleObstacle("pole", [0, 0, 0], [0, 0, 1.0], 0.05, kind="cylinder")
    g = cap.scene_geom()
    assert g.kind == "cylinder"
    np.testing.assert_allclose(g.pos, [0, 0, 0.5])
    np.testing.assert_allclose(g.size, [0.05, 0.5])
    plane = PlaneObstacle("floor", [0, 0, -0.1], [0, 0, 2.0])
    np.testing.assert_allclose(plane.normal, [0, 0, 1])
    np.testing.assert_allclose(quat_to_matrix(plane.scene_geom().quat)[:, 2], [0, 0, 1])


def test_obstacles_validate() -> None:
    with pytest.raises(CpbcError, match="radius must be > 0"):
        SphereObstacle("s", [0, 0, 0], 0.0)
    with pytest.raises(CpbcError, match="3 finite numbers"):
        SphereObstacle("s", [0, 0], 0.1)
    with pytest.raises(CpbcError, match="start and end must differ"):
        CapsuleObstacle("c", [1, 1, 1], [1, 1, 1], 0.1)
    with pytest.raises(CpbcError, match="half_extents must be > 0"):
        BoxObstacle("b", [0, 0, 0], [0.1, 0, 0.1])
    with pytest.raises(CpbcError, match="normal must be non-zero"):
        PlaneObstacle("p", [0, 0, 0], [0, 0, 0])
