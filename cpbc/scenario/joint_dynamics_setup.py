"""A scenario's joint dynamics: ``robot.armature`` and ``robot.friction`` (with the older
``robot.viscous_friction``) resolved against the model file into one JointDynamics, which
the controller's model and the MuJoCo plant both take (cpbc.scenario.arm_setup).

``auto`` (the default of both) is ``from_model`` for a named arm that declares its joints'
rotor inertia and friction itself (the fr3: cpbc.model.arms), ``none`` otherwise: such an
arm's values are the robot's as its maker's simulator runs it, and a model without them
misses 5–12 % of the FR3's mass matrix and stops its reaches short of the goal."""

from __future__ import annotations

from typing import Literal

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


def joint_dynamics(robot: s.RobotSpec, model: pin.Model, urdf_text: str | None,
                   arm_declares: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                   ) -> JointDynamics:
    """The joints' rotor inertia and friction a scenario asks for; ``model`` is Pinocchio's
    model of the file as read (its ``armature``, ``damping``, ``friction``), ``urdf_text``
    the URDF text for a URDF arm (its ``<dynamics armature>``), else None;
    ``arm_declares``: a named arm's own armature, viscous and Coulomb friction, which
    replace the file's."""
    try:
        declared = (JointDynamics(*arm_declares) if arm_declares is not None
                    else JointDynamics.declared(model, urdf_text))
    except ModelError as exc:
        raise ScenarioError("robot.armature", str(exc)) from None
    auto: Literal["from_model", "none"] = "from_model" if arm_declares is not None else "none"
    armature = auto if robot.armature == "auto" else robot.armature
    friction = robot.friction
    if friction == "auto":
        friction = auto if robot.viscous_friction == 0.0 else "none"
    if friction == "none":
        friction = s.FrictionSpec(viscous=robot.viscous_friction)
    elif robot.viscous_friction != 0.0:
        raise ScenarioError("robot.viscous_friction", "give viscous friction once: with "
                            "robot.friction, as robot.friction.viscous (viscous_friction is "
                            "its older name)")
    elif friction == "from_model":
        friction = s.FrictionSpec(coulomb="from_model", viscous="from_model")
    assert isinstance(friction, s.FrictionSpec)
    field = ("robot.viscous_friction" if robot.friction in ("none", "auto")
             else "robot.friction.viscous")
    return JointDynamics(
        _pick(armature, declared.armature, "robot.armature"),
        _pick(friction.viscous, declared.viscous, field),
        _pick(friction.coulomb, declared.coulomb, "robot.friction.coulomb"))


def friction_spec(robot: s.RobotSpec) -> s.FrictionSpec:
    """``robot.friction`` as a spec (``from_model`` and ``none`` with the defaults of the
    smoothing and the compensation)."""
    return robot.friction if isinstance(robot.friction, s.FrictionSpec) else s.FrictionSpec()
