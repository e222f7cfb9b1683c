"""Link inertias as MuJoCo gets them: one rigid body per driven joint, as in Pinocchio.

Pinocchio merges every link welded to another (a fixed URDF joint, or a joint cpbc locks)
into the body of the nearest joint above it, and every link welded to the world into the
world. That merged inertia is all the dynamics sees. MuJoCo keeps each URDF link as a body
and checks each body's inertia on its own, so a sensor mount, an antenna or a quadruped's base
welded to the world, whose own ``<inertial>`` is unphysical (a zero or negative principal
moment, A + B < C), stops the compiler although it cannot change the arm's motion.

:func:`apply_joint_inertias` therefore gives each MuJoCo body that carries a driven joint the
inertia Pinocchio gives that joint (its link plus everything welded to it), and every welded
body none (they stay as bodies for frames, sites and collision meshes). The mass matrix and the
bias forces of the two engines are then equal by construction.

A driven link whose merged inertia MuJoCo still refuses (a massless "virtual" link between two
joints, a principal moment of zero) cannot be reproduced exactly; :func:`regularise_inertias`
raises the offending principal moments (and a zero mass) by the least amount MuJoCo accepts,
in the Pinocchio model itself, so both engines keep the same dynamics and the change is
reported. It does so only where the change is negligible (:data:`MAX_RAISE`): an inertia
that needs more, such as A + B < C by a share of C (romeo_small's shoulder), is an error in
the model file, and loading it is refused naming the joint.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.errors import ModelError

MIN_MASS = 1e-6  # kg: the mass given to a massless driven link
MIN_MOMENT = 1e-9  # kg·m²: the least principal moment of a driven link
_TRIANGLE_SLACK = 1e-12  # kg·m²: A + B ≥ C is checked with this margin
#: kg·m²: the most a principal moment may be raised (a gram at 3 cm); beyond, a model error
MAX_RAISE = 1e-6


def _moments(inertia: pin.Inertia) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (ascending) about the centre of mass and their axes (columns)."""
    values, axes = np.linalg.eigh(np.asarray(inertia.inertia, dtype=float))
    return values, axes


def mujoco_accepts(inertia: pin.Inertia) -> bool:
    """Whether MuJoCo compiles a moving body with this inertia: a positive mass, positive
    principal moments satisfying the triangle inequality A + B ≥ C."""
    values, _ = _moments(inertia)
    return bool(inertia.mass >= MIN_MASS and values[0] >= MIN_MOMENT
                and values[0] + values[1] >= values[2] + _TRIANGLE_SLACK)


def regularised(inertia: pin.Inertia) -> pin.Inertia:
    """The nearest inertia MuJoCo accepts: the mass raised to :data:`MIN_MASS` if below,
    principal moments raised to :data:`MIN_MOMENT`, then the two smaller ones raised alike
    until A + B ≥ C; the principal axes and the centre of mass are kept."""
    values, axes = _moments(inertia)
    values = np.maximum(values, MIN_MOMENT)
    deficit = values[2] + 2 * _TRIANGLE_SLACK - values[0] - values[1]
    if deficit > 0:
        values[0] += deficit / 2
        values[1] += deficit / 2
    rotational = axes @ np.diag(values) @ axes.T
    mass = max(float(inertia.mass), MIN_MASS)
    return pin.Inertia(mass, np.array(inertia.lever, dtype=float), 0.5 * (rotational
                                                                            + rotational.T))


def regularise_inertias(model: pin.Model) -> tuple[str, ...]:
    """Replace, in ``model``, every joint inertia MuJoCo would refuse by :func:`regularised`;
    the names of the joints changed."""
    changed = []
    for jid in range(1, model.njoints):
        inertia = model.inertias[jid]
        if mujoco_accepts(inertia):
            continue
        fixed = regularised(inertia)
        before, after = _moments(inertia)[0], _moments(fixed)[0]
        if np.max(after - before) > MAX_RAISE:
            raise ModelError(
                f"the link of joint '{model.names[jid]}' has an unphysical inertia (principal "
                f"moments {np.array2string(before, precision=4)} kg·m² break A + B ≥ C, and "
                f"MuJoCo refuses it): correct its <inertial> in the URDF")
        model.inertias[jid] = fixed
        changed.append(str(model.names[jid]))
    return tuple(changed)


def apply_joint_inertias(spec: mujoco.MjSpec, model: pin.Model) -> None:
    """Give each body of ``spec`` carrying a joint of ``model`` that joint's inertia, and every
    other body none (see the module's docstring). The body of a joint is its URDF child link,
    whose frame is Pinocchio's joint frame, so the inertia carries over unchanged."""
    for body in spec.bodies:
        if body.name == "world":
            continue
        joints = [j.name for j in body.joints]
        body.explicitinertial = True
        body.iquat = [1.0, 0.0, 0.0, 0.0]
        if joints and model.existJointName(joints[0]):
            inertia = model.inertias[model.getJointId(joints[0])]
            i = np.asarray(inertia.inertia, dtype=float)
            body.mass = float(inertia.mass)
            body.ipos = np.asarray(inertia.lever, dtype=float).tolist()
            body.inertia = [0.0, 0.0, 0.0]
            body.fullinertia = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
        else:
            body.mass = 0.0
            body.ipos = [0.0, 0.0, 0.0]
            body.inertia = [0.0, 0.0, 0.0]
            body.fullinertia = [np.nan, 0.0, 0.0, 0.0, 0.0, 0.0]
