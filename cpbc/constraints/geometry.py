"""Obstacle shapes and exact, vectorised distances between them and swept-sphere primitives.

A robot primitive is a *capsule*: the set of points within radius r of a segment [a, b]; a
sphere is the capsule with a = b. Obstacles are spheres, capsules, cylinders, boxes and
half-spaces (a floor or table plane). Every distance function here works on stacks of
segments, one row per pair, and returns the distance together with the witness points that
the clearance gradient needs (the envelope theorem: for d(q) = min over the two shapes of
‖p − c‖, ∂d/∂q = n̂ᵀ ∂p/∂q with p, c the closest points held *fixed on their bodies* and
n̂ = (p − c)/‖p − c‖).

Smoothness of d where it is positive (what Remark 6.5 asks of φ = d − Δ):

* segment–point (capsule–sphere): the closest point of a segment to a point is unique, so d
  is C¹ (C^∞ away from the segment's end regions); exact.
* segment–half-space: d = min(n·a, n·b) − h is only Lipschitz where the segment is parallel
  to the plane. :class:`~cpbc.constraints.clearance.Clearance` therefore uses the two end
  spheres as a product of two smooth barriers (same admissible set, smooth).
* segment–segment (capsule–capsule, self-collision): C¹ wherever the closest pair is unique;
  when the two segments are parallel and overlap, d is Lipschitz and directionally
  differentiable, and the gradient returned is that of one closest pair (a generalised
  gradient). Exact.
* segment–box: the distance from a point to a box is C¹ outside the box (the gradient is the
  unit vector from the nearest box point), only its curvature jumps between the Voronoi
  regions of faces, edges and corners — the box's edges and corners need no smoothing. Along
  a segment, the squared distance is a convex piecewise quadratic in the segment parameter
  with at most 6 breakpoints, minimised exactly (see :func:`segment_box`). As for two
  segments, a segment parallel to a face has a non-unique closest point: there d is
  Lipschitz and the gradient is a generalised one. Inside the box the signed distance is
  negative (for monitoring a collision; its depth is then a bound, not exact).
* A cylinder obstacle is enforced through its circumscribing capsule (conservative by at most
  one radius beyond each flat end), since the capsule has an exact smooth distance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import CpbcError

_EPS = 1e-12


def _vec3(value: object, what: str) -> Array:
    a = np.asarray(value, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise CpbcError(f"{what} must be 3 finite numbers, got {value!r}")
    a.setflags(write=False)
    return a


def _radius(value: float, what: str, allow_zero: bool = False) -> float:
    r = float(value)
    if not np.isfinite(r) or r < 0 or (r == 0 and not allow_zero):
        raise CpbcError(f"{what} must be {'≥' if allow_zero else '>'} 0, got {value}")
    return r


def rpy_matrix(rpy: object) -> Array:
    """Rotation matrix of URDF roll-pitch-yaw angles: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = _vec3(rpy, "rpy")
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def matrix_to_quat(rot: Array) -> Array:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    m = np.asarray(rot, dtype=float)
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2
    y = np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2
    z = np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2
    x = np.copysign(x, m[2, 1] - m[1, 2])
    y = np.copysign(y, m[0, 2] - m[2, 0])
    z = np.copysign(z, m[1, 0] - m[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


def quat_to_matrix(quat: Array) -> Array:
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _segment_frame(start: Array, end: Array) -> tuple[Array, Array, float]:
    """Midpoint, quaternion taking z to the segment direction, half-length."""
    axis = end - start
    length = float(np.linalg.norm(axis))
    z = axis / length
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return 0.5 * (start + end), matrix_to_quat(np.column_stack([x, y, z])), 0.5 * length


@dataclass(frozen=True)
class SceneGeom:
    """How to draw or simulate an obstacle, in MuJoCo's conventions (no MuJoCo import here).

    Attributes:
        kind: "sphere", "capsule", "cylinder", "box" or "plane".
        pos: centre [m], shape (3,).
        quat: orientation (w, x, y, z); the local z axis is the capsule/cylinder axis or the
            plane normal.
        size: MuJoCo geom size: (r,), (r, half-length), (r, half-length), half-extents, or
            (0, 0, grid) for a plane.
    """

    kind: str
    pos: Array
    quat: Array
    size: Array


@dataclass(frozen=True)
class RoundedBox:
    """{c + R u : dist(u, box |u_k| ≤ h_k) ≤ ρ}: a box swept by a sphere.

    Every obstacle kind is one: a sphere (h = 0, ρ = r), a capsule (h = (0, 0, L/2), ρ = r),
    a box (ρ = 0) and the half-space below a plane (a box of half-extents H = 100 m whose top
    face is the plane: exact for points within 100 m of its point, to rounding of order
    10⁻¹⁴ m). So the distance from a point to any obstacle is one formula
    (:func:`point_rounded_box`).
    """

    centre: Array
    rotation: Array
    half_extents: Array
    rounding: float


PLANE_HALF_EXTENT = 100.0


class Obstacle:
    """A fixed obstacle in world coordinates.

    Attributes:
        name: label used in constraint names.
        collides: whether it is a physical body in the MuJoCo scene.
    """

    name: str
    collides: bool
    kind: str

    def bounding_sphere(self) -> tuple[Array, float]:
        """Centre and radius of a sphere that contains the obstacle (inf for a plane)."""
        raise NotImplementedError

    def scene_geom(self) -> SceneGeom:
        """The obstacle as a MuJoCo-style geom."""
        raise NotImplementedError

    def core(self) -> RoundedBox:
        """The obstacle as a rounded box (what the clearance of a sphere is computed against)."""
        raise NotImplementedError


@dataclass(frozen=True)
class SphereObstacle(Obstacle):
    """{x : ‖x − c‖ ≤ r}."""

    name: str
    centre: Array
    radius: float
    collides: bool = True
    kind: str = field(default="sphere", init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _vec3(self.centre, f"obstacle '{self.name}' centre"))
        object.__setattr__(self, "radius", _radius(self.radius, f"obstacle '{self.name}' radius"))

    def bounding_sphere(self) -> tuple[Array, float]:
        return self.centre, self.radius

    def scene_geom(self) -> SceneGeom:
        return SceneGeom("sphere", self.centre, np.array([1.0, 0, 0, 0]), np.array([self.radius]))

    def core(self) -> RoundedBox:
        return RoundedBox(self.centre, np.eye(3), np.zeros(3), self.radius)


@dataclass(frozen=True)
class CapsuleObstacle(Obstacle):
    """Points within ``radius`` of the segment [start, end] (a pole with rounded ends).

    ``kind = "cylinder"`` draws and simulates a flat-ended cylinder; the clearance constraint
    then uses this (circumscribing) capsule, which is conservative at the flat ends.
    """

    name: str
    start: Array
    end: Array
    radius: float
    collides: bool = True
    kind: str = "capsule"

    def __post_init__(self) -> None:
        object.__setattr__(self, "start", _vec3(self.start, f"obstacle '{self.name}' start"))
        object.__setattr__(self, "end", _vec3(self.end, f"obstacle '{self.name}' end"))
        object.__setattr__(self, "radius", _radius(self.radius, f"obstacle '{self.name}' radius"))
        if self.kind not in ("capsule", "cylinder"):
            raise CpbcError(f"obstacle '{self.name}': kind must be capsule or cylinder")
        if np.linalg.norm(self.end - self.start) <= 0:
            raise CpbcError(f"obstacle '{self.name}': start and end must differ")

    def bounding_sphere(self) -> tuple[Array, float]:
        half = 0.5 * float(np.linalg.norm(self.end - self.start))
        return 0.5 * (self.start + self.end), half + self.radius

    def scene_geom(self) -> SceneGeom:
        mid, quat, half = _segment_frame(self.start, self.end)
        return SceneGeom(self.kind, mid, quat, np.array([self.radius, half]))

    def core(self) -> RoundedBox:
        mid, quat, half = _segment_frame(self.start, self.end)
        return RoundedBox(mid, quat_to_matrix(quat), np.array([0.0, 0.0, half]), self.radius)


@dataclass(frozen=True)
class BoxObstacle(Obstacle):
    """{centre + R u : |u_k| ≤ h_k}, R from URDF roll-pitch-yaw angles."""

    name: str
    centre: Array
    half_extents: Array
    rpy: Array = field(default_factory=lambda: np.zeros(3))
    collides: bool = True
    kind: str = field(default="box", init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _vec3(self.centre, f"obstacle '{self.name}' centre"))
        h = _vec3(self.half_extents, f"obstacle '{self.name}' half_extents")
        if np.any(h <= 0):
            raise CpbcError(f"obstacle '{self.name}': half_extents must be > 0, got {h.tolist()}")
        object.__setattr__(self, "half_extents", h)
        object.__setattr__(self, "rpy", _vec3(self.rpy, f"obstacle '{self.name}' rpy"))

    @property
    def rotation(self) -> Array:
        return rpy_matrix(self.rpy)

    def bounding_sphere(self) -> tuple[Array, float]:
        return self.centre, float(np.linalg.norm(self.half_extents))

    def scene_geom(self) -> SceneGeom:
        return SceneGeom("box", self.centre, matrix_to_quat(self.rotation), self.half_extents)

    def core(self) -> RoundedBox:
        return RoundedBox(self.centre, self.rotation, self.half_extents, 0.0)


@dataclass(frozen=True)
class PlaneObstacle(Obstacle):
    """The half-space below a plane: {x : n·x ≤ n·p}; the robot must stay on the n side."""

    name: str
    point: Array
    normal: Array = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    collides: bool = True
    kind: str = field(default="plane", init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _vec3(self.point, f"obstacle '{self.name}' point"))
        n = np.array(_vec3(self.normal, f"obstacle '{self.name}' normal"))
        norm = float(np.linalg.norm(n))
        if norm == 0:
            raise CpbcError(f"obstacle '{self.name}': normal must be non-zero")
        n /= norm
        n.setflags(write=False)
        object.__setattr__(self, "normal", n)

    @property
    def offset(self) -> float:
        """h in n·x = h."""
        return float(self.normal @ self.point)

    def bounding_sphere(self) -> tuple[Array, float]:
        return self.point, float("inf")

    def scene_geom(self) -> SceneGeom:
        _, quat, _ = _segment_frame(np.zeros(3), self.normal)
        return SceneGeom("plane", self.point, quat, np.array([0.0, 0.0, 0.05]))

    def core(self) -> RoundedBox:
        _, quat, _ = _segment_frame(np.zeros(3), self.normal)
        h = PLANE_HALF_EXTENT
        return RoundedBox(self.point - h * self.normal, quat_to_matrix(quat), np.full(3, h), 0.0)


# -- distances ------------------------------------------------------------------------------
def _rowdot(a: Array, b: Array) -> Array:
    return (a * b).sum(axis=1)


def _unit(x: Array) -> Array:
    """Clamp to [0, 1] (np.clip costs several times more on small arrays)."""
    return np.minimum(np.maximum(x, 0.0), 1.0)


def segment_point(a: Array, b: Array, c: Array) -> tuple[Array, Array, Array]:
    """Distance from points c to segments [a, b], row by row.

    Args:
        a, b: segment ends, shape (m, 3) (a = b for a sphere).
        c: points, shape (m, 3).

    Returns:
        d (m,), the closest point p on each segment (m, 3) and n̂ = (p − c)/d (m, 3).
    """
    ab = b - a
    den = _rowdot(ab, ab)
    t = _unit(_rowdot(c - a, ab) / np.maximum(den, _EPS))
    p = a + t[:, None] * ab
    diff = p - c
    d = np.sqrt(_rowdot(diff, diff))
    return d, p, diff / np.maximum(d, _EPS)[:, None]


def segment_segment(
    a0: Array, a1: Array, b0: Array, b1: Array
) -> tuple[Array, Array, Array, Array]:
    """Distance between segments [a0, a1] and [b0, b1], row by row (either may be a point).

    Closest points by clamping the unconstrained minimiser in the order of Ericson,
    *Real-Time Collision Detection* §5.1.9.

    Returns:
        d (m,), closest points p on the a-segments and c on the b-segments (m, 3),
        n̂ = (p − c)/d (m, 3).
    """
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e = _rowdot(d1, d1), _rowdot(d2, d2)
    b, c, f = _rowdot(d1, d2), _rowdot(d1, r), _rowdot(d2, r)
    a_s, e_s = np.maximum(a, _EPS), np.maximum(e, _EPS)
    # Parallel segments (denominator ~ 0) give s ∈ {0, 1}; either leads to a closest pair.
    s = _unit((b * f - c * e) / np.maximum(a * e - b * b, 1e-12 * a_s * e_s))
    # A degenerate second segment (a point) forces t = 0 through the clamp below.
    t = np.where(e > _EPS, (b * s + f) / e_s, -1.0)
    tc = _unit(t)
    s = np.where(t == tc, s, _unit((b * tc - c) / a_s))
    t = tc
    p = a0 + s[:, None] * d1
    q = b0 + t[:, None] * d2
    diff = p - q
    dist = np.sqrt(_rowdot(diff, diff))
    return dist, p, q, diff / np.maximum(dist, _EPS)[:, None]


def point_box(u: Array, half: Array) -> tuple[Array, Array]:
    """Signed distance from points u to the box |u_k| ≤ h_k (box coordinates), and the
    nearest box points. u: (..., 3); half: broadcastable to it."""
    excess = np.abs(u) - half
    outside = np.maximum(excess, 0.0)
    d_out = np.sqrt(np.sum(outside * outside, axis=-1))
    d = np.where(d_out > 0, d_out, np.max(excess, axis=-1))
    return d, np.minimum(np.maximum(u, -half), half)


def point_rounded_box(u: Array, half: Array, rounding: Array) -> tuple[Array, Array]:
    """Signed distance from points to rounded boxes, in box coordinates, row by row.

    d = ‖max(|u| − h, 0)‖ − ρ outside the core box (C¹ there: its gradient is the unit
    vector n̂ = sign(u) max(|u| − h, 0)/‖·‖, continuous across face, edge and corner regions);
    max_k(|u_k| − h_k) − ρ inside the core box.

    Args:
        u: points in box coordinates (m, 3); half: (m, 3); rounding: (m,).

    Returns:
        d (m,) and n̂ in box coordinates (m, 3) (zero inside the core box).
    """
    excess = np.abs(u) - half
    outside = np.maximum(excess, 0.0)
    d_out = np.sqrt((outside * outside).sum(axis=1))
    d = np.where(d_out > 0, d_out, excess.max(axis=1)) - rounding
    return d, np.copysign(outside, u) / np.maximum(d_out, _EPS)[:, None]


def segment_box(
    a: Array, b: Array, centre: Array, rotation: Array, half: Array
) -> tuple[Array, Array, Array, Array]:
    """Distance between segments [a, b] and oriented boxes, row by row.

    In box coordinates u(t) = u₀ + t w, the squared distance to the box is
    f(t) = Σ_k max(|u_k(t)| − h_k, 0)², convex and piecewise quadratic in t ∈ [0, 1] with
    breakpoints where u_k(t) = ±h_k. Its minimum is at 0, 1, a breakpoint, or the stationary
    point of the quadratic of one piece; all these candidates (and the pieces' midpoints, which
    detect a segment passing through the box) are evaluated and the best taken, so the result
    is exact (up to rounding) whenever the segment is outside the box.

    Args:
        a, b: segment ends (m, 3) in world coordinates.
        centre: box centres (m, 3); rotation: (m, 3, 3) box-to-world; half: (m, 3).

    Returns:
        signed d (m,) (negative inside the box, then only a bound on the depth), closest
        points p on the segments and c on the boxes (m, 3, world), n̂ = (p − c)/d (m, 3).
    """
    m = a.shape[0]
    u0 = np.einsum("mji,mj->mi", rotation, a - centre)
    w = np.einsum("mji,mj->mi", rotation, b - a)
    w_safe = np.where(np.abs(w) > _EPS, w, _EPS)
    breaks = np.concatenate([(half - u0) / w_safe, (-half - u0) / w_safe], axis=1)  # (m, 6)
    knots = np.sort(np.concatenate([np.zeros((m, 1)), _unit(breaks),
                                    np.ones((m, 1))], axis=1), axis=1)  # (m, 8)
    lo, hi = knots[:, :-1], knots[:, 1:]
    mids = 0.5 * (lo + hi)
    mid_u = u0[:, None, :] + mids[:, :, None] * w[:, None, :]  # (m, 7, 3)
    side = np.sign(mid_u) * (np.abs(mid_u) > half[:, None, :])  # −1 / 0 / +1 per axis
    active = side != 0
    target = side * half[:, None, :]
    num = np.sum(active * (u0[:, None, :] - target) * w[:, None, :], axis=2)
    den = np.sum(active * (w * w)[:, None, :], axis=2)
    t_star = np.minimum(np.maximum(-num / np.maximum(den, _EPS), lo), hi)
    cand = np.concatenate([knots, t_star, mids], axis=1)  # (m, 22); mids find the inside
    u = u0[:, None, :] + cand[:, :, None] * w[:, None, :]
    dist, _ = point_box(u, half[:, None, :])
    best = np.argmin(dist, axis=1)
    rows = np.arange(m)
    t = cand[rows, best]
    d = dist[rows, best]
    u_best = u[rows, best]
    c_local = np.minimum(np.maximum(u_best, -half), half)
    p = a + t[:, None] * (b - a)
    c = centre + np.einsum("mij,mj->mi", rotation, c_local)
    diff = p - c
    norm = np.sqrt(_rowdot(diff, diff))
    return d, p, c, diff / np.maximum(norm, _EPS)[:, None]
