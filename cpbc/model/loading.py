"""One URDF arm, loaded into Pinocchio (the controller's model) and MuJoCo (the plant).

Both engines read the *same* URDF text, in which every mesh URI (``package://``, ``file://``
or relative) has been replaced by an absolute path, so that they see the same links, inertias
and collision meshes. What this module adds on top of the two parsers:

* **Locked joints.** Grippers and other joints the controller should not drive are frozen at
  a value: ``pin.buildReducedModel`` in Pinocchio; in MuJoCo the joint is deleted from the
  spec and its child body is moved to where the joint at that value would put it, so both
  engines weld the same subtree at the same place.
* **The same joint order.** After locking, MuJoCo's ``qpos`` order must equal Pinocchio's
  joint order; this is checked, not assumed.
* **A clean plant.** One ``motor`` (gear 1, no control or force limit) per remaining joint;
  gravity (0, 0, −9.81) in both engines; URDF ``<dynamics damping/friction>`` and armature
  set to zero in MuJoCo here: the joints' rotor inertia and friction are one value
  (cpbc.model.joint_dynamics, the scenario's ``robot.armature`` and ``robot.friction``) that
  the caller puts in both engines, what the file declares included only when asked for. The URDF
  joint ranges stay in MuJoCo as hard stops. Collision meshes of links that can move collide
  with obstacles only (``contype=1, conaffinity=0``: no self-contacts, nothing for links
  welded to the world), so MuJoCo's contact count is a witness of robot–obstacle contact.
* **Limits.** Joint position, velocity and effort limits of the reduced model, as read from
  the URDF ``<limit>`` tags.

The named arms of ``example-robot-data`` are listed in :mod:`cpbc.model.arms`; the URDF text
both engines read is made by :mod:`cpbc.model.urdf_text`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.errors import ModelError
from cpbc.model.arms import ARMS, arm_urdf, available_arms
from cpbc.model.inertias import apply_joint_inertias, regularise_inertias
from cpbc.model.solid_inertias import estimate_point_masses
from cpbc.model.urdf_text import resolve_urdf_meshes, sort_joints, unbound_continuous_joints
from cpbc.model.velocity_limits import PositionDependentVelocity

GRAVITY = np.array([0.0, 0.0, -9.81])


def _quat_axis_angle(axis: Array, angle: float) -> Array:
    q = np.zeros(4)
    mujoco.mju_axisAngle2Quat(q, np.asarray(axis, dtype=float), float(angle))
    return q


def lock_mujoco_joint(spec: mujoco.MjSpec, joint_name: str, value: float) -> None:
    """Delete a hinge/slide joint from a spec, welding its body where the joint puts it at
    ``value``: X_parent,body ← X_parent,body · T(p_j) · M(value − ref) · T(−p_j)."""
    joint = spec.joint(joint_name)
    if joint is None:
        raise ModelError(f"MuJoCo model has no joint '{joint_name}'")
    body = joint.parent
    pos, quat = np.array(body.pos, dtype=float), np.array(body.quat, dtype=float)
    quat /= np.linalg.norm(quat)
    axis = np.array(joint.axis, dtype=float)
    axis /= np.linalg.norm(axis)
    anchor = np.array(joint.pos, dtype=float)
    v = float(value) - float(joint.ref)
    if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
        rot = _quat_axis_angle(axis, v)
        moved = np.zeros(3)
        mujoco.mju_rotVecQuat(moved, anchor, rot)
        shift = np.zeros(3)
        mujoco.mju_rotVecQuat(shift, anchor - moved, quat)
        new_quat = np.zeros(4)
        mujoco.mju_mulQuat(new_quat, quat, rot)
        body.pos, body.quat = pos + shift, new_quat
    elif joint.type == mujoco.mjtJoint.mjJNT_SLIDE:
        shift = np.zeros(3)
        mujoco.mju_rotVecQuat(shift, v * axis, quat)
        body.pos = pos + shift
    else:
        raise ModelError(f"joint '{joint_name}' is not a hinge or slide joint; cannot lock it")
    spec.delete(joint)


@dataclass
class LoadedArm:
    """An arm loaded from URDF: the reduced Pinocchio model and a recipe for its MuJoCo twin.

    Attributes:
        name: label (robot name or URDF stem).
        urdf_path: the source file.
        urdf_text: the URDF with absolute mesh paths (what both engines read).
        model: Pinocchio model of the driven joints (locked joints removed), gravity on.
        collision_model: collision geometry of ``model`` (coal shapes, one per URDF element).
        locked_joints: frozen joints and their values.
        joint_names: driven joints, in the order of q (same in both engines).
        position_lower, position_upper: joint position limits from the URDF, shape (n,);
            ±inf where the URDF has none.
        velocity_limit: joint rate limits [rad/s or m/s], shape (n,); inf where none.
        effort_limit: joint effort limits [N·m or N], shape (n,); inf where none.
        tip: link carrying the MuJoCo site ``end_point`` (the tool centre point), or None.
        continuous_joints: joints the URDF declares ``continuous``, driven as unbounded
            revolute joints (see :func:`unbound_continuous_joints`).
        regularised: driven joints whose link inertia (with the links welded to it) MuJoCo
            would refuse, raised to the nearest it accepts in both engines
            (cpbc.model.inertias).
        estimated: driven joints whose link the URDF gives a mass and an all-zero inertia
            tensor, given the inertia of a solid box of its geometry in both engines
            (cpbc.model.solid_inertias).
        ranges: joint ranges that replace the URDF's in both engines (:func:`narrow`).
        torque_rate_limits: the motors' torque-rate limits a named arm declares [N·m/s],
            shape (n,), or None.
        declared_dynamics: a named arm's own rotor inertia, viscous and Coulomb friction
            per joint (they replace the URDF's ``<dynamics>``), or None.
        velocity_limits: a named arm's position-dependent joint velocity limits, or None.
    """

    name: str
    urdf_path: Path
    urdf_text: str
    model: pin.Model
    collision_model: pin.GeometryModel
    locked_joints: dict[str, float]
    joint_names: tuple[str, ...]
    position_lower: Array
    position_upper: Array
    velocity_limit: Array
    effort_limit: Array
    tip: str | None = None
    continuous_joints: tuple[str, ...] = ()
    regularised: tuple[str, ...] = ()
    estimated: tuple[str, ...] = ()
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    torque_rate_limits: Array | None = None
    declared_dynamics: tuple[Array, Array, Array] | None = None
    velocity_limits: PositionDependentVelocity | None = None

    @property
    def n(self) -> int:
        return len(self.joint_names)

    def mujoco_spec(self) -> mujoco.MjSpec:
        """A fresh MjSpec of the arm (locked joints welded, motors, gravity, no dissipation)."""
        try:
            spec = mujoco.MjSpec.from_string(self.urdf_text)
        except ValueError as exc:
            raise ModelError(f"MuJoCo could not read {self.urdf_path}: {exc}") from None
        spec.option.gravity = GRAVITY.tolist()
        # The URDF's visual elements were skipped while parsing; keep every geom added later
        # (non-colliding obstacles have contype = conaffinity = 0, which MuJoCo would discard
        # as "visual"), and keep bodies welded to others (the viewer tells links from the
        # world by body).
        spec.compiler.discardvisual = False
        spec.compiler.fusestatic = False
        for joint_name, value in self.locked_joints.items():
            lock_mujoco_joint(spec, joint_name, value)
        for eq in list(spec.equalities):  # e.g. a mimic of a locked finger
            spec.delete(eq)
        apply_joint_inertias(spec, self.model)
        for joint_name, (lo, hi) in self.ranges.items():
            spec.joint(joint_name).range = [lo, hi]
        for joint_name in self.continuous_joints:
            if spec.joint(joint_name) is not None:
                spec.joint(joint_name).limited = mujoco.mjtLimited.mjLIMITED_FALSE
        for joint in spec.joints:
            joint.damping = np.zeros_like(np.asarray(joint.damping, dtype=float))
            joint.frictionloss = 0.0
            joint.armature = 0.0
        for geom in spec.geoms:
            geom.contype, geom.conaffinity = 1, 0
        # The geoms' own inertia is never used (every body's is explicit, from Pinocchio): a
        # flat or open mesh, whose volume MuJoCo cannot compute, is measured as a shell.
        for mesh in spec.meshes:
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        if self.tip is not None and spec.body(self.tip) is not None:
            spec.body(self.tip).add_site(name="end_point", size=[0.01, 0, 0])
        for joint_name in self.joint_names:
            spec.add_actuator(
                name=f"{joint_name}_motor", target=joint_name,
                trntype=mujoco.mjtTrn.mjTRN_JOINT, gear=[1.0, 0, 0, 0, 0, 0],
                ctrllimited=0, forcelimited=0,
            )
        return spec

    def mujoco_model(self, spec: mujoco.MjSpec | None = None) -> mujoco.MjModel:
        """Compile a spec of this arm (``mujoco_spec()`` when omitted) and check it."""
        spec = self.mujoco_spec() if spec is None else spec
        try:
            model = spec.compile()
        except ValueError as exc:
            hint = ("; MuJoCo, unlike Pinocchio, refuses unphysical inertias: correct that "
                    "link's <inertial> in the URDF" if "inertia" in str(exc) else "")
            raise ModelError(
                f"MuJoCo could not compile {self.urdf_path}: {str(exc).strip()}{hint}"
            ) from None
        finish_mujoco_model(model, self.joint_names)
        return model


def finish_mujoco_model(model: mujoco.MjModel, joint_names: Sequence[str]) -> None:
    """Check the joint order and silence geoms welded to the world (they cannot move)."""
    names = tuple(model.joint(i).name for i in range(model.njnt))
    if names != tuple(joint_names) or model.nq != len(joint_names):
        raise ModelError(
            f"MuJoCo and Pinocchio disagree on the joints: MuJoCo has {list(names)}, "
            f"Pinocchio {list(joint_names)}"
        )
    static = model.body_weldid[model.geom_bodyid] == 0
    robot = model.geom_conaffinity == 0  # obstacles added by the scenario have conaffinity 1
    model.geom_contype[static & robot] = 0


def _limits(model: pin.Model) -> tuple[Array, Array, Array, Array]:
    lower = np.array(model.lowerPositionLimit, dtype=float)
    upper = np.array(model.upperPositionLimit, dtype=float)
    bad = ~(np.isfinite(lower) & np.isfinite(upper) & (lower < upper))
    lower[bad], upper[bad] = -np.inf, np.inf
    vel = np.array(model.velocityLimit, dtype=float)
    eff = np.array(model.effortLimit, dtype=float)
    vel[~(vel > 0)] = np.inf
    eff[~(eff > 0)] = np.inf
    return lower, upper, vel, eff


def load_urdf(
    path: str | Path,
    locked_joints: Mapping[str, float] | None = None,
    name: str | None = None,
    package_dirs: Sequence[str | Path] = (),
    driven: Sequence[str] | None = None,
) -> LoadedArm:
    """Load a fixed-base URDF arm into Pinocchio, ready for MuJoCo.

    Args:
        path: the URDF file.
        locked_joints: joints to freeze, with their values [rad or m].
        name: label; the file's stem when omitted.
        package_dirs: extra folders to look up ``package://`` URIs in (besides
            ``ROS_PACKAGE_PATH``, example-robot-data and the URDF's parent folders).
        driven: when given, the joints to drive: every other joint is locked too, at its
            value in ``locked_joints`` or else at 0 moved into its range.

    Raises:
        ModelError: missing file or mesh, unknown or out-of-range locked joint, a joint type
            other than revolute/prismatic among the driven joints.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"URDF file not found: {path}")
    text, continuous = unbound_continuous_joints(
        sort_joints(resolve_urdf_meshes(path, package_dirs=package_dirs)))
    try:
        full = pin.buildModelFromXML(text)
        geoms = pin.buildGeomFromUrdfString(full, text, pin.GeometryType.COLLISION)
    except (RuntimeError, ValueError) as exc:
        raise ModelError(f"Pinocchio could not load {path}: {exc}") from None
    locked = _locked(full, locked_joints or {}, driven, path)
    for joint_name in continuous:  # unbounded: no stop in MuJoCo, ±inf in Pinocchio
        idx = full.joints[full.getJointId(joint_name)].idx_q
        full.lowerPositionLimit[idx], full.upperPositionLimit[idx] = -np.inf, np.inf
    q_ref = pin.neutral(full)
    ids = []
    for joint_name, value in locked.items():
        jid = full.getJointId(joint_name)
        jm = full.joints[jid]
        if jm.nq != 1:
            raise ModelError(f"cannot lock joint '{joint_name}': it is not a 1-DOF joint",
                             "locked_joints")
        lo, hi = full.lowerPositionLimit[jm.idx_q], full.upperPositionLimit[jm.idx_q]
        if np.isfinite(lo) and np.isfinite(hi) and lo < hi and not lo <= value <= hi:
            raise ModelError(
                f"locked joint '{joint_name}' = {value} is outside its range [{lo}, {hi}]",
                "locked_joints",
            )
        q_ref[jm.idx_q] = value
        ids.append(jid)
    if ids:
        try:
            model, collision = pin.buildReducedModel(full, geoms, ids, q_ref)
        except (RuntimeError, ValueError) as exc:
            raise ModelError(f"Pinocchio could not lock {list(locked)} in {path}: {exc}",
                             "locked_joints") from None
    else:
        model, collision = full, geoms
    model.gravity = pin.Motion(GRAVITY, np.zeros(3))
    if model.nq != model.nv:
        odd = [model.names[i] for i in range(1, model.njoints)
               if model.joints[i].nq != model.joints[i].nv]
        raise ModelError(
            f"{path.name}: joints {odd} are multi-DOF (spherical, planar or floating), which "
            "cpbc can neither drive nor lock: make them fixed, revolute, continuous or "
            "prismatic in the URDF"
        )
    if model.nv == 0:
        raise ModelError(f"{path.name} has no joint to drive (every joint is fixed or locked)")
    if not any(model.inertias[j].mass > 0 for j in range(1, model.njoints)):
        raise ModelError(f"{path.name}: no moving link has a mass (every <inertial> is missing "
                         "or has mass 0), and the laws need the arm's inertia: give the links "
                         "their <inertial> mass and inertia")
    lower, upper, vel, eff = _limits(model)
    estimated = estimate_point_masses(model, [lambda: collision, lambda: _visual(model, text)])
    return LoadedArm(
        name or path.stem, path, text, model, collision, locked, tuple(model.names[1:]),
        lower, upper, vel, eff, continuous_joints=continuous,
        regularised=regularise_inertias(model), estimated=estimated,
    )


def _visual(model: pin.Model, text: str) -> pin.GeometryModel:
    """The URDF's visual geometry on ``model`` (its links' frames survive the locking);
    none when Pinocchio cannot build it."""
    try:
        return pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    except (RuntimeError, ValueError):
        return pin.GeometryModel()


def _locked(full: pin.Model, given: Mapping[str, float], driven: Sequence[str] | None,
            path: Path) -> dict[str, float]:
    """The joints to lock, with their values: those given and, with ``driven``, every other
    joint but the driven ones (:func:`_all_but`)."""
    locked = {k: float(v) for k, v in given.items()}
    if driven is not None:
        locked = {**_all_but(full, driven, path), **locked}
    joints = list(full.names[1:])
    unknown = [j for j in locked if j not in joints]
    if unknown:
        raise ModelError(f"locked joints {unknown} are not in {path.name}; its joints: {joints}",
                         "locked_joints")
    return locked


def _all_but(full: pin.Model, driven: Sequence[str], path: Path) -> dict[str, float]:
    """Every joint of ``full`` but the ``driven`` ones, each at 0 moved into its range."""
    missing = [j for j in driven if j not in full.names]
    if missing:
        raise ModelError(f"driven joints {missing} are not in {path.name}", "driven")
    out = {}
    for jid in range(1, full.njoints):
        if full.names[jid] in driven or full.joints[jid].nq != 1:
            continue
        idx = full.joints[jid].idx_q
        lo, hi = full.lowerPositionLimit[idx], full.upperPositionLimit[idx]
        out[full.names[jid]] = float(np.clip(0.0, lo, hi)) if lo <= hi else 0.0
    return out


def narrow(arm: LoadedArm, ranges: Mapping[str, tuple[float, float]]) -> None:
    """Replace driven joints' ranges in the Pinocchio model, the arm's limits and (through
    ``arm.ranges``) its MuJoCo twin; each must lie inside the URDF's."""
    for joint_name, (lo, hi) in ranges.items():
        if joint_name not in arm.joint_names:
            raise ModelError(f"cannot set the range of '{joint_name}': not a driven joint of "
                             f"{arm.name}", "ranges")
        i = arm.joint_names.index(joint_name)
        if not arm.position_lower[i] <= lo < hi <= arm.position_upper[i]:
            raise ModelError(f"range [{lo}, {hi}] of '{joint_name}' is not inside the URDF's "
                             f"[{arm.position_lower[i]}, {arm.position_upper[i]}]", "ranges")
        idx = arm.model.joints[arm.model.getJointId(joint_name)].idx_q
        arm.model.lowerPositionLimit[idx], arm.model.upperPositionLimit[idx] = lo, hi
        arm.position_lower[i], arm.position_upper[i] = lo, hi
        arm.ranges[joint_name] = (lo, hi)


def load_arm(
    name_or_path: str | Path,
    locked_joints: Mapping[str, float] | None = None,
    package_dirs: Sequence[str | Path] = (),
) -> LoadedArm:
    """Load a named ``example-robot-data`` arm (see :data:`ARMS`) or a URDF file.

    For a named arm the default locked joints (its gripper) apply; ``locked_joints`` adds to
    or overrides them.
    """
    if isinstance(name_or_path, str) and name_or_path in ARMS:
        entry = ARMS[name_or_path]
        locked = {**entry.locked_joints, **(locked_joints or {})}
        arm = load_urdf(arm_urdf(name_or_path), locked, name_or_path, package_dirs,
                        entry.driven)
        arm.tip = entry.tip
        narrow(arm, entry.ranges)
        if entry.torque_rate is not None:
            arm.torque_rate_limits = np.full(arm.n, entry.torque_rate)
        if entry.armature is not None:
            arm.declared_dynamics = (np.array(entry.armature), np.array(entry.viscous),
                                     np.array(entry.coulomb))
        arm.velocity_limits = entry.velocity_limits
        return arm
    path = Path(name_or_path)
    if path.suffix.lower() not in (".urdf", ".xml"):  # a URDF saved as .xml is common
        raise ModelError(
            f"unknown robot '{name_or_path}'; available: {', '.join(available_arms())}, "
            "or a path to a .urdf file"
        )
    return load_urdf(path, locked_joints, package_dirs=package_dirs)
