"""``python -m cpbc.robot NAME_OR_PATH``: what cpbc sees of an arm, and a scenario to start from.

Prints the driven joints in order with their position ranges, rate and effort limits, the
locked and continuous joints, the frames (for ``point_outside_sphere.frame`` and clearance
primitives) and the links with collision geometry (what ``clearance`` covers by default),
all as YAML comments, followed by a valid scenario (PD + gravity and CPBC on the arm's own
limits). So ``python -m cpbc.robot kinova > kinova.yaml`` gives a file that
``python -m cpbc.run kinova.yaml`` runs. Exit code 2 for a name or path it cannot load.
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import yaml

from cpbc.errors import CpbcError, ModelError
from cpbc.model.actuators import apply_actuator_efforts
from cpbc.model.arms import ARMS
from cpbc.model.collision_geoms import covered_bodies
from cpbc.model.gravity_load import BRAKING_DECELERATION, holdable_near, joint_loads
from cpbc.model.loading import load_arm
from cpbc.model.mjcf_arm import check_mjcf_arm
from cpbc.model.robot_model import RobotModel
from cpbc.model.urdf_text import package_dir
from cpbc.resources import builtin_models
from cpbc.scenario.gain_check import physical_gains, spectral_radius
from cpbc.scenario.robots import xml_root
from cpbc.scenario.skeleton import JointLimits, home, skeleton


@dataclass(frozen=True)
class RobotDescription:
    """An arm as a scenario refers to it.

    Attributes:
        model: what to write in ``robot.model`` (a name, or an absolute path).
        summary: one line about the arm.
        limits: the driven joints and their declared limits.
        frames: every frame of the Pinocchio model below the world.
        covered_links: moving links with collision geometry (an MJCF's: with a colliding
            geom).
        locked: joints frozen by default, with their values.
        continuous: joints driven as unbounded revolute joints.
        pin_model: Pinocchio model of the driven joints (for the inertia of the gains).
        regularised: joints whose link inertia was raised to the least MuJoCo accepts.
        estimated: joints whose link the file gives a mass and an all-zero inertia, given a
            solid box's of its geometry (cpbc.model.solid_inertias).
        package_dirs: the ``package://`` folders it was loaded with (absolute; a folder or
            NAME=FOLDER), for the skeleton's ``robot.package_dirs``.
        rotor_driven: an MJCF's joints whose links have next to no inertia of their own
            (:data:`LEAST_INERTIA`) but a declared armature: the skeleton takes the file's
            armature (``robot.armature: from_model``), which ``pin_model`` then holds.
        mjcf: read from an MJCF file, whose joints a scenario cannot lock.
    """

    model: str
    summary: str
    limits: JointLimits
    frames: tuple[str, ...]
    covered_links: tuple[str, ...] = ()
    locked: dict[str, float] = field(default_factory=dict)
    continuous: tuple[str, ...] = ()
    pin_model: pin.Model | None = field(default=None, compare=False, repr=False)
    regularised: tuple[str, ...] = ()
    package_dirs: tuple[str, ...] = ()
    estimated: tuple[str, ...] = ()
    rotor_driven: tuple[str, ...] = ()
    mjcf: bool = False


#: A joint whose link, with all it carries, has less inertia about the joint than this
#: [kg·m² or kg] cannot be driven at 1 kHz without the rotor's (dm-control's Jaco: 6e-13).
LEAST_INERTIA = 1e-6


def _rotor_driven(pm: pin.Model, mj: mujoco.MjModel) -> tuple[str, ...]:
    """Joints of an MJCF whose own inertia at the neutral pose is below LEAST_INERTIA and
    that the file gives an armature; ``pm`` is left with the file's armature then, with none
    otherwise (what the scenario's ``robot.armature`` defaults to)."""
    bare = pin.Model(pm)
    bare.armature = np.zeros(pm.nv)
    own = np.diag(pin.crba(bare, bare.createData(), pin.neutral(bare)))
    declared = np.asarray(mj.dof_armature[:pm.nv], dtype=float)
    light = (own < LEAST_INERTIA) & (declared > 0)
    if not light.any():  # the scenario's default: no armature
        pm.armature = np.zeros(pm.nv)
        return ()
    pm.armature = declared
    return tuple(pm.names[1 + int(i)] for i in np.flatnonzero(light))


def _frames(model: pin.Model) -> tuple[str, ...]:
    return tuple(dict.fromkeys(f.name for f in model.frames if f.name != "universe"))


def _describe_urdf(name_or_path: str, locked: Mapping[str, float] | None = None,
                   package_dirs: Sequence[str] = ()) -> RobotDescription:
    arm = load_arm(name_or_path, locked, package_dirs)
    model = name_or_path if name_or_path in ARMS else str(Path(name_or_path).resolve())
    covered = tuple(dict.fromkeys(
        arm.model.frames[g.parentFrame].name for g in arm.collision_model.geometryObjects
        if g.parentJoint > 0))
    summary = ARMS[name_or_path].summary if name_or_path in ARMS else f"URDF {arm.urdf_path}"
    kept = None
    if arm.velocity_limits is not None:
        lo, hi = arm.velocity_limits.range_for(0.5 * arm.velocity_limits.peak)
        kept = np.maximum(lo, arm.position_lower), np.minimum(hi, arm.position_upper)
    limits = JointLimits(arm.joint_names, arm.position_lower, arm.position_upper,
                         arm.velocity_limit, arm.effort_limit, kept)
    return RobotDescription(model, summary, limits, _frames(arm.model), covered,
                            dict(arm.locked_joints), arm.continuous_joints, arm.model,
                            arm.regularised, tuple(package_dirs), arm.estimated)


def _describe_mjcf(path: Path, model_name: str) -> RobotDescription:
    try:
        mj = mujoco.MjModel.from_xml_path(str(path))
        check_mjcf_arm(path, mj)
        pm = pin.buildModelFromMJCF(str(path))
    except (ValueError, RuntimeError) as exc:
        raise ModelError(f"could not load {path}: {exc}") from None
    n = pm.nq
    limited = mj.jnt_limited[:n].astype(bool)
    lower = np.where(limited, mj.jnt_range[:n, 0], -np.inf)
    upper = np.where(limited, mj.jnt_range[:n, 1], np.inf)
    effort = apply_actuator_efforts(pm, mj)  # what from_model reads when it runs
    limits = JointLimits(tuple(pm.names[1:]), lower, upper, np.full(n, np.inf),
                         np.where(effort > 0, effort, np.inf))
    return RobotDescription(model_name, f"MJCF {path}", limits, _frames(pm),
                            covered_bodies(mj), pin_model=pm, rotor_driven=_rotor_driven(pm, mj),
                            mjcf=True)


def describe(name_or_path: str, locked: Mapping[str, float] | None = None,
             package_dirs: Sequence[str] = ()) -> RobotDescription:
    """The description of a built-in model, an example-robot-data arm, or a model file
    (a URDF's ``locked`` joints frozen at their values besides its defaults, its
    ``package://`` meshes also looked up in ``package_dirs``)."""
    builtin = builtin_models()
    if name_or_path in builtin:
        return _describe_mjcf(builtin[name_or_path], name_or_path)
    path = Path(name_or_path)
    if name_or_path not in ARMS:
        if path.is_dir():
            raise ModelError(f"{name_or_path} is a directory: give a .urdf or .xml file in it")
        if path.name.lower().endswith(".xacro"):
            raise ModelError(f"{name_or_path} is xacro source, not a URDF: expand it first "
                             "(xacro FILE > arm.urdf)")
        if path.suffix.lower() == ".xml":
            if not path.is_file():
                raise ModelError(f"model file not found: {name_or_path}")
            if xml_root(path) != "robot":  # a URDF saved as .xml is read as one
                return _describe_mjcf(path, str(path.resolve()))
        if path.suffix.lower() not in (".urdf", ".xml"):
            raise ModelError(
                f"unknown robot '{name_or_path}': give a built-in model "
                f"({', '.join(builtin)}), an example-robot-data arm "
                f"({', '.join(sorted(ARMS))}) or a path to a .urdf or .xml file")
    return _describe_urdf(name_or_path, locked, package_dirs)


OMEGAS = (10.0, 5.0, 2.0, 1.0)  # rad/s, tried in turn for the skeleton's gains


def stable_omega(d: RobotDescription, states: Sequence[np.ndarray], period: float = 0.001,
                 zeta: float = 1.0) -> float | None:
    """The largest of :data:`OMEGAS` whose physical gains (at the first state's D_ii) keep the
    held loop stable at twice ``period`` at every state (cpbc.scenario.gain_check): arms near a
    singular pose couple their joints strongly. None when none does; the smallest for a model
    without a Pinocchio twin."""
    if d.pin_model is None:
        return OMEGAS[-1]
    data = d.pin_model.createData()

    def inertia(q: np.ndarray) -> np.ndarray:
        m = pin.crba(d.pin_model, data, q)
        return np.triu(m) + np.triu(m, 1).T

    ds = [inertia(np.asarray(q, dtype=float)) for q in states]
    n = len(d.limits.names)
    for omega in OMEGAS:
        kp, kd = physical_gains(np.full(n, omega), np.full(n, zeta), np.diag(ds[0]))
        if all(spectral_radius(kp, kd, m, 2 * period) < 1.0 for m in ds):
            return omega
    return None


#: Share of each joint range kept clear when the target is lowered for the motors.
CLEAR_OF_RANGE = 0.1


def suggested_pose(d: RobotDescription) -> tuple[np.ndarray, np.ndarray]:
    """The skeleton's target and start (cpbc.scenario.skeleton.home): mid-range, or, where
    the motors cannot carry the arm there with room to brake, the configuration near it
    (inside the ranges, clear of their ends) where they can (gravity_load.holdable_near)."""
    target, start = home(d.limits)
    lim = d.limits
    if d.pin_model is None or not np.any(np.isfinite(lim.effort)):
        return target, start
    finite = np.isfinite(lim.lower) & np.isfinite(lim.upper)
    clear = np.where(finite, CLEAR_OF_RANGE * (lim.upper - lim.lower), 0.0)
    lowered = holdable_near(RobotModel(pin.Model(d.pin_model)), target, lim.lower + clear,
                            lim.upper - clear, lim.effort)
    return home(lim, lowered)


#: The skeleton's default duration [s], and in periods of its ω_n when that is longer: a
#: critically damped joint is within 1 % at ω_n t ≈ 6.6, but the xArm7's wrist joints,
#: coupled, ring until ω_n t ≈ 10 at ω_n = 2, and the settle window comes on top.
DURATION, SETTLE_PERIODS = 5.0, 20.0


def scenario_for(d: RobotDescription, duration: float | None = None,
                 locked: Mapping[str, float] | None = None) -> dict:
    """The skeleton scenario of an arm, with gains its held loop tolerates at 1 kHz (the
    smallest tried where none does), and the joints ``locked`` besides the arm's defaults;
    ``duration`` by default long enough for those gains to settle (:data:`SETTLE_PERIODS`)."""
    target, start = suggested_pose(d)
    omega = stable_omega(d, [target, start]) or OMEGAS[-1]
    if duration is None:
        duration = max(DURATION, SETTLE_PERIODS / omega)
    data = skeleton(d.model, d.limits, duration, omega_n=omega, target=target)
    if locked:
        data["robot"]["locked_joints"] = dict(locked)
    if d.rotor_driven:
        data["robot"]["armature"] = "from_model"
    if d.package_dirs:
        data["robot"]["package_dirs"] = list(d.package_dirs)
    return data


def _at_zero(d: RobotDescription, joints: Sequence[str]) -> dict[str, float]:
    """The ``joints`` at 0 moved into their ranges."""
    lim = d.limits
    return {j: float(np.clip(0.0, lim.lower[i], lim.upper[i]))
            for i, j in enumerate(lim.names) if j in joints}


def _overloaded(d: RobotDescription) -> dict[str, float]:
    """Joints whose motors cannot hold the arm up even at the suggested target (the target
    already lowered where it helps): a TIAGo dual's suspension carries the robot's weight."""
    if d.pin_model is None or not np.any(np.isfinite(d.limits.effort)):
        return {}
    target, _ = suggested_pose(d)
    loads = joint_loads(RobotModel(pin.Model(d.pin_model)), target, d.limits.effort)
    return _at_zero(d, [load.joint for load in loads if not load.held])


def _massless(d: RobotDescription) -> dict[str, float]:
    """Joints whose link inertia was raised to the least MuJoCo accepts (the URDF leaves it
    at zero), when no gain of :data:`OMEGAS` holds the loop stable at 1 kHz with them (the
    full iCub's neck: a massless link no sampled-data law can drive at that rate)."""
    if not d.regularised or d.pin_model is None:
        return {}
    if stable_omega(d, list(suggested_pose(d))) is not None:
        return {}
    return _at_zero(d, d.regularised)


def for_skeleton(name_or_path: str, package_dirs: Sequence[str] = ()
                 ) -> tuple[RobotDescription, dict[str, float]]:
    """The arm's description and the joints its skeleton locks (at 0 moved into their ranges)
    besides the arm's defaults: those whose motors cannot hold the arm up anywhere near the
    suggested target, then those a sampled-data law cannot drive at 1 kHz (massless links)."""
    d = describe(name_or_path, package_dirs=package_dirs)
    locked: dict[str, float] = {}
    for find in (_overloaded, _massless):
        found = find(d)
        if found and d.mjcf:  # a skeleton locking them would be refused by cpbc.run
            effort = dict(zip(d.limits.names, d.limits.effort, strict=True))
            raise ModelError(
                f"{name_or_path}: the motors of " + ", ".join(
                    f"{j} ({effort[j]:.4g} N·m)" for j in found) + " cannot hold the arm up "
                "near any target tried, and an MJCF arm's joints cannot be locked (robot."
                "locked_joints needs a URDF): raise their effort limits in the file (the "
                "motor's ctrlrange × gear, its forcerange or the joint's actuatorfrcrange)")
        if found:
            locked |= found
            d = describe(name_or_path, {**d.locked, **found}, package_dirs)
    return d, locked


def _number(v: float, unit: str = "") -> str:
    return "-" if not np.isfinite(v) else f"{v:.4g}{unit}"


def gravity_at_target(d: RobotDescription) -> list[str]:
    """Per joint with an effort limit, the torque gravity asks of it at the skeleton's
    target, with the brake's allowance on top (cpbc.model.gravity_load), against the limit."""
    if d.pin_model is None:
        return []
    target, _ = suggested_pose(d)
    loads = joint_loads(RobotModel(pin.Model(d.pin_model)), target, d.limits.effort)
    if not loads:
        return []
    width = max(len(load.joint) for load in loads)
    lowered = not np.array_equal(target, home(d.limits)[0])
    lines = [f"gravity at the suggested target [N·m], + the brake's allowance "
             f"(at {BRAKING_DECELERATION:g} rad/s²), against the effort limit:"]
    if lowered:
        lines.append("(the target is lowered from mid-range, where the motors could not "
                     "carry the arm with room to brake)")
    for load in loads:
        verdict = (" cannot hold it: a run is refused" if not load.held else
                   " no room to brake" if not load.brakes else "")
        lines.append(f"  {load.joint:<{width}}  {load.gravity:8.2f} + {load.braking:5.2f} of "
                     f"{load.limit:<7.4g} {load.share:5.0%}{verdict}")
    return lines


def report(d: RobotDescription) -> str:
    """The description as YAML comment lines."""
    lim = d.limits
    lines = [f"{d.model}: {d.summary}", f"{len(lim.names)} driven joints, in the order of x:"]
    width = max(len(n) for n in lim.names)
    lines.append(f"  {'joint':<{width}}  {'range':>20}  {'rate':>8}  {'effort':>8}")
    for i, name in enumerate(lim.names):
        rng = ("unbounded" if not np.isfinite(lim.lower[i]) else
               f"[{lim.lower[i]:.4g}, {lim.upper[i]:.4g}]")
        tag = " (continuous)" if name in d.continuous else ""
        lines.append(f"  {name:<{width}}  {rng:>20}  {_number(lim.velocity[i]):>8}  "
                     f"{_number(lim.effort[i]):>8}{tag}")
    lines += gravity_at_target(d)
    if d.regularised:
        lines += textwrap.wrap(
            "inertia raised to the least MuJoCo accepts (by at most 1e-6 kg·m², in both "
            "engines) on the links of: " + ", ".join(d.regularised), 96,
            subsequent_indent="  ")
    if d.rotor_driven:
        lines += textwrap.wrap(
            "armature from the file (robot.armature: from_model): without it the links of "
            f"{', '.join(d.rotor_driven)} have less than {LEAST_INERTIA:g} kg·m² of inertia "
            "about their joints, which no law can drive at 1 kHz", 96,
            subsequent_indent="  ")
    if d.estimated:
        lines += textwrap.wrap(
            "inertia estimated from the mass and the geometry, as a solid box of uniform "
            "density bounding the link (the file gives a mass and an all-zero inertia "
            "tensor) on the links of: " + ", ".join(d.estimated), 96, subsequent_indent="  ")
    if d.locked:
        lines.append("locked by default: " + ", ".join(f"{k} = {v:g}" for k, v in
                                                       d.locked.items()))
    lines += textwrap.wrap("frames: " + ", ".join(d.frames), 96, subsequent_indent="  ")
    lines += textwrap.wrap("links with collision geometry (clearance covers these): " + (
        ", ".join(d.covered_links) if d.covered_links else "none (declare primitives)"), 96,
        subsequent_indent="  ")
    return "".join(f"# {line}\n" for line in lines)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m cpbc.robot",
        description="Describe an arm (joints, limits, frames, collision links) and print a "
                    "scenario to start from.")
    p.add_argument("robot", help="a built-in model, an example-robot-data arm "
                   f"({', '.join(sorted(ARMS))}), or a path to a .urdf or .xml file")
    p.add_argument("--duration", type=float, default=None, help=(
        f"of the scenario [s] (default {DURATION:g}, or {SETTLE_PERIODS:g}/omega_n when the "
        "gains are slower)"))
    p.add_argument("--package-dir", action="append", default=[], metavar="NAME=PATH",
                   help="the folder of package://NAME/ meshes, when it is not called NAME "
                   "(repeatable; a bare PATH is a folder holding packages)")
    return p


def package_dirs(given: Sequence[str]) -> tuple[str, ...]:
    """The ``--package-dir`` entries with absolute folders; ModelError naming the first
    whose folder does not exist."""
    out = []
    for entry in given:
        name, folder = package_dir(entry)
        if not folder.is_dir():
            raise ModelError(f"--package-dir {entry}: {folder} is not a folder; give "
                             "NAME=PATH with PATH the folder that package://NAME/ stands for",
                             "package_dirs")
        out.append(str(folder.resolve()) if name is None else f"{name}={folder.resolve()}")
    return tuple(out)


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        d, locked = for_skeleton(args.robot, package_dirs(args.package_dir))
    except CpbcError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    scenario = scenario_for(d, args.duration, locked)
    why = "".join(f"# {line}\n" for line in textwrap.wrap(
        "the skeleton locks " + ", ".join(locked) + ": motors that cannot hold the arm up "
        "near any target tried, or links without inertia (no gain is stable at 1 kHz)", 96,
        subsequent_indent="  ")) if locked else ""
    sys.stdout.write(report(d) + why + "# --- scenario (python -m cpbc.run FILE) ---\n"
                     + yaml.safe_dump(scenario, sort_keys=False, default_flow_style=None,
                                      width=100))
    return 0


if __name__ == "__main__":
    sys.exit(main())
