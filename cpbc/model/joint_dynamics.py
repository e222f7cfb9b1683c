"""What each driven joint adds to its links' rigid-body dynamics: the motor's rotor inertia
(armature) and the joint's viscous and Coulomb friction, one value for the controller's
model (D and f of eq. 6.1) and the MuJoCo plant (``dof_armature``, ``dof_damping``,
``dof_frictionloss``).

What a model file declares: an MJCF joint's ``armature``, ``damping`` and ``frictionloss``
(Pinocchio's MJCF parser reads all three into ``armature``, ``damping`` and ``friction``);
a URDF joint's ``<dynamics damping=… friction=…/>`` (Pinocchio's URDF parser reads the two)
and — URDF has no tag for it, and neither engine's parser reads one — a ``armature=…``
attribute of the same ``<dynamics>`` element, which cpbc reads itself.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.errors import ModelError


def _levels(value: object, n: int, field: str) -> Array:
    """One finite value ≥ 0 per joint (a number is every joint's), read-only."""
    a = np.array(value, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ModelError(f"{field} must be one finite number ≥ 0 or {n} of them (one per "
                         f"joint), got {np.asarray(value).tolist()}", field)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class JointDynamics:
    """Per driven joint, in the model's joint order and joint coordinates.

    Attributes:
        armature: rotor inertia reflected to the joint [kg·m² or kg], added to D's diagonal.
        viscous: viscous friction F_d [N·m·s/rad or N·s/m].
        coulomb: Coulomb (dry) friction level F_c [N·m or N].
    """

    armature: Array
    viscous: Array
    coulomb: Array

    def __post_init__(self) -> None:
        n = np.asarray(self.armature).size
        for name in ("armature", "viscous", "coulomb"):
            object.__setattr__(self, name, _levels(getattr(self, name), n, name))

    @classmethod
    def none(cls, n: int) -> JointDynamics:
        """No rotor inertia and no friction."""
        return cls(np.zeros(n), np.zeros(n), np.zeros(n))

    @classmethod
    def declared(cls, model: pin.Model, urdf_text: str | None = None) -> JointDynamics:
        """What the model file declares: Pinocchio's ``armature``, ``damping`` and
        ``friction`` of ``model`` (read from its MJCF or URDF), and for a URDF
        (``urdf_text``) each driven joint's ``<dynamics armature=…>``."""
        armature = np.array(model.armature, dtype=float)
        if urdf_text is not None:
            armature = armature + _urdf_armature(urdf_text, tuple(model.names[1:]))
        return cls(armature, np.array(model.damping, dtype=float),
                   np.array(model.friction, dtype=float))

    @property
    def n(self) -> int:
        return int(self.armature.size)

    @property
    def any(self) -> bool:
        """Whether the joints add anything."""
        return bool(np.any(self.armature) or np.any(self.viscous) or np.any(self.coulomb))

    def on_pinocchio(self, model: pin.Model) -> pin.Model:
        """A copy of ``model`` whose CRBA, RNEA and ABA include the armature (Pinocchio 3+
        adds ``model.armature`` to D's diagonal); the friction is the RobotModel's f, not
        Pinocchio's (its algorithms ignore ``damping`` and ``friction``)."""
        if model.nv != self.n:
            raise ModelError(f"joint dynamics of {self.n} joints for a model of {model.nv}")
        out = pin.Model(model)
        out.armature[:] = self.armature
        return out

    def on_mujoco(self, plant: mujoco.MjModel) -> None:
        """The plant's joints get the same rotor inertia, viscous and dry friction (in place,
        replacing what its file declared)."""
        if plant.nv != self.n:
            raise ModelError(f"joint dynamics of {self.n} joints for a plant of {plant.nv}")
        plant.dof_armature[:] = self.armature
        plant.dof_damping[:] = self.viscous
        plant.dof_frictionloss[:] = self.coulomb
        # the constants MuJoCo derives from the inertia at compile time, dof_invweight0 among
        # them: it sets how soon a joint's frictionloss builds up (its constraint's
        # regulariser). Left at the compiled value, the xArm7's last joint (0.01 kg·m² of
        # armature added to a link of 1.4e-4) slid at 1.5 rad/s under 0.26 of its 2 N·m.
        mujoco.mj_setConst(plant, mujoco.MjData(plant))

    def summary(self) -> dict[str, list[float]]:
        """The values as a summary reports them: ``armature``, ``coulomb``, ``viscous``."""
        return {"armature": self.armature.tolist(), "coulomb": self.coulomb.tolist(),
                "viscous": self.viscous.tolist()}


def _urdf_armature(urdf_text: str, joints: Sequence[str]) -> Array:
    """Each joint's ``<dynamics armature=…>`` in the URDF text, 0 where none."""
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as exc:  # both engines read it already: not expected
        raise ModelError(f"the URDF text is not XML: {exc}") from None
    found = np.zeros(len(joints))
    index = {name: i for i, name in enumerate(joints)}
    for joint in root.iter("joint"):
        i = index.get(joint.get("name", ""))
        dynamics = joint.find("dynamics")
        if i is None or dynamics is None or dynamics.get("armature") is None:
            continue
        try:
            found[i] = float(dynamics.get("armature", "0"))
        except ValueError:
            raise ModelError(f"joint '{joint.get('name')}': <dynamics armature=…> is not a "
                             "number", "armature") from None
    return found
