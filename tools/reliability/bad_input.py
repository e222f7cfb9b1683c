"""Invalid scenarios, generated from one valid scenario, and how the CLI answers each.

Every variant must end with exit code 2, a message on stderr that names the offending field,
no traceback, and nothing written: no output folder and no scratch folder next to it.
"""

from __future__ import annotations

import contextlib
import copy
import io
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import yaml

from cpbc.resources import scenarios_dir
from cpbc.run import main

# A small valid scenario that uses every part of the format the variants touch: an obstacle,
# a relative-angle limit, rate limits, a kinetic-energy limit, noise, plant mismatch, and
# each kind of controller.
BASE: dict = {
    "name": "base",
    "robot": {
        "model": "planar_2link",
        "coordinates": "absolute",
        "plant": {"mass_scale": [1.1, 0.9], "damping": 0.01},
    },
    "simulation": {
        "duration": 0.02, "timestep": 0.001, "control_period": 0.002, "integrator": "Euler",
        "noise": {"position": 0.0001, "velocity": 0.001, "seed": 1}, "safeguard": True,
        "torque_limit": 50,
    },
    "target": [1.0, 1.5],
    "cases": [{"name": "rest", "position": [0, 0], "velocity": [0.1, 0.05]}],
    "constraints": [
        {"type": "point_outside_sphere", "name": "obstacle", "frame": "end_point",
         "centre": [0, 2], "radius": 0.5},
        {"type": "linear_limit", "name": "relative_angle", "coefficients": [[-1, 1]],
         "lower": ["-17*pi/18"], "upper": ["17*pi/18"]},
        {"type": "joint_rate_limit", "name": "link_rates", "bounds": [0.3, 0.2]},
        {"type": "kinetic_energy_limit", "name": "energy", "limit": 0.5},
    ],
    "controllers": [
        {"type": "pd", "name": "PD", "kp": 4, "kd": 20},
        {"type": "cpbc", "name": "CPBC", "kp": 4, "kd": 20,
         "shaping": {"type": "power", "alpha": 0.2},
         "constraints": ["obstacle", "relative_angle", "link_rates"]},
        {"type": "bpbc", "name": "BPBC", "kp": [2, 10], "kd": [4, 20], "xi": 1, "gamma": 1,
         "constraints": ["link_rates"]},
        {"type": "bpbc_ke", "name": "BPBC-KE", "kp": 2, "kd": 4, "constraints": ["energy"]},
    ],
}

# A small valid Part I scenario (a system: block): the quarter car with the barrier law and
# its unconstrained comparison; the variants below change a copy of it.
SYSTEM_BASE: dict = {
    "name": "system_base",
    "system": {
        "type": "quarter_car", "travel_limit": 0.1,
        "laws": [{"name": "barrier", "gains": {"k1": 3.5, "k2": 0.051}},
                 {"name": "unconstrained", "barrier": False}],
    },
    "simulation": {"duration": 0.002, "timestep": 0.0001},
    "cases": [{"name": "bump", "bump_height": 0.05, "state": [0, 0, 0, 0]}],
}
RWP_BASE: dict = {
    "name": "rwp_base",
    "system": {"type": "reaction_wheel_pendulum", "laws": [{"name": "barrier"}]},
    "simulation": {"duration": 0.01},
    "cases": [{"name": "side", "state": ["pi/2", 0, 0]}],
}
CHAIN_BASE: dict = {
    "name": "chain_base",
    "system": {"type": "integrator_chain", "laws": [{"name": "barrier"}]},
    "simulation": {"duration": 0.01, "timestep": 0.005, "backend": "reference"},
    "cases": [{"name": "fig4.1", "state": [-10, -1.5, -0.05, -2.5]}],
}

AEROSONDE_BASE: dict = {
    "name": "aerosonde_base",
    "system": {"type": "aerosonde",
               "laws": [{"type": "traditional", "name": "traditional"},
                        {"type": "constrained", "name": "constrained"}]},
    "simulation": {"duration": 0.2, "timestep": 0.1, "backend": "reference"},
    "cases": [{"name": "climb", "state": [100, 0],
               "commands": [{"time": 0.1, "altitude": 150}]}],
}

# Builds the scenario file's content from a copy of BASE; bytes for a file that is not
# text, None when it has put something at ``folder/scenario.yaml`` itself (a directory).
Make = Callable[[dict, Path], "str | bytes | None"]


@dataclass(frozen=True)
class BadInput:
    """One invalid scenario.

    Attributes:
        name: short label.
        category: wrong type, wrong shape, unknown key, non-positive, non-finite,
            inadmissible, model file, structure, file, duplicate key, length, gains.
        field: what the error message must name.
        make: builds the scenario text from a copy of BASE (and may write files in the
            folder, e.g. a broken model).
    """

    name: str
    category: str
    field: str
    make: Make


def _path(data: dict, dotted: str) -> tuple[object, object]:
    keys = [int(k) if k.lstrip("-").isdigit() else k for k in dotted.split(".")]
    node = data
    for k in keys[:-1]:
        node = node[k]
    return node, keys[-1]


def setting(dotted: str, value: object) -> Make:
    """data[a][b][i] = value."""

    def make(data: dict, _folder: Path) -> str:
        node, key = _path(data, dotted)
        node[key] = value  # type: ignore[index]
        return yaml.safe_dump(data, sort_keys=False)

    return make


def removing(dotted: str) -> Make:
    def make(data: dict, _folder: Path) -> str:
        node, key = _path(data, dotted)
        del node[key]  # type: ignore[attr-defined]
        return yaml.safe_dump(data, sort_keys=False)

    return make


def system(dotted: str, value: object, base: dict | None = None) -> Make:
    """A copy of SYSTEM_BASE (or ``base``) with data[a][b][i] = value (a key is deleted
    when ``value`` is REMOVE)."""

    def make(_data: dict, _folder: Path) -> str:
        data = copy.deepcopy(SYSTEM_BASE if base is None else base)
        node, key = _path(data, dotted)
        if value is REMOVE:
            del node[key]  # type: ignore[attr-defined]
        else:
            node[key] = value  # type: ignore[index]
        return yaml.safe_dump(data, sort_keys=False)

    return make


REMOVE = object()


def raw(text: str) -> Make:
    return lambda _data, _folder: text


def model_file(content: str | None, name: str = "arm.xml") -> Make:
    """robot.model points at a file in the folder with this content (None: no file)."""

    def make(data: dict, folder: Path) -> str:
        if content is not None:
            (folder / name).write_text(content)
        data["robot"]["model"] = name
        return yaml.safe_dump(data, sort_keys=False)

    return make


def raw_bytes(data: bytes) -> Make:
    return lambda _data, _folder: data


def directory(_data: dict, folder: Path) -> None:
    """``scenario.yaml`` is a folder (holding a scenario, to tempt a loader)."""
    (folder / "scenario.yaml").mkdir()
    (folder / "scenario.yaml" / "inner.yaml").write_text(yaml.safe_dump(BASE, sort_keys=False))
    return None


def with_yaml(text: str) -> Make:
    """BASE with ``text`` (YAML lines) appended at the end of the file."""
    return lambda data, _folder: yaml.safe_dump(data, sort_keys=False) + text


def goal_quat(quat: list[float]) -> Make:
    """scenarios/planar_ch6_taskspace.yaml with its goal's orientation given as ``quat``."""

    def make(_data: dict, _folder: Path) -> str:
        data = yaml.safe_load((scenarios_dir() / "planar_ch6_taskspace.yaml").read_text())
        data["goal"]["orientation"] = {"quat": quat}
        return yaml.safe_dump(data, sort_keys=False)

    return make


def arm(model: str, target: list[object], position: list[object], **extra: object) -> Make:
    """A short PD + gravity scenario of a URDF arm, in its own joint coordinates."""

    def make(_data: dict, _folder: Path) -> str:
        data = {
            "name": "arm", "robot": {"model": model},
            "simulation": {"duration": 0.01},
            "target": target, "cases": [{"name": "start", "position": position}],
            "controllers": [{"type": "pd_gravity", "kp": 50, "kd": 10}],
        }
        for dotted, value in extra.items():
            node, key = _path(data, dotted.replace("__", "."))
            node[key] = value  # type: ignore[index]
        return yaml.safe_dump(data, sort_keys=False)

    return make


def urdf(joint_type: str = "revolute", inertia: str = 'ixx="0.01" iyy="0.01" izz="0.01"',
         mesh: tuple[str, str] | None = None, mass: float = 1.0) -> Make:
    """robot.model is a one-joint URDF in the folder (with a mesh file ``mesh`` = (name,
    content) on its link, if given)."""

    def make(data: dict, folder: Path) -> str:
        geometry = ""
        if mesh is not None:
            (folder / mesh[0]).write_text(mesh[1])
            geometry = (f'<collision><geometry><mesh filename="{mesh[0]}"/></geometry>'
                        "</collision>")
        (folder / "arm.urdf").write_text(
            f'<robot name="one"><link name="base"/><link name="arm"><inertial>'
            f'<mass value="{mass:g}"/><inertia {inertia} ixy="0" ixz="0" iyz="0"/></inertial>'
            f'{geometry}</link><joint name="j1" type="{joint_type}"><parent link="base"/>'
            '<child link="arm"/><axis xyz="0 0 1"/>'
            '<limit lower="-1" upper="1" effort="5" velocity="2"/></joint></robot>')
        data["robot"].update(model="arm.urdf", coordinates="joint")
        return yaml.safe_dump(data, sort_keys=False)

    return make


NAN, INF = float("nan"), float("inf")

VARIANTS: list[BadInput] = [
    # -- wrong types -----------------------------------------------------------------------
    BadInput("duration_text", "wrong type", "simulation.duration",
             setting("simulation.duration", "long")),
    BadInput("target_text", "wrong type", "target", setting("target", "home")),
    BadInput("target_mapping", "wrong type", "target", setting("target", {"x": 1})),
    BadInput("cases_mapping", "wrong type", "cases", setting("cases", {"rest": [0, 0]})),
    BadInput("gain_text_entry", "wrong type", "controllers[1].kp",
             setting("controllers.1.kp", [4, "four"])),
    BadInput("gain_boolean", "wrong type", "controllers[1].kd",
             setting("controllers.1.kd", True)),
    BadInput("safeguard_text", "wrong type", "simulation.safeguard",
             setting("simulation.safeguard", "maybe")),
    BadInput("safeguard_number", "wrong type", "simulation.safeguard",
             setting("simulation.safeguard", 1)),
    BadInput("velocity_cushion_one", "out of range", "simulation.safeguard_velocity_cushion",
             setting("simulation.safeguard_velocity_cushion", 1.0)),
    BadInput("log_every_fraction", "wrong type", "simulation.log_every",
             setting("simulation.log_every", 1.5)),
    BadInput("noise_seed_fraction", "wrong type", "simulation.noise.seed",
             setting("simulation.noise.seed", 1.5)),
    BadInput("coordinates_number", "wrong type", "robot.coordinates",
             setting("robot.coordinates", 5)),
    BadInput("bounds_boolean", "wrong type", "constraints[2].bounds",
             setting("constraints.2.bounds", True)),
    BadInput("radius_list", "wrong type", "constraints[0].radius",
             setting("constraints.0.radius", [0.5])),
    BadInput("plant_list", "wrong type", "robot.plant", setting("robot.plant", [1.1, 0.9])),
    BadInput("name_number", "wrong type", "name", setting("name", 7)),
    BadInput("top_level_list", "wrong type", "mapping", raw("- name: x\n- duration: 1\n")),
    BadInput("empty_file", "wrong type", "mapping", raw("")),
    BadInput("not_yaml", "wrong type", "YAML", raw("name: [unclosed\n  target: {")),
    # -- wrong shapes ----------------------------------------------------------------------
    BadInput("target_three", "wrong shape", "target", setting("target", [1, 2, 3])),
    BadInput("target_one", "wrong shape", "target", setting("target", [1])),
    BadInput("position_one", "wrong shape", "cases[0].position",
             setting("cases.0.position", [0])),
    BadInput("velocity_three", "wrong shape", "cases[0].velocity",
             setting("cases.0.velocity", [0, 0, 0])),
    BadInput("bounds_three", "wrong shape", "constraints[2].bounds",
             setting("constraints.2.bounds", [0.3, 0.2, 0.1])),
    BadInput("gain_three", "wrong shape", "controllers[1]",
             setting("controllers.1.kp", [1, 2, 3])),
    BadInput("xi_three", "wrong shape", "controllers[2]",
             setting("controllers.2.xi", [1, 1, 1])),
    BadInput("torque_limit_three", "wrong shape", "simulation.torque_limit",
             setting("simulation.torque_limit", [1, 2, 3])),
    BadInput("coordinates_ragged", "wrong shape", "robot.coordinates",
             setting("robot.coordinates", [[1, 0], [1]])),
    BadInput("coordinates_singular", "wrong shape", "robot.coordinates",
             setting("robot.coordinates", [[1, 1], [1, 1]])),
    BadInput("coefficients_short", "wrong shape", "constraints[1].coefficients",
             setting("constraints.1.coefficients", [[-1]])),
    BadInput("centre_four", "wrong shape", "constraints[0].centre",
             setting("constraints.0.centre", [0, 2, 0, 1])),
    BadInput("mass_scale_three", "wrong shape", "robot.plant.mass_scale",
             setting("robot.plant.mass_scale", [1, 1, 1])),
    BadInput("damping_three", "wrong shape", "robot.plant.damping",
             setting("robot.plant.damping", [0, 0, 0])),
    BadInput("noise_three", "wrong shape", "simulation.noise.position",
             setting("simulation.noise.position", [0.1, 0.1, 0.1])),
    BadInput("viscous_friction_three", "wrong shape", "robot.viscous_friction",
             setting("robot.viscous_friction", [0.1, 0.1, 0.1])),
    # -- unknown keys ----------------------------------------------------------------------
    BadInput("top_level_key", "unknown key", "colour", setting("colour", "red")),
    BadInput("simulation_key", "unknown key", "simulation.dt", setting("simulation.dt", 0.1)),
    BadInput("controller_key", "unknown key", "gain", setting("controllers.1.gain", 3)),
    BadInput("constraint_key", "unknown key", "margin", setting("constraints.2.margin", 1)),
    BadInput("plant_key", "unknown key", "robot.plant.mass", setting("robot.plant.mass", 2)),
    BadInput("noise_key", "unknown key", "simulation.noise.sigma",
             setting("simulation.noise.sigma", 0.1)),
    BadInput("controller_type", "unknown key", "controllers[1]",
             setting("controllers.1.type", "lqr")),
    BadInput("constraint_type", "unknown key", "constraints[2]",
             setting("constraints.2.type", "joint_speed_limit")),
    BadInput("integrator", "unknown key", "simulation.integrator",
             setting("simulation.integrator", "Verlet")),
    BadInput("shaping_type", "unknown key", "shaping",
             setting("controllers.1.shaping", {"type": "cubic"})),
    BadInput("unknown_constraint_name", "unknown key", "controllers[1].constraints",
             setting("controllers.1.constraints", ["obstacle", "wall"])),
    BadInput("unknown_frame", "unknown key", "constraints[0]",
             setting("constraints.0.frame", "gripper")),
    BadInput("unknown_joint", "unknown key", "constraints[2].joints",
             setting("constraints.2.joints", ["theta1", "theta9"])),
    # -- zero or negative gains and bounds -------------------------------------------------
    BadInput("kp_zero", "non-positive", "controllers[1].kp", setting("controllers.1.kp", 0)),
    BadInput("kd_negative", "non-positive", "controllers[1].kd",
             setting("controllers.1.kd", -20)),
    BadInput("kp_entry_negative", "non-positive", "controllers[2].kp",
             setting("controllers.2.kp", [2, -10])),
    BadInput("xi_zero", "non-positive", "controllers[2].xi", setting("controllers.2.xi", 0)),
    BadInput("gamma_negative", "non-positive", "controllers[2].gamma",
             setting("controllers.2.gamma", -1)),
    BadInput("alpha_zero", "non-positive", "alpha",
             setting("controllers.1.shaping", {"type": "power", "alpha": 0})),
    BadInput("sigma_negative", "non-positive", "sigma",
             setting("controllers.1.shaping", {"type": "tanh", "sigma": -1})),
    BadInput("rate_bound_zero", "non-positive", "constraints[2].bounds",
             setting("constraints.2.bounds", [0.3, 0])),
    BadInput("energy_zero", "non-positive", "constraints[3].limit",
             setting("constraints.3.limit", 0)),
    BadInput("radius_negative", "non-positive", "constraints[0].radius",
             setting("constraints.0.radius", -0.5)),
    BadInput("limits_reversed", "non-positive", "constraints[1]",
             setting("constraints.1.lower", [3])),
    BadInput("duration_zero", "non-positive", "simulation.duration",
             setting("simulation.duration", 0)),
    BadInput("duration_negative", "non-positive", "simulation.duration",
             setting("simulation.duration", -1)),
    BadInput("timestep_zero", "non-positive", "simulation.timestep",
             setting("simulation.timestep", 0)),
    BadInput("period_negative", "non-positive", "simulation.control_period",
             setting("simulation.control_period", -0.002)),
    BadInput("period_not_multiple", "non-positive", "simulation.control_period",
             setting("simulation.control_period", 0.0015)),
    BadInput("torque_limit_zero", "non-positive", "simulation.torque_limit",
             setting("simulation.torque_limit", 0)),
    BadInput("log_every_zero", "non-positive", "simulation.log_every",
             setting("simulation.log_every", 0)),
    BadInput("max_log_samples_one", "non-positive", "simulation.max_log_samples",
             setting("simulation.max_log_samples", 1)),
    BadInput("noise_negative", "non-positive", "simulation.noise.velocity",
             setting("simulation.noise.velocity", -0.1)),
    BadInput("noise_seed_negative", "non-positive", "simulation.noise.seed",
             setting("simulation.noise.seed", -3)),
    BadInput("mass_scale_zero", "non-positive", "robot.plant.mass_scale",
             setting("robot.plant.mass_scale", 0)),
    BadInput("armature_negative", "non-positive", "robot.plant.armature",
             setting("robot.plant.armature", -0.1)),
    BadInput("friction_negative", "non-positive", "robot.viscous_friction",
             setting("robot.viscous_friction", -1)),
    BadInput("rotor_armature_negative", "non-positive", "robot.armature",
             setting("robot.armature", -0.1)),
    BadInput("coulomb_negative", "non-positive", "robot.friction.coulomb",
             setting("robot.friction", {"coulomb": -0.5})),
    BadInput("coulomb_three", "wrong shape", "robot.friction.coulomb",
             setting("robot.friction", {"coulomb": [0.1, 0.1, 0.1]})),
    BadInput("rotor_armature_three", "wrong shape", "robot.armature",
             setting("robot.armature", [0.1, 0.1, 0.1])),
    BadInput("viscous_friction_twice", "structure", "robot.viscous_friction",
             lambda d, f: setting("robot.friction", {"viscous": 0.1})(
                 {**d, "robot": {**d["robot"], "viscous_friction": 0.2}}, f)),
    BadInput("compensation_in_link_angles", "structure", "robot.friction.compensate",
             setting("robot.friction", {"coulomb": 0.2})),
    BadInput("tolerance_zero", "non-positive", "simulation.position_tolerance",
             setting("simulation.position_tolerance", 0)),
    # -- NaN, infinity, bad expressions ----------------------------------------------------
    BadInput("target_nan", "non-finite", "target", setting("target", [NAN, 0])),
    BadInput("position_nan", "non-finite", "cases[0].position",
             setting("cases.0.position", [0, NAN])),
    BadInput("velocity_inf", "non-finite", "cases[0].velocity",
             setting("cases.0.velocity", [INF, 0])),
    BadInput("kp_inf", "non-finite", "controllers[1].kp", setting("controllers.1.kp", INF)),
    BadInput("duration_nan", "non-finite", "simulation.duration",
             setting("simulation.duration", NAN)),
    BadInput("bound_text_inf", "non-finite", "constraints[2].bounds",
             setting("constraints.2.bounds", ["inf", 0.2])),
    BadInput("radius_nan", "non-finite", "constraints[0].radius",
             setting("constraints.0.radius", NAN)),
    BadInput("mass_scale_inf", "non-finite", "robot.plant.mass_scale",
             setting("robot.plant.mass_scale", INF)),
    BadInput("noise_nan", "non-finite", "simulation.noise.position",
             setting("simulation.noise.position", NAN)),
    BadInput("division_by_zero", "non-finite", "target", setting("target", ["pi/0", 0])),
    BadInput("overflow", "non-finite", "target", setting("target", ["10**400", 0])),
    BadInput("code_injection", "non-finite", "target",
             setting("target", ["__import__('os').getcwd()", 0])),
    # -- a target or initial state outside S -----------------------------------------------
    BadInput("target_in_obstacle", "inadmissible", "target",
             setting("target", ["pi/2", "pi/2"])),
    BadInput("target_past_relative_limit", "inadmissible", "target",
             setting("target", [0, 3.0])),
    BadInput("start_in_obstacle", "inadmissible", "cases[0]",
             setting("cases.0.position", ["pi/2", "pi/2"])),
    BadInput("start_too_fast", "inadmissible", "cases[0]",
             setting("cases.0.velocity", [0.5, 0])),
    BadInput("start_on_rate_bound", "inadmissible", "cases[0]",
             setting("cases.0.velocity", [0.3, 0])),
    BadInput("start_over_energy", "inadmissible", "cases[0]",
             setting("constraints.3.limit", 0.001)),
    # -- the model file --------------------------------------------------------------------
    BadInput("model_missing", "model file", "robot.model", model_file(None, "missing.xml")),
    BadInput("model_not_xml", "model file", "robot.model", model_file("this is not XML")),
    BadInput("model_bad_mjcf", "model file", "robot.model",
             model_file("<mujoco><worldbody><body><joint type='ball'/></body></worldbody>"
                        "</mujoco>")),
    BadInput("model_empty", "model file", "robot.model", model_file("")),
    BadInput("model_directory", "model file", "robot.model", setting("robot.model", ".")),
    # -- structure -------------------------------------------------------------------------
    BadInput("no_cases", "structure", "cases", setting("cases", [])),
    BadInput("no_controllers", "structure", "controllers", setting("controllers", [])),
    BadInput("missing_duration", "structure", "simulation.duration",
             removing("simulation.duration")),
    BadInput("missing_target", "structure", "target", removing("target")),
    BadInput("duplicate_case", "structure", "cases",
             setting("cases", [{"name": "a", "position": [0, 0]},
                               {"name": "a", "position": [0.1, 0]}])),
    BadInput("duplicate_controller", "structure", "controllers",
             setting("controllers.1.name", "PD")),
    BadInput("duplicate_constraint", "structure", "constraints[3].name",
             setting("constraints.3.name", "obstacle")),
    BadInput("name_escapes", "structure", "name", setting("name", "../elsewhere")),
    BadInput("case_name_escapes", "structure", "cases[0].name",
             setting("cases.0.name", "../../x")),
    BadInput("bpbc_with_obstacle", "structure", "controllers[2]",
             setting("controllers.2.constraints", ["obstacle", "link_rates"])),
    BadInput("ke_law_without_energy", "structure", "controllers[3]",
             setting("controllers.3.constraints", ["link_rates"])),
    # -- the file itself ----------------------------------------------------------------------
    BadInput("not_utf8", "file", "UTF-8", raw_bytes("name: caf\xe9\n".encode("latin-1"))),
    BadInput("utf16", "file", "UTF-8",
             lambda data, _f: yaml.safe_dump(data, sort_keys=False).encode("utf-16")),
    BadInput("yaml_directory", "file", "directory", directory),
    BadInput("duplicate_target", "duplicate key", "target",
             with_yaml("target: [0.5, 0.5]\n")),
    BadInput("duplicate_nested_key", "duplicate key", "simulation.timestep",
             raw("name: d\nsimulation:\n  duration: 1\n  timestep: 0.001\n  timestep: 0.01\n"
                 "target: [1, 1]\ncases: [{name: a, position: [0, 0]}]\n"
                 "controllers: [{type: pd, kp: 1, kd: 1}]\n")),
    BadInput("duplicate_in_list_item", "duplicate key", "cases[0].position",
             raw("name: d\nsimulation: {duration: 1}\ntarget: [1, 1]\n"
                 "cases:\n  - name: a\n    position: [0, 0]\n    position: [1, 0]\n"
                 "controllers: [{type: pd, kp: 1, kd: 1}]\n")),
    # -- run length ------------------------------------------------------------------------
    BadInput("timestep_longer_than_duration", "length", "simulation.duration",
             setting("simulation.duration", 0.001)),
    BadInput("period_longer_than_duration", "length", "simulation.control_period",
             setting("simulation.control_period", 0.04)),
    BadInput("ten_billion_steps", "length", "simulation.max_steps",
             setting("simulation.duration", 1e7)),
    BadInput("max_steps_zero", "non-positive", "simulation.max_steps",
             setting("simulation.max_steps", 0)),
    BadInput("max_steps_fraction", "wrong type", "simulation.max_steps",
             setting("simulation.max_steps", 2.5)),
    # -- gains -----------------------------------------------------------------------------
    BadInput("kd_unstable_at_period", "gains", "controllers[0]",
             setting("controllers.0.kd", 5000)),
    BadInput("kp_unstable_at_period", "gains", "controllers[0]",
             setting("controllers.0.kp", 50000)),
    BadInput("omega_unstable_at_period", "gains", "controllers[0]",
             setting("controllers.0", {"type": "pd", "omega_n": 2000, "zeta": 0.7})),
    BadInput("kp_and_omega", "gains", "controllers[0]",
             setting("controllers.0.omega_n", 2)),
    BadInput("omega_without_zeta", "gains", "controllers[0]",
             setting("controllers.0", {"type": "pd", "omega_n": 2})),
    BadInput("no_gains", "gains", "controllers[0]", setting("controllers.0", {"type": "pd"})),
    BadInput("zeta_negative", "non-positive", "controllers[0].zeta",
             setting("controllers.0", {"type": "pd", "omega_n": 2, "zeta": -1})),
    BadInput("omega_three", "wrong shape", "controllers[0].omega_n",
             setting("controllers.0", {"type": "pd", "omega_n": [1, 2, 3], "zeta": 1})),
    BadInput("check_gains_text", "wrong type", "simulation.check_gains",
             setting("simulation.check_gains", "no")),
    # -- URDF models MuJoCo refuses though Pinocchio reads them ----------------------------
    BadInput("urdf_unphysical_inertia", "model file", "robot.model",
             urdf(inertia='ixx="0.01" iyy="0.01" izz="0.5"')),
    BadInput("urdf_unreadable_collada", "model file", "robot.model",
             urdf(mesh=("arm.dae", "<COLLADA>half a file"))),
    BadInput("urdf_floating_joint", "model file", "robot.model", urdf("floating")),
    BadInput("urdf_massless", "model file", "robot.model",
             urdf(inertia='ixx="0" iyy="0" izz="0"', mass=0.0)),
    BadInput("mjcf_without_joints", "model file", "robot.model",
             model_file("<mujoco><worldbody><body name='b'><geom type='sphere' size='0.1'/>"
                        "</body></worldbody></mujoco>")),
    BadInput("mjcf_arm_after_a_mocap_body", "model file", "robot.model",
             model_file("<mujoco><worldbody><body mocap='true' name='handle'><geom "
                        "type='box' size='0.01 0.01 0.01' contype='0' conaffinity='0'/></body>"
                        "<body name='l1'><joint name='j1' type='hinge' axis='0 0 1'/><geom "
                        "type='capsule' size='0.05' fromto='0 0 0 0.3 0 0' mass='1'/></body>"
                        "</worldbody></mujoco>")),
    BadInput("goal_quat_three_numbers", "wrong shape", "goal.orientation.quat",
             goal_quat([1.0, 0.0, 0.0])),
    BadInput("goal_quat_not_unit", "inadmissible", "goal.orientation.quat",
             goal_quat([1.0, 0.0, 0.0, 1.0])),
    BadInput("goal_quat_zero", "inadmissible", "goal.orientation.quat",
             goal_quat([0.0, 0.0, 0.0, 0.0])),
    BadInput("xacro_source", "model file", "robot.model",
             model_file('<robot xmlns:xacro="http://ros.org/wiki/xacro" name="a">'
                        '<xacro:include filename="arm.xacro"/></robot>', "arm.urdf.xacro")),
    # -- URDF arms: joint ranges and joints ------------------------------------------------
    BadInput("target_past_joint_stop", "inadmissible", "target",
             arm("ur5", [0, -1, 4.0, 0, 0, 0], [0, -1, 1, 0, 0, 0])),
    BadInput("start_past_joint_stop", "inadmissible", "cases[0].position",
             arm("ur5", [0, -1, 1, 0, 0, 0], [0, -1, 1, 0, -7, 0])),
    BadInput("kinova_start_below_range", "inadmissible", "cases[0].position",
             arm("kinova", [0, 3, 2, 0, 3, 0], [0, 0, 2, 0, 3, 0])),
    BadInput("locked_joint_unknown", "model file", "robot.locked_joints",
             arm("ur5", [0] * 5, [0] * 5, robot__locked_joints={"wrist_9_joint": 0.0})),
    BadInput("locked_joint_out_of_range", "model file", "robot.locked_joints",
             arm("panda", [0, 0, 0, -1.5, 0, 1.5, 0], [0, 0, 0, -1.5, 0, 1.5, 0],
                 robot__locked_joints={"panda_finger_joint1": 0.5})),
    # -- Part I systems (a system: block) ---------------------------------------------------
    BadInput("system_unknown_type", "unknown key", "system", system("system.type", "car")),
    BadInput("system_mistyped_key", "unknown key", "system.travel_limt",
             system("system.travel_limt", 0.1)),
    BadInput("system_with_target", "unknown key", "target", system("target", [0, 0])),
    BadInput("system_with_safeguard", "unknown key", "simulation.safeguard",
             system("simulation.safeguard", True)),
    BadInput("system_gain_negative", "non-positive", "system.laws[0].gains.k2",
             system("system.laws.0.gains.k2", -0.05)),
    BadInput("system_gain_text", "wrong type", "system.laws[0].gains.k1",
             system("system.laws.0.gains.k1", "fast")),
    BadInput("system_gain_unknown", "unknown key", "system.laws[0].gains.k9",
             system("system.laws.0.gains.k9", 1)),
    BadInput("system_barrier_text", "wrong type", "system.laws[1].barrier",
             system("system.laws.1.barrier", "no")),
    BadInput("system_bound_above_limit", "gains", "system.laws[0].gains",
             system("system.travel_limit", 0.05)),
    BadInput("system_no_laws", "structure", "system.laws", system("system.laws", [])),
    BadInput("system_law_names_repeat", "structure", "system.laws",
             system("system.laws.1.name", "barrier")),
    BadInput("system_travel_nan", "non-finite", "system.travel_limit",
             system("system.travel_limit", NAN)),
    BadInput("system_bump_missing", "structure", "cases[0].bump_height",
             system("cases.0.bump_height", REMOVE)),
    BadInput("system_bump_negative", "non-positive", "cases[0].bump_height",
             system("cases.0.bump_height", -0.1)),
    BadInput("system_state_three", "wrong shape", "cases[0].state",
             system("cases.0.state", [0, 0, 0])),
    BadInput("system_literal_fig3_7", "inadmissible", "cases[0].state",
             system("cases.0.state", [0, -20, -0.05, 0])),
    BadInput("system_travel_past_limit", "inadmissible", "cases[0].state",
             system("cases.0.state", [0, 0, 0.12, 0])),
    BadInput("system_period_not_multiple", "length", "simulation.control_period",
             system("simulation.control_period", 0.00015)),
    BadInput("system_duration_below_period", "length", "simulation.duration",
             system("simulation.duration", 0.00001)),
    BadInput("system_too_many_steps", "length", "simulation.max_steps",
             system("simulation.duration", 1e7)),
    BadInput("system_tolerance_zero", "non-positive", "simulation.tolerance",
             system("simulation.tolerance", 0)),
    BadInput("rwp_bump", "structure", "cases[0].bump_height",
             system("cases.0.bump_height", 0.1, RWP_BASE)),
    BadInput("rwp_rate_outside_domain", "inadmissible", "cases[0].state",
             system("cases.0.state", [0, 1.5, 0], RWP_BASE)),
    BadInput("rwp_start_outside_domain", "inadmissible", "cases[0].state",
             system("cases.0.state", [0, 0.9, 0], RWP_BASE)),
    BadInput("rwp_gain_zero", "non-positive", "system.laws[0].gains.k4",
             system("system.laws.0.gains", {"k4": 0}, RWP_BASE)),
    BadInput("rwp_torque_limit_text", "wrong type", "system.torque_limit",
             system("system.torque_limit", "0.4 N m", RWP_BASE)),
    BadInput("rwp_torque_limit_below_bound", "inadmissible", "system.laws[0].gains",
             system("system.torque_limit", 0.3, RWP_BASE)),
    BadInput("chain_on_mujoco", "structure", "simulation.backend",
             system("simulation.backend", "mujoco", CHAIN_BASE)),
    BadInput("chain_limits_two", "wrong shape", "system.limits",
             system("system.limits", [2.5, 12], CHAIN_BASE)),
    BadInput("chain_gain_negative", "non-positive", "system.laws[0].gains.c3",
             system("system.laws.0.gains", {"c3": -50}, CHAIN_BASE)),
    BadInput("chain_bound_above_limit", "gains", "system.laws[0].gains",
             system("system.limits", [2.5, 7, 700], CHAIN_BASE)),
    BadInput("chain_start_outside_domain", "inadmissible", "cases[0].state",
             system("cases.0.state", [0, 0, 0, 400], CHAIN_BASE)),
    BadInput("chain_start_past_limit", "inadmissible", "cases[0].state",
             system("cases.0.state", [0, 3, 0, 0], CHAIN_BASE)),
    BadInput("chain_bump", "structure", "cases[0].bump_height",
             system("cases.0.bump_height", 0.1, CHAIN_BASE)),
    BadInput("aerosonde_state_full", "wrong shape", "cases[0].state",
             system("cases.0.state", [100, 0, 0.09, 0], AEROSONDE_BASE)),
    BadInput("aerosonde_climb_past_limit", "inadmissible", "cases[0].state",
             system("cases.0.state", [100, 4.0], AEROSONDE_BASE)),
    BadInput("aerosonde_bound_above_limit", "gains", "system.laws[1].gains",
             system("system.climb_rate_limit", 3.0, AEROSONDE_BASE)),
    BadInput("aerosonde_k2_below_c1", "gains", "system.laws[1].gains.k2",
             system("system.laws.1.gains", {"k2": 1.0}, AEROSONDE_BASE)),
    BadInput("aerosonde_k_on_traditional", "unknown key", "system.laws[0].gains.k3",
             system("system.laws.0.gains", {"k3": 0.5}, AEROSONDE_BASE)),
    BadInput("aerosonde_mujoco", "structure", "simulation.backend",
             system("simulation.backend", "mujoco", AEROSONDE_BASE)),
    BadInput("aerosonde_density_zero", "non-positive", "system.air_density",
             system("system.air_density", 0, AEROSONDE_BASE)),
    BadInput("aerosonde_command_text", "wrong type", "cases[0].commands[0].altitude",
             system("cases.0.commands.0.altitude", "high", AEROSONDE_BASE)),
    BadInput("aerosonde_command_after_end", "length", "cases[0].commands[0].time",
             system("cases.0.commands.0.time", 5, AEROSONDE_BASE)),
    BadInput("aerosonde_commands_out_of_order", "structure", "cases[0].commands[1].time",
             system("cases.0.commands", [{"time": 0.15, "altitude": 150},
                                         {"time": 0.1, "altitude": 130}], AEROSONDE_BASE)),
    BadInput("aerosonde_start_inadmissible", "inadmissible", "cases[0].commands[0]",
             system("cases.0", {"name": "climb", "state": [100, 3.0],
                                "commands": [{"time": 0, "altitude": 0}]}, AEROSONDE_BASE)),
    BadInput("aerosonde_bump", "structure", "cases[0].bump_height",
             system("cases.0.bump_height", 0.1, AEROSONDE_BASE)),
    BadInput("commands_on_quarter_car", "structure", "cases[0].commands",
             system("cases.0.commands", [{"time": 0.001, "altitude": 1}])),
]


@dataclass(frozen=True)
class Answer:
    """How the CLI answered one variant."""

    variant: BadInput
    exit_code: int | None
    message: str
    names_field: bool
    traceback: bool
    left_behind: list[str]

    @property
    def ok(self) -> bool:
        return (self.exit_code == 2 and self.names_field and not self.traceback
                and not self.left_behind)


def answer(variant: BadInput, folder: Path) -> Answer:
    """Write the variant into an empty ``folder``, run the CLI on it, and judge the answer."""
    folder.mkdir(parents=True, exist_ok=True)
    text = variant.make(copy.deepcopy(BASE), folder)
    scenario = folder / "scenario.yaml"
    if isinstance(text, bytes):
        scenario.write_bytes(text)
    elif text is not None:
        scenario.write_text(text, encoding="utf-8")
    before = {p.name for p in folder.iterdir()}
    out = folder / "out"
    err, std = io.StringIO(), io.StringIO()
    code: int | None
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
        try:
            code = main([str(scenario), "--out", str(out), "--quiet"])
        except SystemExit as exc:  # argparse
            code = int(exc.code) if isinstance(exc.code, int) else None
        except BaseException:  # a crash: the finding this check exists for
            code = None
            traceback.print_exc(file=err)
    message = err.getvalue().strip()
    left = sorted({p.name for p in folder.iterdir()} - before)
    return Answer(
        variant, code, message, variant.field in message,
        "Traceback" in message or "Traceback" in std.getvalue(), left,
    )


def answer_all(folder: Path, variants: list[BadInput] | None = None) -> list[Answer]:
    """Every variant in its own sub-folder of ``folder``."""
    return [answer(v, folder / v.name) for v in (variants or VARIANTS)]
