"""The robot's rules, checked on a logged motion (they are the controller's to keep; nothing
in the loop enforces them): the first command 0, every command's change per cycle within
the torque rate, every command inside the torque box, every constraint's margin positive on
the measured states, and — for a robot whose velocity limits depend on the joints' position
(a Franka's ``joint_velocity_violation``) — every measured velocity inside them at its
measured position."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.hardware.backend import RobotLimits


@dataclass(frozen=True)
class RuleReport:
    """What a motion's log shows against the robot's rules.

    Attributes:
        first_command: the largest |τ_d,i| of the first command [N·m].
        largest_step: per joint, the largest |τ_d(k) − τ_d(k−1)| [N·m].
        steps_over: cycles in which some joint's command changed by more than the rate
            limit allows in one period (the first command counted against 0).
        outside_box: cycles with a command outside the torque box.
        worst_margin: per constraint, its smallest margin on the measured states.
        crossed: the constraints whose margin reached 0 or below.
        velocity_over: measured states with some joint's velocity outside the robot's
            position-dependent limits L(q) ≤ q̇ ≤ U(q) (0 when it has none).
        velocity_headroom: per joint, the smallest min(U(q) − q̇, q̇ − L(q)) on the measured
            states [rad/s] (+inf when the robot has no such limits).
    """

    first_command: float
    largest_step: Array
    steps_over: int
    outside_box: int
    worst_margin: dict[str, float]
    crossed: tuple[str, ...]
    velocity_over: int = 0
    velocity_headroom: Array | None = None

    @property
    def kept(self) -> bool:
        """Whether every rule held."""
        return (self.first_command == 0.0 and self.steps_over == 0 and self.outside_box == 0
                and not self.crossed and self.velocity_over == 0)

    def describe(self) -> str:
        step = ", ".join(f"{v:.3g}" for v in self.largest_step)
        worst = min(self.worst_margin.items(), key=lambda kv: kv[1], default=("-", np.nan))
        headroom = ("" if self.velocity_headroom is None else
                    f"; {self.velocity_over} states past the position-dependent velocity "
                    f"limits (least headroom {np.min(self.velocity_headroom):.3g} rad/s)")
        return (f"first command {self.first_command:.3g} N m; largest step per joint "
                f"[{step}] N m; {self.steps_over} cycles over the rate limit; "
                f"{self.outside_box} outside the torque box; smallest margin "
                f"{worst[1]:.3g} ({worst[0]}); crossed: {', '.join(self.crossed) or 'none'}"
                + headroom)


def velocity_headroom(limits: RobotLimits, position: Array, velocity: Array) -> Array | None:
    """Per measured state (rows) and joint, min(U(q) − q̇, q̇ − L(q)) [rad/s]: negative
    where the velocity is past the robot's position-dependent limits; None when it has
    none."""
    if limits.velocity_limits is None:
        return None
    bounds = limits.velocity_limits
    return np.minimum(bounds.upper(position) - velocity, velocity - bounds.lower(position))


def check_rules(commanded: Array, limits: RobotLimits, margins: Array,
                names: tuple[str, ...], position: Array | None = None,
                velocity: Array | None = None) -> RuleReport:
    """The rules on a log: ``commanded`` (N, n) the commands sent, in order (rows where none
    was sent, NaN, are skipped), ``margins`` (M, m) every constraint's margin at the
    measured states, ``names`` the constraints'; ``position`` and ``velocity`` (M, n), the
    measured states, checked against the robot's position-dependent velocity limits when
    it has them."""
    n = commanded.shape[1]
    headroom = (None if position is None or velocity is None
                else velocity_headroom(limits, position, velocity))
    over = 0 if headroom is None else int(np.sum(np.any(headroom < 0, axis=1)))
    least = None if headroom is None else headroom.min(axis=0, initial=np.inf)
    sent = commanded[np.all(np.isfinite(commanded), axis=1)]
    if not len(sent):
        return RuleReport(0.0, np.zeros(n), 0, 0, {}, (), over, least)
    # the robot's command before the motion is 0: the first command is a step from it
    steps = np.abs(np.diff(sent, axis=0, prepend=np.zeros((1, n))))
    fast = np.any(steps > limits.torque_step * (1 + 1e-9), axis=1)
    outside = np.any(np.abs(sent) > limits.torque * (1 + 1e-9), axis=1)
    worst = {name: float(np.nanmin(margins[:, i])) for i, name in enumerate(names)}
    return RuleReport(float(np.max(np.abs(sent[0]))), steps.max(axis=0), int(fast.sum()),
                      int(outside.sum()), worst,
                      tuple(name for name, v in worst.items() if not v > 0), over, least)
