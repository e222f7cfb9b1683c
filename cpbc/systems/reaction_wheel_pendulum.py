"""The Reaction Wheel Pendulum of §3.5 as a plant: MJCF
``models/systems/reaction_wheel_pendulum.xml`` and ODE (3.137).

    d11 q̈1 + d12 q̈2 − d0 sin q1 = 0,   d21 q̈1 + d22 q̈2 = τ,   |q̇1| ≤ 1 rad/s, |τ| ≤ 0.4 N m

The law's state is x = (q1, q̇1, q̇2) (q2 is cyclic and dropped, as in (3.139)); u = τ [N m].
MuJoCo: hinge ``q1`` (0 upright, gravity destabilising) and hinge ``q2`` of the wheel relative
to the pendulum, driven by the ``motor`` actuator (no ctrl limit, so demanded τ is measured).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from cpbc.backstepping.reaction_wheel import WheelPendulumConstants
from cpbc.errors import ModelError
from cpbc.margin_kinds import INPUT_TORQUE, RATE
from cpbc.resources import models_dir
from cpbc.systems.ode_plant import ConstrainedQuantity, Plant, State, check_close


@dataclass(frozen=True)
class ReactionWheelPendulum(Plant):
    """The RWP.

    Args:
        constants: the lumped d's (default: the stated values of §3.5.3).
        rate_limit: Ξ on |q̇1| [rad/s].
        torque_limit: τmax [N m].
        path: the MJCF (default: the built-in ``reaction_wheel_pendulum.xml``).
    """

    constants: WheelPendulumConstants = field(default_factory=WheelPendulumConstants)
    rate_limit: float = 1.0
    torque_limit: float = 0.4
    path: Path = field(
        default_factory=lambda: models_dir() / "systems" / "reaction_wheel_pendulum.xml")

    state_names = ("q1", "dq1", "dq2")
    input_name = "tau [N m]"

    @property
    def constrained(self) -> tuple[ConstrainedQuantity, ...]:
        r, t = self.rate_limit, self.torque_limit
        return (
            ConstrainedQuantity("dq1", -r, r, "state", 1, RATE),
            ConstrainedQuantity("tau", -t, t, "input", 0, INPUT_TORQUE),
        )

    @property
    def mjcf(self) -> Path:
        return self.path

    def verify(self, model: mujoco.MjModel) -> None:
        names = [model.joint(i).name for i in range(model.njnt)]
        if names != ["q1", "q2"] or model.nu != 1:
            raise ModelError(f"RWP needs hinges (q1, q2) and one motor; {self.path} has {names}")
        data = mujoco.MjData(model)
        data.qpos[0] = 0.5 * np.pi
        mujoco.mj_forward(model, data)
        m = np.zeros((2, 2))
        mujoco.mj_fullM(model, data, m)
        c = self.constants
        for what, got, want in (("d11", m[0, 0], c.d11), ("d12", m[0, 1], c.d12),
                                ("d22", m[1, 1], c.d22), ("d0", -data.qfrc_bias[0], c.d0)):
            check_close(what, float(got), want, rtol=1e-5)

    def read_state(self, model: mujoco.MjModel, data: mujoco.MjData) -> State:
        return float(data.qpos[0]), float(data.qvel[0]), float(data.qvel[1])

    def write_state(self, model: mujoco.MjModel, data: mujoco.MjData, x: State) -> None:
        data.qpos[0] = x[0]
        data.qvel[0], data.qvel[1] = x[1], x[2]

    def write_input(self, model: mujoco.MjModel, data: mujoco.MjData, u: float) -> None:
        data.ctrl[0] = u

    def rhs(self, x: State, u: float, t: float) -> State:
        c = self.constants
        q1, dq1, _ = x
        det = c.d11 * c.d22 - c.d12 * c.d12
        g = c.d0 * np.sin(q1)
        ddq1 = (c.d22 * g - c.d12 * u) / det
        ddq2 = (c.d11 * u - c.d12 * g) / det
        return dq1, float(ddq1), float(ddq2)
