"""An MJCF arm's collision geometry, read from MuJoCo's compiled model and placed in the
frames of the controller's Pinocchio model.

A URDF arm's collision geometry comes with Pinocchio's URDF reader (coal shapes); an MJCF's
is read here from what MuJoCo itself collides with: every geom whose ``contype`` or
``conaffinity`` is non-zero (visual geoms have both 0), on a body that moves. A mesh geom
gives the vertices MuJoCo compiled (scaled, in the geom's frame: MuJoCo collides with their
convex hull); a primitive gives its type and MuJoCo's ``size``. Each geom is placed in the
frame of its body in Pinocchio's model, measured at one configuration (the two parsers name
a body's frame alike; the placement is the same at every configuration, tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.errors import ModelError

PRIMITIVES = {
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid",
    mujoco.mjtGeom.mjGEOM_MESH: "mesh",
}


@dataclass(frozen=True)
class CollisionGeom:
    """One collision geom of a link, in the link's Pinocchio frame.

    Attributes:
        name: the geom's MJCF name (``geom<id>`` when it has none).
        geom_id: its id in MuJoCo's model.
        frame: the Pinocchio frame (body name) it is fixed in.
        kind: sphere, capsule, cylinder, box, ellipsoid or mesh (or MuJoCo's name of a type
            no cover can hold: plane, hfield, sdf).
        size: MuJoCo's ``size`` (radius, half-length, half-sides or semi-axes) [m], (3,).
        rotation, translation: the geom's frame in the link's, (3, 3) and (3,).
        vertices: a mesh's vertices in the geom's frame [m], (V, 3); empty otherwise.
    """

    name: str
    geom_id: int
    frame: str
    kind: str
    size: Array
    rotation: Array
    translation: Array
    vertices: Array

    def __post_init__(self) -> None:
        for attr in ("size", "rotation", "translation", "vertices"):
            v = np.array(getattr(self, attr), dtype=float)
            v.setflags(write=False)
            object.__setattr__(self, attr, v)


def _vertices(mj: mujoco.MjModel, g: int) -> Array:
    mesh = int(mj.geom_dataid[g])
    start, count = int(mj.mesh_vertadr[mesh]), int(mj.mesh_vertnum[mesh])
    return np.array(mj.mesh_vert[start:start + count], dtype=float)


def _colliding(mj: mujoco.MjModel) -> list[int]:
    """Geoms that collide (contype or conaffinity ≠ 0) on bodies that move."""
    return [g for g in range(mj.ngeom)
            if (mj.geom_contype[g] or mj.geom_conaffinity[g])
            and int(mj.body_weldid[mj.geom_bodyid[g]]) != 0]


def obstacle_contacts_only(mj: mujoco.MjModel) -> None:
    """Let the arm's geoms touch the scene's obstacles only, as a URDF arm's plant does
    (cpbc.model.loading): a colliding geom of a body that moves gets contype 1 and
    conaffinity 0 (obstacles have conaffinity 1), one of a body of the arm welded to the
    world (its base) neither. Geoms of the world body itself (a floor in the file) keep their
    own. Without this an MJCF's own contacts act in the plant where the controller's model
    has none: robosuite-models' ARX5 base mesh reaches 2 mm into its first link's at every
    configuration, and their friction held joint1 still."""
    arm = mj.body_rootid[mj.geom_bodyid] != 0
    colliding = (mj.geom_contype != 0) | (mj.geom_conaffinity != 0)
    moving = mj.body_weldid[mj.geom_bodyid] != 0
    mj.geom_contype[arm & colliding & moving] = 1
    mj.geom_conaffinity[arm & colliding] = 0
    mj.geom_contype[arm & colliding & ~moving] = 0


def covered_bodies(mj: mujoco.MjModel) -> tuple[str, ...]:
    """The moving bodies that carry a collision geom (what an automatic cover covers)."""
    names = (mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, int(mj.geom_bodyid[g])) or ""
             for g in _colliding(mj))
    return tuple(dict.fromkeys(names))


def mjcf_collision_geoms(mj: mujoco.MjModel, model: pin.Model) -> tuple[CollisionGeom, ...]:
    """The collision geoms of the moving links of an MJCF arm (module docstring).

    Args:
        mj: MuJoCo's model of the arm (before obstacles are added), joints in Pinocchio's
            order.
        model: Pinocchio's model of the same file.

    Raises:
        ModelError: a collision geom on a body Pinocchio has no frame for, or joints other
            than hinges and slides.
    """
    geoms = _colliding(mj)
    if not geoms:
        return ()
    if mj.nq != model.nq:
        raise ModelError(f"MuJoCo reads {mj.nq} joint coordinates in the file, Pinocchio "
                         f"{model.nq}: covers need hinge and slide joints only")
    data, pdata = mujoco.MjData(mj), model.createData()
    q = pin.neutral(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(mj, data)
    pin.framesForwardKinematics(model, pdata, q)
    out = []
    for g in geoms:
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        body = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, int(mj.geom_bodyid[g])) or ""
        geom_type = mujoco.mjtGeom(int(mj.geom_type[g]))
        kind = PRIMITIVES.get(geom_type, geom_type.name[len("mjGEOM_"):].lower())
        if not model.existFrame(body, pin.FrameType.BODY):
            raise ModelError(f"collision geom '{name}' hangs from body '{body}', which "
                             "Pinocchio's model of the file does not have")
        link = pdata.oMf[model.getFrameId(body, pin.FrameType.BODY)]
        world = pin.SE3(data.geom_xmat[g].reshape(3, 3).copy(), data.geom_xpos[g].copy())
        rel = link.actInv(world)
        out.append(CollisionGeom(
            name, g, body, kind, np.array(mj.geom_size[g], dtype=float), rel.rotation,
            rel.translation, _vertices(mj, g) if kind == "mesh" else np.zeros((0, 3))))
    return tuple(out)
