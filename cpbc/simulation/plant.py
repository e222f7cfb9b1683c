"""The MuJoCo plant: the physics that the controller does not see."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.errors import CpbcError, ModelError

INTEGRATORS = {
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}


INSTABILITY_WARNINGS = tuple(
    int(getattr(mujoco.mjtWarning, name))
    for name in ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")
    if hasattr(mujoco.mjtWarning, name)
)


@dataclass(frozen=True)
class PlantSettings:
    """Physics settings.

    Attributes:
        timestep: MuJoCo timestep [s], > 0.
        integrator: one of INTEGRATORS.
    """

    timestep: float = 0.001
    integrator: str = "RK4"

    def __post_init__(self) -> None:
        if not self.timestep > 0:
            raise CpbcError(f"timestep must be > 0, got {self.timestep}")
        if self.integrator not in INTEGRATORS:
            raise CpbcError(
                f"unknown integrator '{self.integrator}'; choose one of {sorted(INTEGRATORS)}"
            )


class MujocoPlant:
    """A MuJoCo model of the arm, stepped with joint torques.

    Args:
        model: a compiled MjModel whose hinge/slide joints are the arm's joints, in order, each
            driven by one actuator (or by qfrc_applied when it has none).
        settings: timestep and integrator.
    """

    def __init__(self, model: mujoco.MjModel, settings: PlantSettings) -> None:
        if model.nq != model.nv:
            raise ModelError("the MuJoCo model has free or ball joints; only arms are supported")
        self.model = model
        self.model.opt.timestep = settings.timestep
        self.model.opt.integrator = INTEGRATORS[settings.integrator]
        self.data = mujoco.MjData(model)
        # A live view of the instability warnings' counters (BADQPOS … BADCTRL are
        # contiguous), compared with zeros as bytes: the cheapest test per step.
        lo, hi = min(INSTABILITY_WARNINGS), max(INSTABILITY_WARNINGS) + 1
        if hi - lo != len(INSTABILITY_WARNINGS):
            raise CpbcError("MuJoCo's instability warnings are no longer contiguous")
        self._instability = self.data.warning.number[lo:hi]
        self._stable = bytes(self._instability.nbytes)
        self.n = model.nv
        self._use_actuators = model.nu == self.n and all(
            model.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_JOINT for i in range(model.nu)
        )
        if self._use_actuators:
            # Actuators drive joints through gear ratios; torque τ_j = gear·ctrl.
            self._gear = np.array([model.actuator_gear[i, 0] for i in range(model.nu)])
            # Actuator i drives the joint whose dof index is _act_dof[i].
            self._act_dof = np.array(
                [model.jnt_dofadr[model.actuator_trnid[i, 0]] for i in range(model.nu)]
            )
            # Motors with unit gear on joints 0..n-1 in order take τ as it is.
            self._direct = bool(
                np.array_equal(self._act_dof, np.arange(self.n)) and np.all(self._gear == 1.0)
            )
            self.model.actuator_ctrllimited[:] = 0
            self.model.actuator_forcelimited[:] = 0
        # the input arrays as views kept once (MjData builds a new view at every access)
        self._ctrl, self._qfrc = self.data.ctrl, self.data.qfrc_applied
        # A URDF's effort limits become joint actuator-force ranges in MuJoCo, which would
        # clip the torque silently; saturation is the loop's job (torque_limit, counted).
        self.model.jnt_actfrclimited[:] = 0

    @classmethod
    def from_file(cls, path: str | Path, settings: PlantSettings) -> MujocoPlant:
        path = Path(path)
        if not path.is_file():
            raise ModelError(f"model file not found: {path}")
        try:
            model = mujoco.MjModel.from_xml_path(str(path))
        except ValueError as exc:
            raise ModelError(f"MuJoCo could not load {path}: {exc}") from exc
        return cls(model, settings)

    @property
    def time(self) -> float:
        return float(self.data.time)

    def reset(self, q: Array, dq: Array) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q
        self.data.qvel[:] = dq
        mujoco.mj_forward(self.model, self.data)

    def state(self) -> tuple[Array, Array]:
        return self.data.qpos.copy(), self.data.qvel.copy()

    def apply(self, tau_joint: Array) -> None:
        """Hold joint torques τ_q until the next call (zero-order hold)."""
        if self._use_actuators:
            self._ctrl[:] = tau_joint if self._direct else tau_joint[self._act_dof] / self._gear
        else:
            self._qfrc[:] = tau_joint

    def step(self, substeps: int) -> None:
        if substeps == 1:  # without the keyword: less call overhead, the same step
            mujoco.mj_step(self.model, self.data)
        else:
            mujoco.mj_step(self.model, self.data, nstep=substeps)

    def unstable(self) -> bool:
        """Whether MuJoCo met a NaN/Inf/huge state, acceleration or control since reset.

        MuJoCo then resets the state (bad qpos/qvel/qacc) or zeroes the control (bad ctrl)
        and carries on, so the loop must ask.
        """
        return self._instability.tobytes() != self._stable
