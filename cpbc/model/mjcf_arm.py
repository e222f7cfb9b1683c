"""Whether an MJCF file holds an arm both engines read alike, checked on MuJoCo's model
before Pinocchio parses it.

Pinocchio's MJCF reader takes the first body of ``<worldbody>`` as the root of the arm and
leaves its siblings out; MuJoCo reads them all. A scene that starts with a mocap handle, a
table or a target marker (gymnasium-robotics' Fetch puts its mocap body first) therefore
gives Pinocchio a model without a joint while MuJoCo drives the arm: the controller would
have nothing to act on. Each such file is refused naming what to change in it.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from cpbc.errors import ModelError


def _root_body(mj: mujoco.MjModel, body: int) -> int:
    """The child of the world that ``body`` hangs from."""
    while int(mj.body_parentid[body]) != 0:
        body = int(mj.body_parentid[body])
    return body


def check_mjcf_arm(path: Path, mj: mujoco.MjModel) -> None:
    """Refuse (ModelError) an MJCF without a joint, or whose joints all hang from a body
    other than the first of ``<worldbody>`` (the only one Pinocchio reads)."""
    if mj.njnt == 0:
        raise ModelError(f"{path} has no joint: an arm needs hinge or slide joints in its "
                         "bodies (this file holds only fixed bodies)")
    first = next((b for b in range(1, mj.nbody) if int(mj.body_parentid[b]) == 0), None)
    holders = {_root_body(mj, int(mj.jnt_bodyid[j])) for j in range(mj.njnt)}
    if first is not None and first not in holders:
        arm = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, min(holders)) or "?"
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, first) or "?"
        raise ModelError(f"{path}: the first body of <worldbody>, '{name}', has no joint, and "
                         "it is the only one Pinocchio reads as the arm; move the arm's body "
                         f"'{arm}' first in <worldbody>")
