"""A scenario's joint dynamics: ``robot.armature`` and ``robot.friction`` (with the older
``robot.viscous_friction``) resolved against the model file into one JointDynamics, which
the controller's model and the MuJoCo plant both take (cpbc.scenario.arm_setup)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from cpbc.errors import ModelError, ScenarioError
from cpbc.model.joint_dynamics import JointDynamics
from cpbc.scenario import schema as s


def _given(value: float | list[float], declared: np.ndarray, field: str) -> np.ndarray:
    """A number or one per joint, checked against the number of joints."""
    n = declared.size
    if isinstance(value, list) and len(value) != n:
        raise ScenarioError(field, f"needs 1 or {n} entries (one per joint), got {len(value)}")
    return np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()


def _pick(value: object, declared: np.ndarray, field: str) -> np.ndarray:
    """``from_model``: the declared values; ``none``: zero; else the given ones."""
    if value == "from_model":
        return declared
    if value == "none":
        return np.zeros(declared.size)
    return _given(value, declared, field)  # type: ignore[arg-type]


def joint_dynamics(robot: s.RobotSpec, model: pin.Model, urdf_text: str | None
                   ) -> JointDynamics:
    """The joints' rotor inertia and friction a scenario asks for; ``model`` is Pinocchio's
    model of the file as read (its ``armature``, ``damping``, ``friction``), ``urdf_text``
    the URDF text for a URDF arm (its ``<dynamics armature>``), else None."""
    try:
        declared = JointDynamics.declared(model, urdf_text)
    except ModelError as exc:
        raise ScenarioError("robot.armature", str(exc)) from None
    friction = robot.friction
    if friction == "none":
        friction = s.FrictionSpec(viscous=robot.viscous_friction)
    elif robot.viscous_friction != 0.0:
        raise ScenarioError("robot.viscous_friction", "give viscous friction once: with "
                            "robot.friction, as robot.friction.viscous (viscous_friction is "
                            "its older name)")
    elif friction == "from_model":
        friction = s.FrictionSpec(coulomb="from_model", viscous="from_model")
    assert isinstance(friction, s.FrictionSpec)
    field = ("robot.viscous_friction" if robot.friction == "none" else "robot.friction.viscous")
    return JointDynamics(
        _pick(robot.armature, declared.armature, "robot.armature"),
        _pick(friction.viscous, declared.viscous, field),
        _pick(friction.coulomb, declared.coulomb, "robot.friction.coulomb"))


def friction_spec(robot: s.RobotSpec) -> s.FrictionSpec:
    """``robot.friction`` as a spec (``from_model`` and ``none`` with the defaults of the
    smoothing and the compensation)."""
    return robot.friction if isinstance(robot.friction, s.FrictionSpec) else s.FrictionSpec()
