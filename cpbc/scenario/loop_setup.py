"""The sampled-data loop of an arm scenario: its length, torque limits and measurement
noise."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.safeguard.model_error import DeclaredError
from cpbc.errors import CpbcError, ScenarioError
from cpbc.model import RobotModel
from cpbc.model.input_bounds import InputBounds
from cpbc.scenario import schema as s
from cpbc.scenario.arm_setup import ScenarioSetup
from cpbc.simulation import LoopSettings, substeps_per_control
from cpbc.simulation.disturbances import MeasurementNoise
from cpbc.spec.values import model_limits, vector


def _check_length(sim: s.SimulationSpec, control_period: float) -> None:
    """At least one control period, and no more physics steps than ``max_steps``."""
    period_key = "control_period" if sim.control_period else "timestep"
    if sim.duration < control_period * (1 - 1e-9):
        raise ScenarioError(
            "simulation.duration",
            f"{sim.duration:g} s is shorter than one control period (simulation.{period_key} "
            f"= {control_period:g} s): lengthen the duration or shorten the period",
        )
    try:
        substeps_per_control(control_period, sim.timestep)
    except CpbcError as exc:
        raise ScenarioError("simulation.control_period", str(exc)) from None
    steps = sim.duration / sim.timestep
    if steps > sim.max_steps:
        raise ScenarioError(
            "simulation.duration",
            f"{sim.duration:g} s at a timestep of {sim.timestep:g} s is {steps:.3g} physics "
            f"steps per run, more than simulation.max_steps = {sim.max_steps:,}: shorten the "
            "duration, lengthen the timestep, or raise simulation.max_steps if you mean it",
        )


def _declared_efforts(model: RobotModel) -> Array | None:
    """The effort limits the model declares (a URDF arm), in joint coordinates, inf for a joint
    that declares none; None when no joint declares one (the built-in MJCF arm)."""
    effort = np.array(model.model.effortLimit, dtype=float)
    declared = np.isfinite(effort) & (effort > 0)
    if not model.coordinates.is_identity or effort.size != model.n or not np.any(declared):
        return None
    return np.where(declared, effort, np.inf)


def undeclared_efforts(setup: ScenarioSetup) -> tuple[str, ...]:
    """The joints that run without a torque limit beside joints that have one (the model
    declares effort limits for some joints only; ``simulation.torque_limit: auto``)."""
    limit = setup.loop_settings.bounds.torque
    if limit is None:
        return ()
    return tuple(n for n, v in zip(setup.model.joint_names, limit, strict=True)
                 if not np.isfinite(v))


def _rate_limit(sim: s.SimulationSpec, model: RobotModel) -> Array | None:
    """The joint torque-rate limits [N·m/s] the scenario asks for, or None."""
    rate = sim.torque_rate_limit
    if rate is None or rate == "none":
        return None
    field = "simulation.torque_rate_limit"
    if rate == "from_model":
        if model.torque_rate_limits is None:
            raise ScenarioError(field, f"the model '{model.name}' declares no torque-rate "
                                "limit: give one number or one per joint [N·m/s]")
        return model.torque_rate_limits.copy()
    if not model.coordinates.is_identity and isinstance(rate, list):
        raise ScenarioError(field, "per-joint rate limits are in joint coordinates: give one "
                            "number, or use robot.coordinates: joint")
    values = rate if isinstance(rate, list) else [rate] * model.n
    return vector(values, model.n, field)


def loop_settings(sim: s.SimulationSpec, model: RobotModel) -> LoopSettings:
    n = model.n
    control_period = sim.period
    _check_length(sim, control_period)
    limit = None
    if sim.torque_limit == "from_model":
        limit = sim.torque_limit_scale * model_limits(
            model, "effort", "simulation.torque_limit")[1]
    elif sim.torque_limit == "auto":  # real arms have real motors
        limit = _declared_efforts(model)
        limit = None if limit is None else sim.torque_limit_scale * limit
    elif isinstance(sim.torque_limit, (float, list)):
        limit = sim.torque_limit_scale * vector(
            sim.torque_limit if isinstance(sim.torque_limit, list) else [sim.torque_limit] * n,
            n,
            "simulation.torque_limit",
        )
    noise = None
    if sim.noise is not None:
        noise = MeasurementNoise(
            tuple(sim.noise.position) if isinstance(sim.noise.position, list)
            else sim.noise.position,
            tuple(sim.noise.velocity) if isinstance(sim.noise.velocity, list)
            else sim.noise.velocity,
            sim.noise.seed,
        )
    bounds = InputBounds(control_period, limit, _rate_limit(sim, model))  # built once here
    return LoopSettings(
        sim.duration, bounds, sim.log_every,
        noise=noise,
        max_log_samples=sim.max_log_samples,
        model_error=_model_error(sim, model),
        declared_error=_declared_error(sim, model),
    )


def _model_error(sim: s.SimulationSpec, model: RobotModel) -> Array | None:
    """The declared acceleration error ā in controller coordinates (|T| ā_q: x = T q), or
    None."""
    if sim.model_error is None or sim.model_error.acceleration is None:
        return None
    given = sim.model_error.acceleration
    bound = vector(given if isinstance(given, list) else [given] * model.n, model.n,
                   "simulation.model_error.acceleration")
    coords = model.coordinates
    return bound if coords.is_identity else np.abs(coords.matrix) @ bound


def _declared_error(sim: s.SimulationSpec, model: RobotModel) -> DeclaredError | None:
    """The declared inertia and measurement errors (controller coordinates), or None."""
    spec = sim.model_error
    if spec is None or all(getattr(spec, k) is None for k in s.DECLARED[1:]):
        return None

    def per_coordinate(given: float | list[float] | None, name: str) -> Array | None:
        if given is None:
            return None
        return vector(given if isinstance(given, list) else [given] * model.n, model.n,
                      f"simulation.model_error.{name}")

    return DeclaredError(
        spec.inertia or 0.0, per_coordinate(spec.armature, "armature"),
        per_coordinate(spec.damping, "damping"), per_coordinate(spec.friction, "friction"),
        per_coordinate(spec.position, "position"), per_coordinate(spec.velocity, "velocity"))
