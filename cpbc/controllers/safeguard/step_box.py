"""The safeguard's input bounds at one step: the torque box, and under a torque-rate limit the
part of it the actuators can reach in one period from the torque they hold. Every torque the
guard tests or returns is put in it here (:meth:`StepBox.fit`)."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import TorqueBox
from cpbc.errors import ParameterError
from cpbc.model.input_bounds import InputBounds
from cpbc.model.robot_model import ArmState, RobotModel


def _per_joint(value: Array | None, n: int, name: str) -> Array | None:
    """A bound of the input bounds, one per joint (a single number for every joint)."""
    if value is None:
        return None
    if value.size not in (1, n):
        raise ParameterError(name, f"{name} limits: one number or one per joint ({n}), got "
                             f"{value.size}")
    return np.broadcast_to(value, (n,))


class StepBox:
    """The torques the guard may hold at this step.

    Args:
        model: the controller's model (the box is in its coordinates).
        bounds: the control period h, |τ_q| ≤ L and |τ̇_q| ≤ ρ per joint (either may be
            None); a ParameterError names a bound that is neither one number nor one per
            joint.

    Attributes:
        torque_limit, rate_limit: L and ρ per joint, or None.
        torque_box: the torque box as declared (None without a torque or rate limit).
        rate_step: ρh, how far one step can move each joint torque (None: as far as the box
            allows).
        holding: the torque the actuators hold (controller coordinates), under a rate limit.
    """

    def __init__(self, model: RobotModel, bounds: InputBounds) -> None:
        n = model.n
        self.torque_limit = _per_joint(bounds.torque, n, "torque")
        self.rate_limit = _per_joint(bounds.rate, n, "rate")
        step = bounds.step
        self.rate_step: Array | None = None if step is None else np.broadcast_to(step, (n,))
        limit = self.torque_limit if self.torque_limit is not None else (
            None if self.rate_limit is None else np.full(n, math.inf))
        self.torque_box = None if limit is None else TorqueBox.of(model, limit)
        self._static = self.torque_box  # this step's torque box (moved by ``added``)
        self._step = self.torque_box  # ... narrowed to what one step reaches
        self.holding: Array | None = None
        self._added: Array | None = None  # the torque the robot adds itself (hold)
        self._inertia = np.zeros((0, 0))  # D at this step's state: what a brake is reached by

    @property
    def reachable(self) -> TorqueBox | None:
        """The torques this step may hold: the torque box, narrowed under a rate limit to
        what one step reaches (None without either limit)."""
        return self._step

    @property
    def rate_limited(self) -> bool:
        return self.rate_step is not None

    @property
    def to_joint(self) -> Array | None:
        """Tᵀ, the map of controller-coordinate torques to joint torques (None: joints)."""
        assert self.torque_box is not None
        return self.torque_box.to_joint

    def hold(self, tau: Array, added: Array | None = None) -> None:
        """The torque the actuators hold now, and the torque the robot adds to every command
        itself (its box then bounds τ − added): :meth:`Safeguard.holding`, which hands in
        fresh float vectors, kept as they are."""
        self.holding = tau
        self._added = added

    def begin(self, state: ArmState) -> None:
        """This step's box under a rate limit: the torque box (moved by what the robot adds)
        around the held torque — or, at the first step, the gravity torque of the state (an
        arm held at rest), clipped into the box (a motor holds at most its limit) — by ρh."""
        box, step = self.torque_box, self.rate_step
        assert box is not None and step is not None
        if self._added is not None:  # the robot's box bounds the command, τ − added
            lower, upper = box.bounds
            shift = box.joint(self._added)
            box = box.with_bounds(lower + shift, upper + shift)
        self._static = box
        held = self.holding
        if held is None:  # the first step: an arm held at rest, at most at the box's edge
            held = state.gravity
            lower, upper = box.bounds
            joint = box.joint(held)
            if not ((joint >= lower) & (joint <= upper)).all():
                held = box.clip(held)
        self.holding = held  # this step's anchor (fit)
        self._step = box.around(box.joint(held), step)
        self._inertia = state.inertia

    def end(self, tau: Array) -> Array:
        """The step's torque clipped to the step's box, now the torque held."""
        tau = self.end_clip(tau)
        self.holding = tau
        return tau

    def end_clip(self, tau: Array) -> Array:
        """τ clipped to the step's box joint by joint, as :meth:`end` holds it (and as a
        prediction holds a torque outside the box)."""
        assert self._step is not None
        return self._step.clip(tau)

    def fit(self, bias: Array, tau: Array, brake: bool = False) -> Array:
        """τ scaled toward the bias b = C ẋ + g + f until it fits the torque box
        (:meth:`TorqueBox.toward`): the acceleration D⁻¹(τ − b) keeps its direction and only
        shrinks, so no joint is spun up by the coupling through D, as clipping each joint
        would (τ itself when it fits, or when there is no limit). Under a torque-rate limit
        it is then reached from the held torque τ_h as far as one step allows: the law's
        torque and what follows it (the slide) along the straight line τ_h + s(τ − τ_h),
        which keeps the direction of the change of acceleration the law asks for (a reach
        that bent it took the FR3's hand 23 mm off a circle it tracked within 2 mm); a
        ``brake`` (the brakes, the escape, the rescue's) as the torque within ρh of τ_h
        whose acceleration is nearest to its own (:meth:`TorqueBox.nearest`), which gives
        every joint as much of its own interval as it needs: scaled along the straight
        line, the FR3's light last joint kept −11 N·m for 15 ms (0.14 of its 1 N·m a
        period) while its motion had to turn, and ran through its rate bound. (Clipped joint
        by joint, a brake far outside the rate box spun the Panda's base joint up through
        its rate bound: the coupling through D.)"""
        box = self._static
        if box is None:
            return tau
        boxed = box.toward(bias, tau)
        step, held = self._step, self.holding
        if self.rate_step is None or step is None or held is None:
            return boxed
        return step.nearest(self._inertia, boxed) if brake else step.toward(held, boxed)
