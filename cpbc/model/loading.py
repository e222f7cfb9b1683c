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
  set to zero in MuJoCo because the controller's model does not contain them (use the
  scenario's ``robot.viscous_friction`` to model viscous friction in both engines). The URDF
  joint ranges stay in MuJoCo as hard stops. Collision meshes of links that can move collide
  with obstacles only (``contype=1, conaffinity=0``: no self-contacts, nothing for links
  welded to the world), so MuJoCo's contact count is a witness of robot–obstacle contact.
* **Limits.** Joint position, velocity and effort limits of the reduced model, as read from
  the URDF ``<limit>`` tags.

``example-robot-data`` ships URDFs and meshes but not its Python loader; :data:`ARMS` lists
the arms of that package that this module knows, with their gripper joints locked by default.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.errors import ModelError
from cpbc.model.inertias import apply_joint_inertias, regularise_inertias
from cpbc.model.meshes import mujoco_mesh

GRAVITY = np.array([0.0, 0.0, -9.81])


@dataclass(frozen=True)
class ArmEntry:
    """An arm shipped by ``example-robot-data``.

    Attributes:
        urdf: URDF path relative to the package's ``robots/`` folder.
        locked_joints: joints frozen by default (grippers), with their values [rad or m].
        summary: one line for listings.
        tip: the link at the tool centre point; the MuJoCo model gets a site ``end_point``
            there (the point the viewer traces).
        driven: for the arm of a larger robot (a mobile manipulator, a quadruped carrying an
            arm): the joints to drive; every other joint is locked (``load_urdf``).
    """

    urdf: str
    locked_joints: Mapping[str, float] = field(default_factory=dict)
    summary: str = ""
    tip: str | None = None
    driven: tuple[str, ...] | None = None


# Baxter is two 7-DOF arms on a fixed torso: each is an arm of its own, the rest locked.
_BAXTER_OTHERS = {"head_pan": 0.0, "l_gripper_l_finger_joint": 0.0,
                  "l_gripper_r_finger_joint": 0.0, "r_gripper_l_finger_joint": 0.0,
                  "r_gripper_r_finger_joint": 0.0}
_BAXTER_LEFT = {f"left_{j}": 0.0 for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")}
_BAXTER_RIGHT = {f"right_{j}": 0.0 for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")}

ARMS: dict[str, ArmEntry] = {
    "panda": ArmEntry(
        "panda_description/urdf/panda.urdf",
        {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0},
        "Franka Emika Panda, 7 DOF (fingers locked closed)", "panda_hand_tcp",
    ),
    "ur3": ArmEntry("ur_description/urdf/ur3_robot.urdf", {}, "Universal Robots UR3, 6 DOF",
                    "tool0"),
    "ur5": ArmEntry("ur_description/urdf/ur5_robot.urdf", {}, "Universal Robots UR5, 6 DOF",
                    "tool0"),
    "ur10": ArmEntry("ur_description/urdf/ur10_robot.urdf", {}, "Universal Robots UR10, 6 DOF",
                     "tool0"),
    # the same arms with joint ranges of ±π (the "joint limited" descriptions) or a gripper
    # welded to the flange
    "ur3_limited": ArmEntry("ur_description/urdf/ur3_joint_limited_robot.urdf", {},
                            "Universal Robots UR3, 6 DOF, joints limited to ±π", "tool0"),
    "ur5_limited": ArmEntry("ur_description/urdf/ur5_joint_limited_robot.urdf", {},
                            "Universal Robots UR5, 6 DOF, joints limited to ±π", "tool0"),
    "ur10_limited": ArmEntry("ur_description/urdf/ur10_joint_limited_robot.urdf", {},
                             "Universal Robots UR10, 6 DOF, joints limited to ±π", "tool0"),
    "ur3_gripper": ArmEntry("ur_description/urdf/ur3_gripper.urdf", {},
                            "Universal Robots UR3 with a fixed gripper, 6 DOF", "tool0"),
    "ur5_gripper": ArmEntry("ur_description/urdf/ur5_gripper.urdf", {},
                            "Universal Robots UR5 with a fixed gripper, 6 DOF", "tool0"),
    "xarm7": ArmEntry("xarm_description/urdf/xarm7.urdf", {}, "UFactory xArm 7, 7 DOF",
                      "link_eef"),
    "z1": ArmEntry(
        "z1_description/urdf/z1.urdf", {"jointGripper": 0.0}, "Unitree Z1, 6 DOF (gripper locked)",
        "gripperStator",
    ),
    "kinova": ArmEntry(
        "kinova_description/robots/kinova.urdf", {},
        "Kinova Jaco2 (j2s6s200), 6 DOF, joints 1, 4, 6 continuous; Collada meshes",
        "j2s6s200_end_effector",
    ),
    # The SO-ARM100's jaw joint and its link are both named "gripper", which Pinocchio's
    # buildReducedModel cannot tell apart: the jaw stays a driven joint.
    "so100": ArmEntry(
        "so_arm_description/urdf/so100.urdf", {}, "SO-ARM100, 5 DOF and the jaw", "jaw",
    ),
    "so101": ArmEntry(
        "so_arm_description/urdf/so101.urdf", {"gripper": 0.0},
        "SO-ARM101, 5 DOF (jaw locked)", "gripper_frame_link",
    ),
    "talos_arm": ArmEntry(
        "talos_data/robots/talos_left_arm.urdf", {"gripper_left_joint": 0.0},
        "PAL TALOS left arm, 6 DOF (gripper locked)", "wrist_left_ft_tool_link",
    ),
    "baxter_left": ArmEntry(
        "baxter_description/urdf/baxter.urdf", {**_BAXTER_OTHERS, **_BAXTER_RIGHT},
        "Rethink Baxter's left arm, 7 DOF (head, right arm and grippers locked)",
        "left_gripper",
    ),
    "baxter_right": ArmEntry(
        "baxter_description/urdf/baxter.urdf", {**_BAXTER_OTHERS, **_BAXTER_LEFT},
        "Rethink Baxter's right arm, 7 DOF (head, left arm and grippers locked)",
        "right_gripper",
    ),
    # The arms of mobile manipulators and legged robots, the rest of the robot locked
    # (base fixed to the world, legs, wheels, torso, head and hand held at 0 or the nearest
    # end of their range).
    "tiago_arm": ArmEntry(
        "tiago_description/robots/tiago.urdf", {}, "PAL TIAGo's arm, 7 DOF (the rest locked)",
        "arm_tool_link", tuple(f"arm_{i}_joint" for i in range(1, 8)),
    ),
    "tiago_pro_left": ArmEntry(
        "tiago_pro_description/robots/tiago_pro.urdf", {},
        "PAL TIAGo Pro's left arm, 7 DOF (the rest locked)", "arm_left_tool_link",
        tuple(f"arm_left_{i}_joint" for i in range(1, 8)),
    ),
    "pr2_left": ArmEntry(
        "pr2_description/urdf/pr2.urdf", {}, "Willow Garage PR2's left arm, 7 DOF "
        "(the rest locked)", "l_gripper_tool_frame",
        tuple(f"l_{j}_joint" for j in ("shoulder_pan", "shoulder_lift", "upper_arm_roll",
                                        "elbow_flex", "forearm_roll", "wrist_flex",
                                        "wrist_roll")),
    ),
    "pr2_right": ArmEntry(
        "pr2_description/urdf/pr2.urdf", {}, "Willow Garage PR2's right arm, 7 DOF "
        "(the rest locked)", "r_gripper_tool_frame",
        tuple(f"r_{j}_joint" for j in ("shoulder_pan", "shoulder_lift", "upper_arm_roll",
                                        "elbow_flex", "forearm_roll", "wrist_flex",
                                        "wrist_roll")),
    ),
    "b1_z1": ArmEntry(
        "b1_description/urdf/b1-z1.urdf", {}, "Unitree Z1 on a B1 quadruped, 6 DOF "
        "(legs and gripper locked)", "gripperStator", tuple(f"joint{i}" for i in range(1, 7)),
    ),
    "anymal_kinova": ArmEntry(
        "anymal_b_simple_description/robots/anymal-kinova.urdf", {},
        "Kinova arm on an ANYmal B, 6 DOF (legs locked)", "j2s6s200_end_effector",
        tuple(f"j2s6s200_joint_{i}" for i in range(1, 7)),
    ),
}

_MESH_URI = re.compile(r'(<mesh\b[^>]*?\bfilename\s*=\s*)(["\'])(.*?)\2', re.DOTALL)
# A <joint> element of the kinematic tree (self-closing or with children); <transmission>'s
# <joint name=…> has no type and is left alone.
_JOINT = re.compile(r"<joint\b[^>]*?/>|<joint\b[^>]*?[^/]>.*?</joint>", re.DOTALL)
_JOINT_HEAD = re.compile(r"<joint\b[^>]*>", re.DOTALL)
_CONTINUOUS = re.compile(r"""\btype\s*=\s*(["'])continuous\1""")
_REVOLUTE = re.compile(r"""\btype\s*=\s*(["'])revolute\1""")
_NAME = re.compile(r"""\bname\s*=\s*(["'])(.*?)\1""")
_LIMIT = re.compile(r"<limit\b[^>]*>", re.DOTALL)
_LOWER_UPPER = re.compile(r"""\s(lower|upper)\s*=\s*(["']).*?\2""")
_COMMENT = re.compile(r"<!--.*?-->", re.DOTALL)
_TYPED = re.compile(r"""\btype\s*=""")
_ROBOT_END = re.compile(r"</robot\s*>\s*$")


def example_robot_data_share() -> Path | None:
    """The ``share`` folder that holds ``example-robot-data/robots``, or None if not installed."""
    try:
        import cmeel

        roots = [Path(cmeel.__file__).resolve().parent.parent / "cmeel.prefix" / "share"]
    except ImportError:  # pragma: no cover - cmeel comes with pin
        roots = []
    roots += [Path(p) / "cmeel.prefix" / "share" for p in _site_packages()]
    for root in roots:
        if (root / "example-robot-data" / "robots").is_dir():
            return root
    return None


def _site_packages() -> list[str]:
    import site
    import sysconfig

    paths = [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]]
    try:
        paths += site.getsitepackages()
    except AttributeError:  # pragma: no cover - virtualenv's old site module
        pass
    return list(dict.fromkeys(paths))


def available_arms() -> list[str]:
    """Names of the ``example-robot-data`` arms that :func:`load_arm` accepts."""
    return sorted(ARMS)


def arm_urdf(name: str) -> Path:
    """The URDF file of a named ``example-robot-data`` arm."""
    if name not in ARMS:
        raise ModelError(f"unknown robot '{name}'; available: {', '.join(available_arms())}")
    share = example_robot_data_share()
    if share is None:
        raise ModelError(
            f"robot '{name}' comes from the example-robot-data package, which is not installed "
            "(pip install example-robot-data)"
        )
    path = share / "example-robot-data" / "robots" / ARMS[name].urdf
    if not path.is_file():
        raise ModelError(f"example-robot-data is installed but lacks {path}")
    return path


def _package_dirs(urdf: Path, extra: Sequence[str | Path]) -> list[Path]:
    """Folders in which ``package://NAME/...`` is looked up as ``folder/NAME/...`` (after the
    URDF's own folders, see :func:`resolve_mesh_uri`).

    Raises:
        ModelError: one of ``extra`` is not an existing folder.
    """
    missing = [str(p) for p in extra if not Path(p).is_dir()]
    if missing:
        raise ModelError(f"package_dirs {missing} do not exist or are not folders",
                         "package_dirs")
    dirs = [Path(p) for p in extra]
    dirs += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    share = example_robot_data_share()
    if share is not None:
        dirs.append(share)
    dirs += list(urdf.resolve().parents)
    return list(dict.fromkeys(dirs))


def resolve_mesh_uri(uri: str, urdf: Path, package_dirs: Sequence[Path]) -> Path:
    """Absolute path of a URDF mesh reference; ModelError naming the URI if it is missing.

    ``package://NAME/rest`` is first looked up from the URDF's own location (the nearest of
    its parent folders called NAME), so that a package shipped with its URDF wins over a
    namesake elsewhere, then as ``folder/NAME/rest`` in each of ``package_dirs``.
    """
    looked: list[Path] = []
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        looked += [d / rest for d in urdf.resolve().parents if d.name == package]
        for d in package_dirs:
            looked.append(d / package / rest)
            if d.name == package:
                looked.append(d / rest)
    elif uri.startswith("file://"):
        looked.append(Path(uri[len("file://"):]))
    else:
        p = Path(uri)
        looked.append(p if p.is_absolute() else urdf.resolve().parent / p)
    for p in looked:
        if p.is_file():
            return p.resolve()
    where = ", ".join(str(p) for p in looked[:4]) + (" …" if len(looked) > 4 else "")
    raise ModelError(f"mesh '{uri}' referenced by {urdf} not found (looked in {where})")


def resolve_urdf_meshes(
    urdf: Path, text: str | None = None, package_dirs: Sequence[str | Path] = ()
) -> str:
    """The URDF text, without its comments, with every mesh filename replaced by an absolute
    path."""
    text = _COMMENT.sub("", urdf.read_text() if text is None else text)
    dirs = _package_dirs(urdf, package_dirs)

    def sub(m: re.Match[str]) -> str:
        path = mujoco_mesh(resolve_mesh_uri(m.group(3), urdf, dirs))
        return f"{m.group(1)}{m.group(2)}{path}{m.group(2)}"

    return _MESH_URI.sub(sub, text)


def sort_joints(text: str) -> str:
    """The URDF text with the joints of its kinematic tree in name order, after the links.

    Pinocchio (through urdfdom) visits the children of a link in the order of their joints'
    names, MuJoCo's URDF parser in the order of the file; in name order both number the joints
    of a branching robot (two arms, four legs) alike. Comments must be gone (see
    :func:`resolve_urdf_meshes`): a commented-out joint would be moved out of its comment.
    """
    blocks = [m for m in _JOINT.finditer(text)
              if (head := _JOINT_HEAD.match(m.group(0))) and _TYPED.search(head.group(0))]

    def name(m: re.Match[str]) -> str:
        head = _JOINT_HEAD.match(m.group(0))
        found = _NAME.search(head.group(0)) if head else None
        return found.group(2) if found else ""

    end = _ROBOT_END.search(text)
    if not blocks or end is None:
        return text
    parts, last = [], 0
    for m in blocks:
        parts.append(text[last:m.start()])
        last = m.end()
    parts.append(text[last:end.start()])
    joints = "\n".join(m.group(0) for m in sorted(blocks, key=name))
    return "".join(parts) + joints + "\n" + text[end.start():]


def unbound_continuous_joints(text: str) -> tuple[str, tuple[str, ...]]:
    """The URDF text with every ``continuous`` joint made ``revolute`` without position
    limits, and the names of those joints.

    Pinocchio models a continuous joint by (cos q, sin q) (nq = 2, nv = 1), MuJoCo by the
    angle (nq = nv = 1); as an unbounded revolute joint both use the angle, so q means the
    same in both engines and the controllers' x = q holds. The ``<limit>`` keeps its effort
    and velocity; its lower/upper (meaningless for a continuous joint) are dropped, and the
    loader marks the joint unbounded in both engines.

    A continuous or revolute joint without ``<limit>`` (TIAGo dual's casters) gets one
    without effort or rate limit (urdfdom, hence Pinocchio, refuses a revolute joint without);
    a revolute one is then read as what it describes, a continuous joint.
    """
    names: list[str] = []

    def sub(m: re.Match[str]) -> str:
        block = m.group(0)
        head = _JOINT_HEAD.match(block)
        if head is None:
            return block
        no_limit = block.endswith("</joint>") and not _LIMIT.search(block)
        if not (_CONTINUOUS.search(head.group(0))
                or (no_limit and _REVOLUTE.search(head.group(0)))):
            return block
        name = _NAME.search(head.group(0))
        names.append(name.group(2) if name else "?")
        block = _CONTINUOUS.sub('type="revolute"', block, count=1)
        if no_limit:  # urdfdom requires one for a revolute joint
            return block[:-len("</joint>")] + '<limit effort="0" velocity="0"/></joint>'
        return _LIMIT.sub(lambda lim: _LOWER_UPPER.sub("", lim.group(0)), block)

    return _JOINT.sub(sub, text), tuple(names)


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
    lower, upper, vel, eff = _limits(model)
    return LoadedArm(
        name or path.stem, path, text, model, collision, locked, tuple(model.names[1:]),
        lower, upper, vel, eff, continuous_joints=continuous,
        regularised=regularise_inertias(model),
    )


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
        return arm
    path = Path(name_or_path)
    if path.suffix.lower() not in (".urdf", ".xml"):  # a URDF saved as .xml is common
        raise ModelError(
            f"unknown robot '{name_or_path}'; available: {', '.join(available_arms())}, "
            "or a path to a .urdf file"
        )
    return load_urdf(path, locked_joints, package_dirs=package_dirs)
