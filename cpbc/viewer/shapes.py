"""MuJoCo geoms as meshcat geometry: primitives, capsules and cylinders via trimesh, meshes."""

from __future__ import annotations

import meshcat.geometry as mg
import mujoco
import numpy as np

from cpbc.constraints.constraint_types import Array

_CIRCLE_SEGMENTS = 32


def geom_geometry(model: mujoco.MjModel, g: int) -> mg.Geometry | None:
    """The shape of geom ``g`` in its own frame, or None for planes and height fields.

    MuJoCo capsules and cylinders lie along their local z-axis, like trimesh's; sizes are
    half-lengths (``geom_size``), meshes come already scaled and centred (``mesh_vert``).
    """
    t, size = model.geom_type[g], model.geom_size[g]
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return mg.Sphere(float(size[0]))
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        return mg.Box((2.0 * size).tolist())
    if t == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return mg.Ellipsoid(size.tolist())
    if t == mujoco.mjtGeom.mjGEOM_CAPSULE or t == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return _round_geometry(t, size)
    if t == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
        return mg.TriangularMeshGeometry(
            model.mesh_vert[v0 : v0 + nv], model.mesh_face[f0 : f0 + nf]
        )
    return None


def _round_geometry(t: int, size: Array) -> mg.TriangularMeshGeometry:
    """A capsule or cylinder as a triangle mesh. trimesh is loaded here only: it takes 0.2 s
    (SciPy's spatial module with it), on the CLI's path after the simulation, and scenes of
    spheres, boxes and meshes do not need it."""
    import trimesh

    if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        m = trimesh.creation.capsule(
            height=2.0 * float(size[1]), radius=float(size[0]), count=[_CIRCLE_SEGMENTS, 16]
        )
    else:
        m = trimesh.creation.cylinder(
            radius=float(size[0]), height=2.0 * float(size[1]), sections=_CIRCLE_SEGMENTS
        )
    return mg.TriangularMeshGeometry(m.vertices, m.faces)


def tube(points: Array, radius: float, sides: int = 6) -> mg.TriangularMeshGeometry | None:
    """A tube of ``radius`` along a polyline (F, 3): a trace visible at any zoom.

    WebGL draws lines one pixel wide whatever their width, so traces are thin meshes.
    Points closer than ``radius`` to the last kept one are dropped (the last point is always
    kept); None when fewer than two remain.
    """
    p = np.asarray(points, dtype=float)
    if len(p) > 1:
        keep, last = [0], p[0]
        for k in range(1, len(p)):
            if np.linalg.norm(p[k] - last) >= radius:
                keep.append(k)
                last = p[k]
        if keep[-1] != len(p) - 1 and np.linalg.norm(p[-1] - p[keep[-1]]) > 1e-12:
            keep.append(len(p) - 1)
        p = p[keep]
    if len(p) < 2:
        return None
    tangent = np.gradient(p, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    # A normal transported along the curve (no twisting), seeded off the first tangent.
    seed = np.eye(3)[int(np.argmin(np.abs(tangent[0])))]
    normal = np.empty_like(p)
    normal[0] = np.cross(tangent[0], seed)
    normal[0] /= np.linalg.norm(normal[0])
    for k in range(1, len(p)):
        n = normal[k - 1] - (normal[k - 1] @ tangent[k]) * tangent[k]
        norm = np.linalg.norm(n)
        normal[k] = n / norm if norm > 1e-12 else normal[k - 1]
    binormal = np.cross(tangent, normal)
    a = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    cos, sin = np.cos(a)[None, :, None], np.sin(a)[None, :, None]
    ring = cos * normal[:, None, :] + sin * binormal[:, None, :]
    vertices = (p[:, None, :] + radius * ring).reshape(-1, 3)
    seg = np.arange(len(p) - 1)[:, None]
    j = np.arange(sides)[None, :]
    a0, a1 = seg * sides + j, seg * sides + (j + 1) % sides
    b0, b1 = a0 + sides, a1 + sides
    faces = np.concatenate(
        [np.stack([a0, a1, b1], -1).reshape(-1, 3), np.stack([a0, b1, b0], -1).reshape(-1, 3)]
    )
    return mg.TriangularMeshGeometry(vertices, faces)
