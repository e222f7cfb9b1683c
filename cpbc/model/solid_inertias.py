"""Rotational inertias a URDF leaves out, estimated from the link's mass and geometry.

Some URDFs give a link its mass and an all-zero ``<inertia>`` tensor (rtb-data's Lynxmotion
AL5D, every link): a point mass at the centre of mass. Raised to the least MuJoCo accepts
(cpbc.model.inertias), a wrist whose centre of mass lies on its axis keeps a moment of 1e-9
kg·m² about it: the law's torque then accelerates it by thousands of rad/s² per N·m, no
sampled-data loop or safeguard keeps up, and the arm crosses its range. Such a link is given
the inertia of a solid of uniform density: the box that bounds its geometry (collision, or
visual when it has none; its welded links' geometry included), of the link's mass, taken
about the centre of mass the URDF gives,

    I = m/12 · diag(b² + c², a² + c², a² + b²)     (a, b, c: the box's sides)

which is what the link's shape says about its spread of mass. A point-mass link with no
geometry to measure is left as it is, to be raised to MuJoCo's least (iCub's wrists: the
skeleton of ``cpbc.robot`` then locks such a joint when no gain drives it stably).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.model.inertias import MIN_MASS, MIN_MOMENT


def point_mass(inertia: pin.Inertia) -> bool:
    """A mass with no rotational inertia about its centre (an all-zero tensor)."""
    moments = np.linalg.eigvalsh(np.asarray(inertia.inertia, dtype=float))
    return bool(inertia.mass >= MIN_MASS and moments[-1] < MIN_MOMENT)


def bounding_box(geometry: pin.GeometryModel, joint: int) -> Array | None:
    """The sides (a, b, c) [m] of the box, in the joint's axes, that bounds every geometry
    object attached to ``joint``; None when there is none."""
    corners = []
    for g in geometry.geometryObjects:
        if g.parentJoint != joint:
            continue
        shape = g.geometry
        shape.computeLocalAABB()
        lo, hi = np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)
        box = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
        corners.append(box @ g.placement.rotation.T + g.placement.translation)
    if not corners:
        return None
    points = np.vstack(corners)
    return np.asarray(points.max(axis=0) - points.min(axis=0), dtype=float)


def solid_box(mass: float, sides: Array) -> Array:
    """The rotational inertia of a solid box about its centre (module docstring)."""
    a2, b2, c2 = np.asarray(sides, dtype=float) ** 2
    return mass / 12.0 * np.diag([b2 + c2, a2 + c2, a2 + b2])


def estimate_point_masses(model: pin.Model,
                          geometries: Sequence[Callable[[], pin.GeometryModel]]) -> tuple[str, ...]:
    """Give every point-mass joint inertia of ``model`` the solid box of its geometry, from
    the first of ``geometries`` (made on demand: collision, then visual) that has some for
    it; the names of the joints changed (one without any geometry is left as it is)."""
    changed = []
    made: dict[int, pin.GeometryModel] = {}
    for jid in range(1, model.njoints):
        inertia = model.inertias[jid]
        if not point_mass(inertia):
            continue
        sides = None
        for k, make in enumerate(geometries):
            if sides is None:
                made.setdefault(k, make())
                sides = bounding_box(made[k], jid)
        if sides is None:
            continue
        model.inertias[jid] = pin.Inertia(float(inertia.mass),
                                          np.array(inertia.lever, dtype=float),
                                          solid_box(float(inertia.mass), sides))
        changed.append(str(model.names[jid]))
    return tuple(changed)
