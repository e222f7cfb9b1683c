"""The arms cpbc knows by name: those of the ``example-robot-data`` package (which ships URDFs
and meshes but not its Python loader) and the Franka FR3 of ``franky-sim`` (which ships its
URDF, from Franka's own description), with the joints each locks by default (its gripper, or
the rest of a larger robot)."""

from __future__ import annotations

import importlib.util
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cpbc.errors import ModelError
from cpbc.model.velocity_limits import PositionDependentVelocity


@dataclass(frozen=True)
class ArmEntry:
    """An arm shipped by ``example-robot-data`` (or by ``franky-sim``: ``package``).

    Attributes:
        urdf: URDF path relative to the package's ``robots/`` folder (franky-sim: its
            ``assets/`` folder).
        locked_joints: joints frozen by default (grippers), with their values [rad or m].
        summary: one line for listings.
        tip: the link at the tool centre point; the MuJoCo model gets a site ``end_point``
            there (the point the viewer traces).
        driven: for the arm of a larger robot (a mobile manipulator, a quadruped carrying an
            arm): the joints to drive; every other joint is locked (``load_urdf``).
        ranges: joint ranges [rad] that replace the URDF's, in both engines (the robot
            maker's published ranges where its URDF's are wider).
        torque_rate: the motors' torque-rate limit [N·m/s] the robot maker publishes (what
            ``simulation.torque_rate_limit: from_model`` reads), or None.
        package: the Python package that ships the URDF.
        armature, viscous, coulomb: per driven joint, the rotor inertia [kg·m²], viscous
            [N·m·s/rad] and Coulomb friction [N·m] that replace what the URDF declares
            (what ``robot.armature`` and ``robot.friction: from_model`` read, and their
            default ``auto``), or None: the URDF's.
        velocity_limits: the robot maker's position-dependent joint velocity limits, which
            ``joint_rate_limit`` bounds must lie inside, or None.
    """

    urdf: str
    locked_joints: Mapping[str, float] = field(default_factory=dict)
    summary: str = ""
    tip: str | None = None
    driven: tuple[str, ...] | None = None
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    torque_rate: float | None = None
    package: str = "example-robot-data"
    armature: tuple[float, ...] | None = None
    viscous: tuple[float, ...] | None = None
    coulomb: tuple[float, ...] | None = None
    velocity_limits: PositionDependentVelocity | None = None

    @property
    def declares_dynamics(self) -> bool:
        """Whether the entry declares its joints' rotor inertia and friction."""
        return self.armature is not None


#: The Python package that ships franky-sim's files, and how cpbc installs it.
FRANKY_SIM = "franky_sim"
FRANKA_EXTRA = "pip install 'cpbc[franka]'"

# Baxter is two 7-DOF arms on a fixed torso: each is an arm of its own, the rest locked.
_BAXTER_OTHERS = {"head_pan": 0.0, "l_gripper_l_finger_joint": 0.0,
                  "l_gripper_r_finger_joint": 0.0, "r_gripper_l_finger_joint": 0.0,
                  "r_gripper_r_finger_joint": 0.0}
_BAXTER_LEFT = {f"left_{j}": 0.0 for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")}
_BAXTER_RIGHT = {f"right_{j}": 0.0 for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2")}

# The FR3's joint ranges [rad], Franka's FCI documentation ("Robot and interface
# specifications": q_min, q_max).
_FR3_RANGES = {
    "fr3_joint1": (-2.7437, 2.7437), "fr3_joint2": (-1.7837, 1.7837),
    "fr3_joint3": (-2.9007, 2.9007), "fr3_joint4": (-3.0421, -0.1518),
    "fr3_joint5": (-2.8065, 2.8065), "fr3_joint6": (0.5445, 4.5169),
    "fr3_joint7": (-3.0159, 3.0159),
}

# The FR3's joints as franky-sim's MuJoCo plant models them (its assets/fr3.xml, franky-sim
# 1.0.4: the class default armature 0.195, damping 0.21, frictionloss 1.137; joints 5-7
# override armature 0.074 and frictionloss 0.763, 0.44, 0.248). Franka publishes no such
# values; the URDF's <dynamics damping="0.003" friction="0.2"> are not what the plant runs.
_FR3_ARMATURE = (0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074)
_FR3_VISCOUS = (0.21,) * 7
_FR3_COULOMB = (1.137, 1.137, 1.137, 1.137, 0.763, 0.44, 0.248)

# The FR3's position-dependent joint velocity limits: Franka's FCI documentation ("Limits for
# Franka Research 3"), as libfranka's rate_limiting.h computes them (0.15, commit 155ddac):
# v, c, k and the two ends a+, a- per joint (cpbc.model.velocity_limits for the formula).
FR3_VELOCITY_LIMITS = PositionDependentVelocity(
    peak=np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26]),
    offset=np.array([0.30, 0.20, 0.20, 0.30, 0.35, 0.35, 0.35]),
    gain=np.array([12.0, 5.17, 7.0, 8.0, 34.0, 11.0, 34.0]),
    upper_end=np.array([2.7501, 1.7918, 2.9065, -0.1458, 2.8101, 4.5205, 3.0196]),
    lower_end=np.array([-2.7501, -1.7918, -2.9065, -3.0481, -2.8101, 0.54092, -3.0196]),
)

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
    # Franka's URDF of the FR3 with its hand, as franky-sim ships it (the simulator's own
    # gravity compensation reads the same links): the fingers locked closed. Velocities
    # (2.62 rad/s on joints 1-4, 5.26, 4.18, 5.26) and torques (87/12 N m) are the URDF's;
    # its joint ranges on joints 1, 2, 4-7 are wider than the FCI's published ones (which
    # franky-sim's MuJoCo plant also stops at): those replace them. Its torque rate: 1000
    # N m/s on every joint (FCI; libfranka's kMaxTorqueRate), beyond which it aborts. Its
    # rotor inertia and joint friction: franky-sim's fr3.xml (above), used by default.
    "fr3": ArmEntry(
        "fr3.urdf", {"fr3_finger_joint1": 0.0, "fr3_finger_joint2": 0.0},
        "Franka Research 3, 7 DOF (fingers locked closed; from franky-sim)", "fr3_hand_tcp",
        ranges=_FR3_RANGES, torque_rate=1000.0, package=FRANKY_SIM,
        armature=_FR3_ARMATURE, viscous=_FR3_VISCOUS, coulomb=_FR3_COULOMB,
        velocity_limits=FR3_VELOCITY_LIMITS,
    ),
}


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


def _franky_sim_asset(name: str, file: str) -> Path:
    """A file of franky-sim's ``assets/`` folder, found without importing franky-sim (which
    would load its simulators)."""
    spec = importlib.util.find_spec(FRANKY_SIM)
    if spec is None or spec.origin is None:
        raise ModelError(f"robot '{name}' comes from the franky-sim package, which is not "
                         f"installed ({FRANKA_EXTRA})")
    path = Path(spec.origin).parent / "assets" / file
    if not path.is_file():
        raise ModelError(f"franky-sim is installed but lacks {path}")
    return path


def arm_urdf(name: str) -> Path:
    """The URDF file of a named arm (``example-robot-data``'s, or franky-sim's FR3)."""
    if name not in ARMS:
        raise ModelError(f"unknown robot '{name}'; available: {', '.join(available_arms())}")
    if ARMS[name].package == FRANKY_SIM:
        return _franky_sim_asset(name, ARMS[name].urdf)
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
