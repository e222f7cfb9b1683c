"""Covering a robot's collision geometry with spheres or capsules, automatically.

The clearance constraints need each link as a few swept spheres with exact distances, not
as a triangle mesh. For every link that carries collision geometry, this module gathers the
geometry's points in the link frame (a URDF's mesh vertices read with trimesh, an MJCF's as
MuJoCo compiled them, cpbc.model.collision_geoms; boxes, cylinders, capsules, spheres and
ellipsoids by polytopes that circumscribe them) and fits the capsule of least volume that
contains them all. A capsule is convex, so it then contains the convex hull of the points
and with it the whole link surface: the cover is conservative.

Fitting, for a candidate axis direction a (the three principal axes of the points, and the
axes of trimesh's minimum oriented bounding box): the axis line goes through the centre of
the smallest circle that holds the points projected on the plane ⟂ a (radius r₀). For a
radius r ≥ r₀ a point v (axial coordinate s_v, distance ρ_v ≤ r from the line) lies in the
capsule with segment [s_lo, s_hi] iff s_lo ≤ s_v + k_v and s_hi ≥ s_v − k_v, where
k_v = √(r² − ρ_v²). The shortest segment is therefore s_lo = min_v(s_v + k_v),
s_hi = max_v(s_v − k_v), or a single point of [s_hi, s_lo] when that is empty. Radii from r₀ up
to 1.6 r₀ and the smallest enclosing sphere are tried; the least volume π r² L + 4/3 π r³ wins.

Spheres (the default of :func:`cover_links`): the capsule (a, b, r) is covered by k spheres
centred evenly on [a, b], spacing δ = L/(k − 1), of radius r' = √(r² + (δ/2)²) — the farthest
point of the capsule from every centre is midway between two of them on its surface — with
the fewest k for which r' ≤ r + ``tolerance``. Spheres have exact, C¹ distances to every
obstacle kind (cpbc.constraints.geometry.point_rounded_box), which capsules do not have to a
box, and they are cheaper in the control loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.errors import CpbcError, ModelError

if TYPE_CHECKING:  # read through its attributes; its module imports MuJoCo
    from cpbc.model.collision_geoms import CollisionGeom


def _trimesh() -> Any:
    """trimesh, imported on first use (it takes most of a second to import)."""
    import trimesh

    return trimesh


@dataclass(frozen=True)
class LinkPrimitive:
    """A capsule fixed in a frame of the robot: points within ``radius`` of [start, end].

    A sphere is the capsule with start == end.

    Attributes:
        name: label used in constraint names.
        frame: the robot frame it is fixed in (a link name).
        start, end: segment ends in that frame [m], shape (3,).
        radius: [m], > 0.
    """

    name: str
    frame: str
    start: Array
    end: Array
    radius: float

    def __post_init__(self) -> None:
        for attr in ("start", "end"):
            v = np.asarray(getattr(self, attr), dtype=float).reshape(-1)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise CpbcError(f"primitive '{self.name}': {attr} must be 3 finite numbers")
            v.setflags(write=False)
            object.__setattr__(self, attr, v)
        if not (np.isfinite(self.radius) and self.radius > 0):
            raise CpbcError(f"primitive '{self.name}': radius must be > 0, got {self.radius}")
        object.__setattr__(self, "radius", float(self.radius))

    @property
    def kind(self) -> str:
        return "sphere" if np.array_equal(self.start, self.end) else "capsule"

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.end - self.start))

    @property
    def volume(self) -> float:
        return float(np.pi * self.radius**2 * self.length + 4.0 / 3.0 * np.pi * self.radius**3)

    def distance_to_points(self, points: Array) -> Array:
        """Distance from points (frame coordinates, (N, 3)) to the segment, minus nothing."""
        ab = self.end - self.start
        den = float(ab @ ab)
        t = np.zeros(len(points)) if den == 0 else np.clip((points - self.start) @ ab / den, 0, 1)
        return np.linalg.norm(points - (self.start + t[:, None] * ab), axis=1)


def _circle(points2: Array) -> tuple[Array, float]:
    """Smallest circle containing 2-D points."""
    try:
        centre, radius = _trimesh().nsphere.minimum_nsphere(points2)
        return np.asarray(centre, dtype=float), float(radius)
    except Exception:  # degenerate (collinear) input: fall back to the bounding box circle
        lo, hi = points2.min(axis=0), points2.max(axis=0)
        centre = 0.5 * (lo + hi)
        return centre, float(np.max(np.linalg.norm(points2 - centre, axis=1)))


def fit_capsule(points: Array, radius_factors: Sequence[float] = ()) -> tuple[Array, Array, float]:
    """The least-volume capsule (over a few axes and radii) containing every point.

    Args:
        points: shape (N, 3), N ≥ 1.
        radius_factors: multiples of each axis's minimal radius to try; 1 … 1.6 by default.

    Returns:
        start, end (3,) and radius of the capsule; start == end for a sphere.
    """
    trimesh = _trimesh()
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(pts) == 0:
        raise CpbcError("cannot fit a capsule to no points")
    if len(pts) > 8:
        try:
            pts = trimesh.convex.convex_hull(pts).vertices
        except Exception:  # flat or degenerate point sets: keep all points
            pass
    factors = list(radius_factors) or [1.0 + 0.04 * i for i in range(16)]
    centre3, r3 = trimesh.nsphere.minimum_nsphere(pts) if len(pts) > 4 else (
        pts.mean(axis=0), float(np.max(np.linalg.norm(pts - pts.mean(axis=0), axis=1))))
    best = (np.asarray(centre3, float), np.asarray(centre3, float), max(float(r3), 1e-6))
    best_volume = 4.0 / 3.0 * np.pi * best[2] ** 3
    mean = pts.mean(axis=0)
    axes = list(np.linalg.svd(pts - mean, full_matrices=False)[2])
    if len(pts) >= 4:
        try:
            to_origin, _ = trimesh.bounds.oriented_bounds(pts)
            axes += list(np.linalg.inv(to_origin)[:3, :3].T)
        except Exception:  # degenerate input: principal axes are enough
            pass
    for a in axes:
        a = a / np.linalg.norm(a)
        e1 = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(a, e1)
        s = (pts - mean) @ a
        planar = np.column_stack([(pts - mean) @ e1, (pts - mean) @ e2])
        c2, r0 = _circle(planar)
        origin = mean + c2[0] * e1 + c2[1] * e2
        rho = np.linalg.norm(planar - c2, axis=1)
        r0 = max(r0, float(rho.max()), 1e-6)
        for f in factors:
            r = r0 * f
            k = np.sqrt(np.maximum(r * r - rho * rho, 0.0))
            s_lo, s_hi = float(np.min(s + k)), float(np.max(s - k))
            if s_lo > s_hi:
                s_lo = s_hi = 0.5 * (s_lo + s_hi)
            volume = np.pi * r * r * (s_hi - s_lo) + 4.0 / 3.0 * np.pi * r**3
            if volume < best_volume:
                best_volume = volume
                best = (origin + s_lo * a, origin + s_hi * a, r)
    start, end, radius = best
    # Guard against rounding: grow the radius until every point is inside.
    prim = LinkPrimitive("fit", "fit", start, end, radius)
    radius = max(radius, float(prim.distance_to_points(pts).max()) * (1 + 1e-9))
    return np.asarray(start), np.asarray(end), radius


def _polygon(radius: float, sections: int) -> Array:
    """A regular polygon that circumscribes a circle of ``radius`` in the xy-plane."""
    ang = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    r = radius / np.cos(np.pi / sections)
    return np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(sections)])


def _sphere_points(radius: float) -> Array:
    ico = _trimesh().creation.icosphere(subdivisions=2, radius=1.0)
    # the icosphere's facets lie inside the unit sphere; push them out to circumscribe it
    inner = float(np.min(np.abs(np.einsum("ij,ij->i", ico.face_normals,
                                          ico.vertices[ico.faces[:, 0]]))))
    return np.asarray(ico.vertices) * (radius / inner)


_MESH_CACHE: dict[tuple[str, tuple[float, ...]], Array] = {}


def geometry_points(geom: pin.GeometryObject) -> Array:
    """Points whose convex hull contains a collision geometry, in the geometry's own frame."""
    shape = geom.geometry
    if isinstance(shape, coal.Box):
        h = np.asarray(shape.halfSide, dtype=float)
        corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        return corners * h
    if isinstance(shape, coal.Sphere):
        return _sphere_points(float(shape.radius))
    if isinstance(shape, coal.Cylinder):
        ring = _polygon(float(shape.radius), 24)
        hl = float(shape.halfLength)
        return np.vstack([ring - np.array([0, 0, hl]), ring + np.array([0, 0, hl])])
    if isinstance(shape, coal.Capsule):
        ball = _sphere_points(float(shape.radius))
        hl = float(shape.halfLength)
        return np.vstack([ball - np.array([0, 0, hl]), ball + np.array([0, 0, hl])])
    path = str(geom.meshPath)
    if path and Path(path).is_file():
        scale = tuple(float(x) for x in np.asarray(geom.meshScale).reshape(-1))
        key = (path, scale)
        if key not in _MESH_CACHE:
            trimesh = _trimesh()
            try:
                mesh = trimesh.load(path, force="mesh")
            except Exception as exc:
                raise ModelError(f"trimesh could not read collision mesh {path}: {exc}") from None
            verts = np.asarray(mesh.vertices, dtype=float) * np.asarray(scale)
            if len(verts) > 8:
                verts = np.asarray(trimesh.convex.convex_hull(verts).vertices)
            _MESH_CACHE[key] = verts
        return _MESH_CACHE[key]
    raise ModelError(
        f"collision geometry '{geom.name}' ({type(shape).__name__}) cannot be covered "
        "automatically; declare its primitives in the scenario"
    )


def link_points(model: pin.Model, collision: pin.GeometryModel) -> dict[str, Array]:
    """Collision points of every link, in its own frame: {frame name: (N, 3)}."""
    out: dict[str, list[Array]] = {}
    for geom in collision.geometryObjects:
        frame = model.frames[geom.parentFrame]
        pts = geometry_points(geom)
        # geometry placement and frame placement are both relative to the parent joint
        rel = frame.placement.actInv(geom.placement)
        out.setdefault(frame.name, []).append(pts @ rel.rotation.T + rel.translation)
    return {k: np.vstack(v) for k, v in out.items()}


def moving_frames(model: pin.Model) -> set[str]:
    """Frames attached to a joint that moves (parent joint ≠ universe)."""
    return {f.name for f in model.frames if f.parentJoint > 0}


def sphere_chain(
    start: Array, end: Array, radius: float, tolerance: float
) -> list[tuple[Array, float]]:
    """Spheres (centre, radius) whose union contains the capsule (start, end, radius), each
    at most ``tolerance`` larger in radius than the capsule."""
    if not tolerance > 0:
        raise CpbcError(f"sphere tolerance must be > 0, got {tolerance}")
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    length = float(np.linalg.norm(end - start))
    if length <= 2.0 * tolerance:  # one sphere around the midpoint is tight enough
        return [(0.5 * (start + end), radius + 0.5 * length)]
    max_gap = 2.0 * np.sqrt((radius + tolerance) ** 2 - radius**2)
    k = int(np.ceil(length / max_gap)) + 1
    gap = length / (k - 1)
    r = float(np.sqrt(radius**2 + (0.5 * gap) ** 2))
    return [(start + (end - start) * (i / (k - 1)), r) for i in range(k)]


def surface_points(points: Array) -> Array:
    """The corners of the convex hull of ``points`` (N, 3), its facets' centroids and its
    edges' midpoints: what a declared cover is checked on (:func:`uncovered`)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    try:
        hull = _trimesh().convex.convex_hull(pts)
    except Exception:  # flat or degenerate: the points themselves
        return pts
    corners = np.asarray(hull.vertices)[np.asarray(hull.faces)]  # (F, 3, 3)
    edges = 0.5 * (corners + np.roll(corners, 1, axis=1))
    return np.vstack([np.asarray(hull.vertices), corners.mean(axis=1), edges.reshape(-1, 3)])


def uncovered(points: Array, primitives: Sequence[LinkPrimitive]) -> float:
    """How far the farthest of ``points`` (a link's frame) lies outside the union of
    ``primitives`` [m] (≤ 0: every point inside). On :func:`surface_points` of a link's
    collision points it is what a declared cover may read beyond the link's clearance
    (up to the facets' bulge between the points checked)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    gaps = np.min([p.distance_to_points(pts) - p.radius for p in primitives], axis=0)
    return float(np.max(gaps))


def geom_points(geom: CollisionGeom) -> Array:
    """Points whose convex hull contains an MJCF collision geom, in its link's frame
    (MuJoCo's sizes: a capsule's and a cylinder's half-length along the geom's z)."""
    size = geom.size
    half = np.array([0.0, 0.0, size[1]])  # a capsule's or cylinder's half-length on z
    if geom.kind == "mesh":
        local = geom.vertices
    elif geom.kind == "box":
        local = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * size
    elif geom.kind in ("sphere", "ellipsoid"):
        # an affine image of a polytope around the unit sphere holds the ellipsoid
        axes = np.full(3, size[0]) if geom.kind == "sphere" else size
        local = _sphere_points(1.0) * axes
    elif geom.kind == "capsule":
        ball = _sphere_points(float(size[0]))
        local = np.vstack([ball - half, ball + half])
    elif geom.kind == "cylinder":
        ring = _polygon(float(size[0]), 24)
        local = np.vstack([ring - half, ring + half])
    else:
        raise ModelError(f"collision geom '{geom.name}' of link '{geom.frame}' is a "
                         f"{geom.kind}, which no cover can hold: make it visual (contype and "
                         "conaffinity 0) or declare the link's primitives")
    return np.asarray(local, dtype=float) @ geom.rotation.T + geom.translation


def geoms_points(geoms: Sequence[CollisionGeom]) -> dict[str, Array]:
    """Collision points of every link of an MJCF arm, in its own frame: {frame: (N, 3)}."""
    out: dict[str, list[Array]] = {}
    for geom in geoms:
        out.setdefault(geom.frame, []).append(geom_points(geom))
    return {k: np.vstack(v) for k, v in out.items()}


def cover_links(
    model: pin.Model,
    collision: pin.GeometryModel,
    links: Sequence[str] | None = None,
    padding: float = 0.0,
    kind: str = "spheres",
    tolerance: float = 0.01,
) -> list[LinkPrimitive]:
    """Cover the collision geometry of each link by spheres (default) or one capsule.

    Args:
        model: the (reduced) Pinocchio model.
        collision: its collision geometry.
        links: frames to cover; every moving link with collision geometry when omitted
            (links welded to the world cannot change their clearance and are skipped).
        padding: extra radius added to every primitive [m], ≥ 0.
        kind: "spheres" (a chain of spheres around the least-volume capsule) or "capsules".
        tolerance: for spheres, how much larger than the capsule's radius each sphere may be
            [m], > 0; smaller means more spheres.

    Returns:
        Primitives named after their link (``link`` for a capsule, ``link#i`` for spheres).

    Raises:
        ModelError: a requested link has no collision geometry or is not in the model.
    """
    _check_settings(padding, kind)
    return cover_points(link_points(model, collision), moving_frames(model), links, padding,
                        kind, tolerance)


def _check_settings(padding: float, kind: str) -> None:
    if padding < 0:
        raise CpbcError(f"padding must be ≥ 0, got {padding}")
    if kind not in ("spheres", "capsules"):
        raise CpbcError(f"cover kind must be 'spheres' or 'capsules', got {kind!r}")


def cover_points(
    points: dict[str, Array],
    moving: set[str],
    links: Sequence[str] | None = None,
    padding: float = 0.0,
    kind: str = "spheres",
    tolerance: float = 0.01,
) -> list[LinkPrimitive]:
    """:func:`cover_links` on each link's collision points ({frame: (N, 3)}, in its frame;
    ``moving``: the frames that move, covered when ``links`` is omitted)."""
    _check_settings(padding, kind)
    if links is None:
        chosen = [name for name in points if name in moving]
    else:
        missing = [name for name in links if name not in points]
        if missing:
            raise ModelError(
                f"links {missing} have no collision geometry; links with geometry: "
                f"{sorted(points)}"
            )
        chosen = list(links)
    prims = []
    for name in chosen:
        start, end, radius = fit_capsule(points[name])
        if kind == "capsules":
            prims.append(LinkPrimitive(name, name, start, end, radius + padding))
            continue
        chain = sphere_chain(start, end, radius, tolerance)
        for i, (centre, r) in enumerate(chain):
            label = name if len(chain) == 1 else f"{name}#{i}"
            prims.append(LinkPrimitive(label, name, centre, centre, r + padding))
    return prims
