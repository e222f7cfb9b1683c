"""A Franka (FR3 or Panda) through libfranka's Python bindings, ``pylibfranka`` (0.21):
``Robot(ip, RealtimeConfig.kIgnore)``, ``start_torque_control()``, then per cycle
``readOnce()`` / ``writeOnce(Torques)``, the last with ``motion_finished``.

What the robot does to a command, and so what this backend assumes: it adds its own gravity
compensation and clips to 87/12 N·m; it aborts the motion (a reflex, reported as
:class:`~cpbc.hardware.backend.RobotFault` by name) when a command breaks its rules. The
0.21 torque path applies no low-pass filter and no rate limiter: the torque written is the
torque the robot checks.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import CpbcError, ParameterError
from cpbc.hardware.backend import MeasuredState, RobotDynamics, RobotFault, RobotLimits
from cpbc.model.arms import FR3_VELOCITY_LIMITS, FRANKA_EXTRA

#: The FR3's rules (Franka's FCI documentation; the torque rate is libfranka's
#: ``kMaxTorqueRate``): per joint, joints 1-7.
FR3_LIMITS = RobotLimits(
    torque=np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
    torque_rate=np.full(7, 1000.0),
    velocity=np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26]),
    period=0.001,
    velocity_limits=FR3_VELOCITY_LIMITS,
)
FR3_JOINTS = tuple(f"fr3_joint{i}" for i in range(1, 8))
#: What libfranka's Model needs in the state to compute gravity: a simulator may leave the
#: base's acceleration at 0 (franky-sim does); a real robot fills it.
EARTH = (0.0, 0.0, -9.81)
_REFLEX = re.compile(r'"?([a-z_]+_(?:violation|reflex|discontinuity|timeout|detected|'
                     r'reading|inconsistent|invalid))"?')


def _bindings() -> Any:
    try:
        import pylibfranka
    except ImportError:
        raise CpbcError(f"--backend franka needs pylibfranka ({FRANKA_EXTRA})") from None
    return pylibfranka


def fault_name(exc: BaseException) -> str:
    """The robot's name for what ended a motion, read from libfranka's message (the first
    reflex it lists), else ``network`` for a lost connection, else the exception's kind."""
    found = _REFLEX.search(str(exc))
    if found:
        return found.group(1)
    kind = type(exc).__name__
    return "network" if kind == "NetworkException" else kind


class FrankaBackend:
    """A :class:`~cpbc.hardware.backend.RobotBackend` for a Franka at ``address``; with
    ``realtime``, libfranka insists on a real-time kernel (``RealtimeConfig.kEnforce``, what
    a real robot wants), else it runs on any (``kIgnore``: a simulator, a test).

    Raises:
        RobotFault: the robot cannot be reached (``network``) or refuses the connection.
    """

    def __init__(self, address: str, limits: RobotLimits = FR3_LIMITS,
                 joint_names: tuple[str, ...] = FR3_JOINTS, realtime: bool = False) -> None:
        franka = _bindings()
        self._franka = franka
        self._limits, self._names = limits, joint_names
        self._errors = (franka.FrankaException, RuntimeError)
        try:
            config = franka.RealtimeConfig.kEnforce if realtime else franka.RealtimeConfig.kIgnore
            self._robot = franka.Robot(address, config)
            self._model = self._robot.load_model()
        except self._errors as exc:
            raise RobotFault(fault_name(exc), f"cannot connect to {address}: {exc}") from None
        self._control: Any = None
        self._last: MeasuredState | None = None
        self._raw: Any = None

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self._names

    def limits(self) -> RobotLimits:
        return self._limits

    def _measured(self, raw: Any, lost: int = 0) -> MeasuredState:
        self._raw = raw
        self._last = MeasuredState(np.array(raw.q), np.array(raw.dq), raw.time.to_sec(), lost,
                                   np.array(raw.tau_J_d))
        return self._last

    def _fault(self, exc: BaseException) -> RobotFault:
        return RobotFault(fault_name(exc), str(exc).strip(), self._last)

    def read(self) -> MeasuredState:
        try:
            if self._control is None:
                return self._measured(self._robot.read_once())
            raw, period = self._control.readOnce()
        except self._errors as exc:
            raise self._fault(exc) from None
        # the robot's clock advanced by ``period``: whole cycles beyond one were lost
        lost = max(0, round(period.to_sec() / self._limits.period) - 1)
        return self._measured(raw, lost)

    def start(self) -> MeasuredState:
        try:
            self._control = self._robot.start_torque_control()
        except self._errors as exc:
            raise self._fault(exc) from None
        return self.read()

    def _send(self, torque: Array, finished: bool) -> None:
        command = self._franka.Torques(torque.tolist())
        command.motion_finished = finished
        try:
            self._control.writeOnce(command)
        except self._errors as exc:
            raise self._fault(exc) from None

    def write(self, torque: Array) -> None:
        self._send(torque, False)

    def finish(self, torque: Array) -> None:
        self._send(torque, True)
        self._control = None

    def _with_gravity(self, state: MeasuredState) -> Any:
        """The robot's own state object behind ``state`` (the last one read), with the
        base's acceleration set when the robot left it at 0, so that the Model's gravity
        is not zero."""
        if state is not self._last:
            raise ParameterError("state", "the robot's model is evaluated at the last state "
                                 "read only")
        raw = self._raw
        if not any(raw.O_ddP_O):
            raw.O_ddP_O = list(EARTH)
        return raw

    def added_torque(self, state: MeasuredState) -> Array:
        return np.array(self._model.gravity(self._with_gravity(state)))

    def dynamics(self, state: MeasuredState) -> RobotDynamics:
        raw = self._with_gravity(state)
        n = len(self._names)
        mass = np.array(self._model.mass(raw)).reshape(n, n, order="F")  # column-major
        return RobotDynamics(mass, np.array(self._model.gravity(raw)))

    def close(self) -> None:
        self._control = None
        self._robot = None
