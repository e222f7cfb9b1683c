"""An MJCF arm's effort limits, read from what drives its joints in MuJoCo.

A URDF declares each joint's effort in ``<limit effort>``; an MJCF puts it on the actuators
and the joint: per actuator, the force bound |gear| · min|``forcerange``| (when
``forcelimited``) and, for a direct-torque actuator (a fixed gain and no bias: ``motor``),
|gear| · |gain| · min|``ctrlrange``| (when ``ctrllimited``); several actuators on one
joint add up; the joint's own ``actuatorfrcrange`` bounds their sum. Pinocchio's MJCF
parser reads the last only, so an arm whose motors carry the limits (robosuite's Panda:
``ctrlrange`` ±80/±12 N·m) ran unlimited; :func:`apply_actuator_efforts` writes them into
the Pinocchio model, where ``simulation.torque_limit: from_model`` and ``auto`` read them.
A position or velocity servo's ``ctrlrange`` is a set point's range, not a torque bound.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array


def _actuator_bound(mj: mujoco.MjModel, a: int) -> float:
    """The largest joint effort actuator ``a`` can exert, ignoring its joint's bound."""
    bounds = [np.inf]
    if mj.actuator_forcelimited[a]:
        bounds.append(float(np.min(np.abs(mj.actuator_forcerange[a]))))
    direct = (mj.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
              and mj.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE)
    if mj.actuator_ctrllimited[a] and direct:
        bounds.append(abs(float(mj.actuator_gainprm[a, 0]))
                      * float(np.min(np.abs(mj.actuator_ctrlrange[a]))))
    return abs(float(mj.actuator_gear[a, 0])) * min(bounds)


def actuator_efforts(mj: mujoco.MjModel, joints: list[int]) -> Array:
    """The effort limit [N·m or N] of each MuJoCo joint of ``joints`` (ids) from the
    actuators that drive it and its ``actuatorfrcrange`` (module docstring); inf where
    nothing bounds it."""
    total = {j: 0.0 for j in joints}
    driven: set[int] = set()
    for a in range(mj.nu):
        j = int(mj.actuator_trnid[a, 0])
        if mj.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and j in total:
            total[j] += _actuator_bound(mj, a)
            driven.add(j)
    out = np.array([total[j] if j in driven else np.inf for j in joints])
    for i, j in enumerate(joints):
        if mj.jnt_actfrclimited[j]:
            out[i] = min(out[i], float(np.min(np.abs(mj.jnt_actfrcrange[j]))))
    return out


def apply_actuator_efforts(model: pin.Model, mj: mujoco.MjModel) -> Array:
    """Lower the effort limit of each of ``model``'s joints to what ``mj``'s actuators
    allow (the same joints, matched by name; a joint MuJoCo lacks is left as it is); the
    limits written, per joint, are returned."""
    ids = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)
           for name in list(model.names)[1:]]
    known = [j for j in ids if j >= 0]
    found = dict(zip(known, actuator_efforts(mj, known), strict=True))
    effort = np.array(model.effortLimit, dtype=float)
    for k, j in enumerate(ids):
        v = model.joints[k + 1].idx_v
        if j >= 0 and model.joints[k + 1].nv == 1:
            current = effort[v] if effort[v] > 0 else np.inf  # 0: Pinocchio's "none"
            effort[v] = min(current, found[j])
    model.effortLimit = effort
    return effort
